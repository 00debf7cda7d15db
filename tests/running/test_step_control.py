"""Error-controlled macro steps (``--step auto``, master/running/step_control.py):
the error against a closed form falls with the tolerance and stays within 100 E, the
step grows where the motion is smooth, every output point keeps its row, the statistics
and the summary say what the controller did, and bad input is one line, exit 2.

The two-mass oscillator split in two C FMUs (tests/support/third_party/kinds: position and
speed one way, force the other) runs with its connections coupled strongly, against
the closed form of its four states."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

import dsim
from dsim.master.running.step_control import StepControl, levels
from dsim.master.tools.cli import main
from tests.support.closed_forms import LINKS, exact_x1
from tests.support.scenes import archive_scene

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")


@pytest.fixture(scope="module")
def masses(tmp_path_factory):
    from tests.support.third_party.kinds.build import build_fmu, mass_fmus

    folder = tmp_path_factory.mktemp("masses")
    return mass_fmus(folder) | {
        "fixed": build_fmu(folder / "fixed", "mass1", "2.0", can_save_state=False,
                           interfaces=("CoSimulation",))}


def two_masses(masses, path: Path, interface="CoSimulation", master="", first="mass1",
               stop=2.0, step=0.1) -> Path:
    """The oscillator's archive, its connections strongly coupled to 1e-13."""
    return archive_scene(path, {"mass1": (masses[first], interface, ""),
                        "mass2": (masses["mass2"], interface, "")}, LINKS, stop=stop,
                 step=step, master='coupling="strong" tolerance="1e-13" '
                                   f'relativeTolerance="1e-13" {master}')


def test_the_error_falls_with_the_tolerance_and_stays_within_100_tolerances(masses,
                                                                             tmp_path):
    """Measured: E = 1e-4 -> 8.4e-5 (0.84 E), 1e-6 -> 7.2e-6 (7.2 E); 1e-8 -> 3.5e-7
    (35 E, 5.6 s: not run here).  Every output point of the 0.1 s grid has its row."""
    path = two_masses(masses, tmp_path / "two.ssp")
    errors = []
    for tolerance in (1e-4, 1e-6):
        result = dsim.simulate(path, step="auto", error_tolerance=tolerance)
        assert result.ok, result.statistics["message"]
        np.testing.assert_allclose(result["time"], np.linspace(0, 2, 21), rtol=0, atol=1e-12)
        error = float(np.max(np.abs(result["mass1.x1"] - exact_x1(result["time"]))))
        print(f"E = {tolerance:g}: max |x1 - exact| = {error:.3g}")
        assert error < 100 * tolerance
        errors.append(error)
        control = result.statistics["step_control"]
        assert control["error_tolerance"] == tolerance
        assert control["accepted_steps"] >= 20
        assert control["largest_step"] <= 0.1 + 1e-15
        assert control["largest_estimate"] <= 1.0
    assert errors[1] < errors[0] / 5


def test_the_step_grows_as_the_motion_dies_out(masses, tmp_path):
    """With mass1 damped (d1 = 20 N.s/m) |x1| falls from 0.1 m to 0.003 m in 4 s: the
    controller's steps after 3 s are longer than in the first tenth of a second
    (measured: 0.98 ms at most there, 15.6 ms after 3 s), and the run still meets its
    tolerance against the closed form."""
    path = two_masses(masses, tmp_path / "damped.ssp", stop=4.0, step=0.5)
    execution = dsim.Execution(dsim.prepare(path, step="auto", error_tolerance=1e-6,
                                            parameters={"mass1.d1": 20.0}))
    result = execution.run(handle_signals=False)
    assert result.ok, result.statistics["message"]
    times = np.array(execution.controller.times)
    sizes = np.array(execution.controller.sizes)
    early, late = sizes[times < 0.1], sizes[times >= 3.0]
    print(f"early steps {early.max():.3g} s at most, late {late.min():.3g} s at least")
    assert late.min() >= 8 * early.max()
    error = np.max(np.abs(result["mass1.x1"] - exact_x1(result["time"], damping=20.0)))
    assert error < 100 * 1e-6


def test_model_exchange_fmus_are_stepped_by_error_control_too(masses, tmp_path):
    """The same oscillator through the FMUs' Model Exchange interface (dsim integrates
    them; their snapshot is the FMU state with dsim's integrator state)."""
    path = two_masses(masses, tmp_path / "me.ssp", interface="ModelExchange", stop=1.0)
    result = dsim.simulate(path, step="auto", error_tolerance=1e-5)
    assert result.ok, result.statistics["message"]
    error = np.max(np.abs(result["mass1.x1"] - exact_x1(result["time"])))
    assert error < 100 * 1e-5


def test_the_summary_and_the_statistics_say_what_the_controller_did(masses, tmp_path,
                                                                    capsys):
    path = two_masses(masses, tmp_path / "said.ssp", stop=0.5)
    assert main(["run", str(path), "--step", "auto", "--error-tolerance", "1e-5",
                 "--out", str(tmp_path / "said.csv")]) == 0
    out = capsys.readouterr().out
    line = next(line for line in out.splitlines() if line.startswith("step auto"))
    assert "E 1e-05" in line and "steps accepted" in line and "largest estimate" in line
    statistics = json.loads((tmp_path / "said.stats.json").read_text())
    control = statistics["step_control"]
    assert control["accepted_steps"] > 5 and control["smallest_step"] <= control["mean_step"]
    assert statistics["master"]["adaptive"] is True
    rows = (tmp_path / "said.csv").read_text().splitlines()
    assert len(rows) == 1 + 6  # the header, then t = 0, 0.1, ..., 0.5


def test_the_scene_can_ask_for_error_control_in_its_annotation(masses, tmp_path):
    path = two_masses(masses, tmp_path / "annotated.ssp", stop=0.3, step="auto",
                      master='errorTolerance="1e-5" maxStep="0.05"')
    result = dsim.simulate(path, output_interval=0.1)
    assert result.ok, result.statistics["message"]
    control = result.statistics["step_control"]
    assert control["error_tolerance"] == 1e-5 and control["largest_step"] <= 0.05 + 1e-15
    assert len(result["time"]) == 4
    fixed = dsim.simulate(path, step=0.01)  # a fixed step given for the run wins
    assert fixed.statistics["step_control"] is None and fixed.statistics["steps"] == 30


@pytest.mark.parametrize("arguments, expected", [
    (["--error-tolerance", "1e-6"], "setting error_tolerance: only an error-controlled step"),
    (["--step", "0.01", "--min-step", "1e-4"], "setting min_step: only an error-controlled"),
    (["--step", "auto", "--error-tolerance", "0"], "must be a finite number greater than 0"),
    (["--step", "auto", "--error-tolerance=-1e-6"], "must be a finite number greater"),
    (["--step", "auto", "--min-step", "0.1", "--max-step", "0.01"],
     "setting min_step 0.1 s is larger than max_step 0.01 s"),
    (["--step", "auto", "--min-step", "1"], "min_step 1 s is longer than the output interval"),
])
def test_bad_error_control_settings_are_one_line_and_exit_2(masses, tmp_path, capsys,
                                                            arguments, expected):
    path = two_masses(masses, tmp_path / "bad.ssp", stop=0.2)
    out = tmp_path / "bad.csv"
    assert main(["run", str(path), "--out", str(out)] + arguments) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0], lines
    assert not out.exists()  # nothing ran


def test_an_fmu_that_cannot_go_back_is_refused_in_one_line_naming_it(masses, tmp_path,
                                                                     capsys):
    path = two_masses(masses, tmp_path / "nostate.ssp", first="fixed", stop=0.2)
    assert main(["run", str(path), "--step", "auto", "--out", str(tmp_path / "n.csv")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    assert "component 'mass1' cannot save and restore its state" in lines[0]
    assert "canGetAndSetFMUstate is false" in lines[0] and "--step" in lines[0]


def test_the_step_levels_land_on_the_output_grid():
    """Steps are the interval over a power of two, between max_step and min_step."""
    assert levels(0.1, StepControl(1e-6, None, None, 0.1)) == (0, 19, 0)
    assert levels(0.1, StepControl(1e-6, 1e-3, 0.02, 0.01)) == (3, 5, 4)
    assert levels(1.0, StepControl(1e-6, 0.5, None, 1.0)) == (0, 0, 0)


def test_an_fmu_that_cannot_go_back_in_co_simulation_runs_its_model_exchange(tmp_path):
    """FMUs with both interfaces whose co-simulation cannot save its state (as
    OMSimulator's dual-mass oscillator FMUs): where the run takes steps back (the strong
    coupling, step auto) they run through Model Exchange, said once each; with
    implementation="CoSimulation" they stay in co-simulation."""
    from tests.support.third_party.kinds.build import mass_fmus

    masses = mass_fmus(tmp_path, can_save_state=False)
    path = two_masses(masses, tmp_path / "me.ssp", interface="", stop=1.0, step=0.01)
    # measured: 4.2e-4 at the fixed 10 ms step (strong), far less with step auto
    for settings, band in (({}, 1e-3), ({"step": "auto", "error_tolerance": 1e-6,
                                         "output_interval": 0.1}, 1e-4)):
        result = dsim.simulate(path, **settings)
        assert result.ok, result.statistics["message"]
        said = [w for w in result.warnings if "runs through its Model Exchange" in w]
        assert len(said) == 2, result.warnings
        assert {c["interface"] for c in result.statistics["components"].values()} == {
            "ModelExchange"}
        error = np.max(np.abs(result["mass1.x1"] - exact_x1(result["time"])))
        print(settings, f"max |x1 - exact| = {error:.3g}")
        assert error < band
    kept = two_masses(masses, tmp_path / "cs.ssp", interface="CoSimulation", stop=0.1,
                      step=0.01)
    result = dsim.simulate(kept)
    assert {c["interface"] for c in result.statistics["components"].values()} == {
        "CoSimulation"}
    assert any("cannot roll back" in w for w in result.warnings)
