"""A third-party FMU, written in C and compiled here (fmpy ships the FMI 2.0
headers), glued to dsim's own SpringMass FMU through a glue:Port map of its own
variable names; and the same FMU without state saving, which dsim must refuse."""
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from fmpy import simulate_fmu
from fmpy.validation import validate_fmu

from dsim.fmus.spring_mass.core import ChainParameters, SpringMassChain
from dsim.master.recording.results import read_csv
from dsim.master.tools.cli import main
import dsim
from dsim.master.api import simulate
from tests.support.scenes import oscillator_scene
from tests.support.third_party.build import OSCILLATOR_VARIABLES, c_fmu


@pytest.fixture(scope="module")
def c_fmus(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cfmu")
    if shutil.which("gcc") is None:
        pytest.skip("no C compiler")
    return {"state": c_fmu(folder, "oscillator", "oscillator.c", OSCILLATOR_VARIABLES),
            "nostate": c_fmu(folder, "oscillator_nostate", "oscillator.c",
                             OSCILLATOR_VARIABLES, can_save_state=False),
            "nostate_live": c_fmu(folder, "oscillator_nostate_live", "oscillator.c",
                                  OSCILLATOR_VARIABLES, can_save_state=False,
                                  defines=("LIVE_OUTPUTS",)),
            "fixed_step": c_fmu(folder, "oscillator_fixed_step", "oscillator.c",
                                OSCILLATOR_VARIABLES, variable_step=False)}


def test_the_c_fmu_is_valid_and_runs_alone_in_fmpy(c_fmus):
    assert validate_fmu(str(c_fmus["state"])) == []
    result = simulate_fmu(str(c_fmus["state"]), stop_time=1.0, output_interval=1e-3,
                          start_values={"m": 1.0, "k": 400.0, "s0": 0.01}, output=["s"])
    w_h = 2.0 / 1e-3 * math.atan(20.0 * 1e-3 / 2.0)  # the trapezoidal rule's frequency
    assert np.max(np.abs(result["s"] - 0.01 * np.cos(w_h * result["time"]))) < 1e-12


def test_third_party_fmu_glued_through_a_port_map_equals_the_merged_model(
        c_fmus, built, tmp_path):
    """Fixed joint between the C FMU's mapped port and SpringMass.P: one mass of
    2 + 3 kg on springs 300 + 200 N/m under the SpringMass load."""
    out = tmp_path / "run.csv"
    stats = simulate(oscillator_scene(tmp_path / "scene", built, c_fmus["state"]), out=out).statistics
    header, data = read_csv(out)
    params = ChainParameters(n=1)
    params.m[0], params.k_ground[0], params.x0[0] = 5.0, 500.0, 0.01
    params.Fa[0], params.omega[0] = 5.0, 7.0
    expected = SpringMassChain(params).history(len(data) - 1, 0.005)[:, 0]
    peak = np.max(np.abs(expected))
    for column in ("third.s", "mass.x[1]"):
        assert np.max(np.abs(data[:, header.index(column)] - expected)) < 1e-9 * peak
    assert stats["iterations"]["max_per_step"] <= 2
    assert stats["components"]["third"]["functions"]["fmi2SetFMUstate"]["calls"] > 0


def test_a_fmu_that_cannot_save_state_is_refused_with_one_line(c_fmus, built, tmp_path,
                                                               capsys):
    folder = oscillator_scene(tmp_path / "scene", built, c_fmus["nostate"])
    assert main(["run", str(folder), "--out", str(tmp_path / "o.csv"), "--quiet"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1
    assert "component 'third' cannot save and restore its state" in lines[0]


def test_consistent_start_needs_fmus_whose_accelerations_follow_their_inputs(
        c_fmus, built, tmp_path, capsys):
    """The C FMU computes its outputs only when it leaves initialization mode, so
    the master cannot find consistent start forces with it: a clear input error."""
    folder = oscillator_scene(tmp_path / "scene", built, c_fmus["state"])
    ssd = folder / "SystemStructure.ssd"
    ssd.write_text(ssd.read_text().replace('tolerance="1e-13"',
                                           'tolerance="1e-13" start="consistent"'))
    assert main(["run", str(folder), "--out", str(tmp_path / "o.csv"), "--quiet"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "component 'third' reports other port accelerations" in lines[0]


def flexible_scene(folder: Path, built, c_fmu_path: Path) -> Path:
    """The scene with a spring-damper joint (k0 = 1000 N/m, c0 = 10 N.s/m) instead of the
    fixed one: a stiff fixed joint is what the explicit coupling cannot glue at all."""
    oscillator_scene(folder, built, c_fmu_path)
    ssd = folder / "SystemStructure.ssd"
    ssd.write_text(ssd.read_text().replace(
        '<glue:Joint name="j" a="third.P" b="mass.P" dofs="x"/>',
        '<glue:Joint name="j" a="third.P" b="mass.P" dofs="x" kind="flexible">'
        '<glue:Spring k0="1000"/><glue:Damper c0="10"/></glue:Joint>'))
    return folder


def two_mass_positions(steps: int, step: float) -> np.ndarray:
    """The C FMU's mass (2 kg on 300 N/m) and the SpringMass one (3 kg on 200 N/m, the
    sine load) in one chain, the joint's spring and damper between them: x1 over time."""
    params = ChainParameters(n=2)
    params.m[:2], params.k_ground[:2] = (2.0, 3.0), (300.0, 200.0)
    params.k[0], params.c[0], params.x0[:2] = 1000.0, 10.0, (0.01, 0.01)
    params.Fa[1], params.omega[1] = 5.0, 7.0
    return SpringMassChain(params).history(steps, step)[:, 0]


def test_an_fmu_without_state_saving_is_glued_by_the_explicit_coupling(c_fmus, built,
                                                                       tmp_path):
    """No rollback at all: the flexibility comes from the start accelerations (the FMU's
    outputs follow its inputs in initialization mode), and the run is the explicit
    baseline's: compatible to what the predictor misses, converging with the step."""
    folder = flexible_scene(tmp_path / "scene", built, c_fmus["nostate_live"])
    errors = []
    for step in (0.005, 0.0025):
        result = simulate(folder, coupling="explicit", predictor="quadratic", step=step)
        assert result.ok and result.statistics["coupling"] == "explicit"
        third = result.statistics["components"]["third"]
        assert third["state_saves"] == 0 and third["state_restores"] == 0
        assert third["do_steps"] == result.steps  # one doStep per step, never repeated
        expected = two_mass_positions(result.steps, step)
        errors.append(np.max(np.abs(result["third.s"] - expected)) / np.max(np.abs(expected)))
    assert errors[0] < 5e-4 and errors[1] < errors[0] / 3  # measured 1.2e-4, 2.5e-5
    # the iterative coupling glues the same pair (with a state-saving build) exactly
    folder = flexible_scene(tmp_path / "iterated", built, c_fmus["state"])
    result = simulate(folder, step=0.005)
    expected = two_mass_positions(result.steps, 0.005)
    assert np.max(np.abs(result["third.s"] - expected)) < 1e-12 * np.max(np.abs(expected))
    # that build computes its outputs only when it leaves initialization mode: the start
    # forces cannot come from its start positions, and the run says so
    assert result.warnings == [
        "start='auto': component 'third' computes its outputs only when it leaves "
        "initialization mode, so the flexible joints' start forces cannot come from its "
        "start positions: every joint starts at zero force"]


def test_the_explicit_coupling_needs_outputs_that_follow_inputs_at_the_start(
        c_fmus, built, tmp_path):
    folder = flexible_scene(tmp_path / "scene", built, c_fmus["nostate"])
    with pytest.raises(dsim.InputError, match="component 'third': its port accelerations "
                                              "do not follow its forces in initialization"):
        simulate(folder, coupling="explicit")


def test_a_failed_step_is_cut_only_where_every_glued_fmu_accepts_variable_steps(
        c_fmus, built, tmp_path):
    """One iteration cannot meet 1e-13 on this fixed joint (the predictor is not exact):
    with a variable-step C FMU the master halves the step down to H/16 before it gives
    up; with one that needs a fixed step it fails at once, no cut tried."""
    variable = simulate(oscillator_scene(tmp_path / "variable", built, c_fmus["state"]),
                        max_iterations=1, step_cuts=4)
    fixed = simulate(oscillator_scene(tmp_path / "fixed", built, c_fmus["fixed_step"]),
                     max_iterations=1, step_cuts=4)
    assert variable.status == fixed.status == "failed"
    assert "(the step was cut: a part of 0.0003125 s from t = 0 s failed too)" in variable.message
    assert fixed.message.startswith("step 1 (t = 0.005 s): joint 'j' (j.f_x) did not "
                                    "converge in 1 iterations")
    assert (variable.statistics["step_cuts"], fixed.statistics["step_cuts"]) == (1, 0)


def test_a_step_an_fmu_discards_is_cut_and_equals_the_merged_model_at_the_cut_step(
        c_fmus, built, tmp_path):
    """The C FMU discards every step longer than 2.5 ms; the scene steps 5 ms: every
    macro step is restored and taken as two halves, so the run is the merged model
    integrated at 2.5 ms, read every 5 ms."""
    folder = oscillator_scene(tmp_path / "scene", built, c_fmus["state"])
    ssd = folder / "SystemStructure.ssd"
    ssd.write_text(ssd.read_text().replace(
        '<ssv:Parameter name="s0"><ssv:Real value="0.01"/></ssv:Parameter>',
        '<ssv:Parameter name="s0"><ssv:Real value="0.01"/></ssv:Parameter>'
        '<ssv:Parameter name="h_max"><ssv:Real value="0.0025"/></ssv:Parameter>'))
    result = simulate(folder, stop=0.5)
    params = ChainParameters(n=1)
    params.m[0], params.k_ground[0], params.x0[0] = 5.0, 500.0, 0.01
    params.Fa[0], params.omega[0] = 5.0, 7.0
    expected = SpringMassChain(params).history(200, 0.0025)[::2, 0]
    assert result.status == "completed" and result.statistics["step_cuts"] == 100
    assert np.max(np.abs(result["third.s"] - expected)) < 1e-9 * np.max(np.abs(expected))
    refused = simulate(folder, stop=0.5, step_cuts=0)
    assert refused.status == "failed"
    assert "fmi2DoStep failed: it returned fmi2Discard (step of 0.005 s is longer than " \
           "h_max)" in refused.message
