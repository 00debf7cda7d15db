"""Every FMU kind a user brings, run by dsim and checked against closed forms: Model
Exchange (FMI 2.0 and 3.0, integrated by dsim, with state and time events), FMI 3.0
and FMI 1.0 co-simulation, glued and causal; and connections coupled strongly (the
two-mass oscillator split in two FMUs), against the once-per-step exchange.

The FMUs are written in C for these tests (tests/support/third_party/kinds) and compiled here;
tests/fmus/test_fmi_kinds_fmus.py shows each passes fmpy's validation and runs alone."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

import dsim
from dsim.master.tools.cli import main
from tests.support.closed_forms import bouncing_height
from tests.support.scenes import archive_scene

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")


@pytest.fixture(scope="module")
def kinds(tmp_path_factory):
    """Builds FMUs by (model, FMI version, interfaces, name) once per module."""
    from tests.support.third_party.kinds.build import build_fmu

    folder = tmp_path_factory.mktemp("kinds")
    made = {}

    def fmu(model, version="2.0", interfaces=("ModelExchange", "CoSimulation"), **kw):
        key = (model, version, tuple(interfaces), tuple(sorted(kw.items())))
        if key not in made:
            made[key] = build_fmu(folder / f"{len(made)}", model, version,
                                  interfaces=interfaces, **kw)
        return made[key]
    return fmu


#: records the oscillator's position (port kinematics are not recorded by default)
POSITION = ('<ssd:Connectors><ssd:Connector name="P.u_x" kind="output"><ssc:Real/>'
            "</ssd:Connector></ssd:Connectors>")
#: OMSimulator's solver annotation, asking for CVODE at rtol 1e-10
CVODE = ('<ssd:Annotations><ssc:Annotation type="org.openmodelica"><oms:Annotations '
         'xmlns:oms="https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/'
         'schema/oms.xsd"><oms:SimulationInformation><oms:VariableStepSolver '
         'description="cvode" relativeTolerance="1e-10"/></oms:SimulationInformation>'
         "</oms:Annotations></ssc:Annotation></ssd:Annotations>")


@pytest.mark.parametrize("version, interface, solver, band", [
    ("2.0", "ModelExchange", "", 1e-12), ("3.0", "ModelExchange", "", 1e-12),
    ("2.0", "ModelExchange", CVODE, 1e-6), ("3.0", "CoSimulation", "", 1e-12),
    ("1.0", "CoSimulation", "", 1e-12)])
def test_an_oscillator_of_every_kind_runs_to_its_closed_form(kinds, tmp_path, version,
                                                             interface, solver, band):
    """x = cos t (m = k = 1, x0 = 1): Model Exchange integrated by dsim (DOP853 by
    default; CVODE where the SSD's OMSimulator annotation asks), FMI 3.0 and 1.0
    co-simulation through their own bindings."""
    interfaces = ("CoSimulation",) if version == "1.0" else ("ModelExchange", "CoSimulation")
    fmu = kinds("oscillator", version, interfaces)
    path = archive_scene(tmp_path / "osc.ssp", {"m": (fmu, interface, POSITION + solver)})
    result = dsim.simulate(path, out=tmp_path / "osc.csv")
    assert result.ok, result.statistics["message"]
    error = np.max(np.abs(result["m.P.u_x"] - np.cos(result["time"])))
    assert error < band
    if solver:  # CVODE is the less accurate here, and not exact either
        assert error > 1e-12


@pytest.mark.parametrize("version", ["2.0", "3.0"])
@pytest.mark.parametrize("method", ["DOP853", "cvode"])
def test_state_events_are_located_to_the_solver_tolerance(kinds, tmp_path, version, method):
    """The bouncing ball (Model Exchange, event indicator h): 2 s, five bounces, step
    0.01 s, against its closed form (DOP853 2e-15, CVODE 9e-8 at rtol 1e-10)."""
    solver = (f'<ssd:Annotations><ssc:Annotation type="org.dsim.solver"><glue:Solver '
              f'xmlns:glue="urn:dsim:gluing:1" method="{method}" rtol="1e-10"/>'
              "</ssc:Annotation></ssd:Annotations>")
    fmu = kinds("bouncing_ball", version)
    path = archive_scene(tmp_path / "ball.ssp", {"b": (fmu, "ModelExchange", solver)})
    result = dsim.simulate(path, out=tmp_path / "ball.csv")
    assert result.ok, result.statistics["message"]
    error = np.max(np.abs(result["b.h"] - bouncing_height(result["time"])))
    assert error < (1e-12 if method == "DOP853" else 1e-6)


def test_a_time_event_is_hit_exactly(kinds, tmp_path):
    """x' = 1 before T = 0.5 s, -1 after; with a step of 0.03 s T falls inside a step:
    the FMU's nextEventTime splits it there."""
    path = archive_scene(tmp_path / "te.ssp", {"e": (kinds("time_event"), "ModelExchange", "")},
                 stop=1.0, step=0.03)
    result = dsim.simulate(path, out=tmp_path / "te.csv")
    t = result["time"]
    assert result.ok
    assert np.max(np.abs(result["e.x"] - np.where(t < 0.5, t, 1.0 - t))) < 1e-12


@pytest.mark.parametrize("interface", ["ModelExchange", "CoSimulation"])
def test_an_fmi3_enumeration_output_is_read_through_either_interface(kinds, tmp_path,
                                                                     capsys, interface):
    """FMI 3.0 reads Enumerations with fmi3GetInt64: the time event model's rate as an
    Enumeration output (Up = 1 before T = 0.5 s, Down = -1 after) is recorded through
    Model Exchange as through co-simulation (it failed there, exit 2: the adapter asked
    fmpy for a getEnumeration that FMI 3.0 has not)."""
    from tests.support.third_party.kinds.build import add_enumeration_output

    fmu = shutil.copy(kinds("time_event", "3.0", defines=("ENUM_VR=10", "ENUM_OF=2")),
                      tmp_path / "time_event.fmu")
    add_enumeration_output(fmu, "direction", 10, "Direction", {"Up": 1, "Down": -1})
    path = archive_scene(tmp_path / "enum.ssp", {"e": (fmu, interface, "")}, stop=1.0,
                         step=0.1)
    out = tmp_path / "enum.csv"
    assert main(["run", str(path), "--out", str(out), "--quiet"]) == 0, capsys.readouterr()
    result = dsim.simulate(path)
    assert result.ok, result.statistics["message"]
    time = result["time"]
    np.testing.assert_array_equal(result["e.direction"], np.where(time < 0.5 - 1e-9, 1, -1))
    np.testing.assert_allclose(result["e.x"], np.where(time < 0.5, time, 1.0 - time),
                               atol=1e-12)


def _two_mass(kinds, folder: Path, interface: str, coupling: str, step: float):
    mass1, mass2 = kinds("mass1"), kinds("mass2")
    path = archive_scene(folder / f"two_{interface}_{coupling}_{step}.ssp",
                 {"mass1": (mass1, interface, ""), "mass2": (mass2, interface, "")},
                 [("mass1", "x1", "mass2", "x1"), ("mass1", "v1", "mass2", "v1"),
                  ("mass2", "F", "mass1", "F")], stop=2.0, step=step,
                 master=f'coupling="{coupling}" tolerance="1e-12" relativeTolerance="1e-12"')
    result = dsim.simulate(path, out=folder / f"{path.stem}.csv")
    assert result.ok, result.statistics["message"]
    m1 = m2 = 1.0
    k1 = k2 = 10.0
    kc = 100.0
    system = np.array([[0, 1, 0, 0], [-(k1 + kc) / m1, 0, kc / m1, 0], [0, 0, 0, 1],
                       [kc / m2, 0, -(k2 + kc) / m2, 0]])
    exact = np.array([(expm(system * t) @ [0.1, 0, 0, 0])[0] for t in result["time"]])
    return np.max(np.abs(result["mass1.x1"] - exact)), result


@pytest.mark.parametrize("interface", ["ModelExchange", "CoSimulation"])
def test_strongly_coupled_connections_beat_the_exchange_tenfold(kinds, tmp_path, interface):
    """The two-mass oscillator split in two FMUs (position and speed one way, force the
    other) against its closed form: at the same step the strong coupling is more than
    10 times closer than the once-per-step exchange (measured: 135x at 0.01 s, 208x at
    0.005 s), and it converges like the FMUs' integrators (error / 4 when the step
    halves) where the exchange converges like the exchange (error / 2.6)."""
    errors = {(c, h): _two_mass(kinds, tmp_path, interface, c, h)[0]
              for c in ("causal", "strong") for h in (0.01, 0.005)}
    for h in (0.01, 0.005):
        assert errors["causal", h] > 10 * errors["strong", h]
    assert errors["strong", 0.01] / errors["strong", 0.005] > 3.5
    assert errors["causal", 0.01] / errors["causal", 0.005] < 3.0
    _, result = _two_mass(kinds, tmp_path, interface, "strong", 0.01)
    iterations = result.statistics["iterations"]
    assert iterations["mean_per_step"] <= 3  # a linear loop: one Newton correction


@pytest.mark.parametrize("measure, band", [("velocity", 1e-11), ("displacement", 1e-11),
                                           ("acceleration", 2e-7)])
def test_a_glued_model_exchange_pair_matches_the_merged_mass(kinds, tmp_path, measure, band):
    """Two Model Exchange oscillators (k = 1 and k = 3, x0 = 1) glued at P by a fixed
    joint move as one mass of 2 kg on 4 N/m: x = cos(sqrt(2) t).  The pair's sum is
    integrated exactly whatever the joint force, so a measure that holds positions or
    velocities compatible at the step's ends is exact there (measured 3e-14 and 8e-14);
    the acceleration measure drifts (7.6e-8 at 1 ms, /4 per halving).  On the
    displacement measure the forces are held over the step (ramped, the force
    sequence grew as (-2)^n and the run failed at step 28)."""
    fmu = kinds("oscillator")
    k3 = ('<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>'
          '<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/'
          'SystemStructureParameterValues" version="1.0" name="p"><ssv:Parameters>'
          '<ssv:Parameter name="k"><ssv:Real value="3"/></ssv:Parameter></ssv:Parameters>'
          "</ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding>"
          "</ssd:ParameterBindings>")
    path = archive_scene(tmp_path / "glued.ssp",
                 {"a": (fmu, "ModelExchange", POSITION), "b": (fmu, "ModelExchange", k3)},
                 gluing='<glue:Joint name="j" a="a.P" b="b.P" dofs="x" kind="fixed" '
                        f'measure="{measure}"/>',
                 master='tolerance="1e-12" start="consistent"', step=0.001, stop=1.0)
    result = dsim.simulate(path, out=tmp_path / "glued.csv")
    assert result.ok, result.statistics["message"]
    error = np.max(np.abs(result["a.P.u_x"] - np.cos(np.sqrt(2) * result["time"])))
    assert error < band


def test_an_fmi1_fmu_in_a_joint_is_refused_in_one_line(kinds, tmp_path, capsys):
    """FMI 1.0 has no FMU state: an iterated joint refuses it, one line naming each
    component."""
    fmu = kinds("oscillator", "1.0", ("CoSimulation",))
    path = archive_scene(tmp_path / "fmi1.ssp", {"a": (fmu, "", ""), "b": (fmu, "", "")},
                 gluing='<glue:Joint name="j" a="a.P" b="b.P" dofs="x" kind="fixed"/>')
    assert main(["validate", str(path)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 2  # one line per component
    for name, line in zip("ab", lines):
        assert f"component '{name}' cannot save and restore its state (an FMI 1.0 " \
            "co-simulation FMU: FMI 1.0 has no FMU state)" in line


def test_dsim_info_says_each_components_version_and_interface(kinds, tmp_path, capsys):
    path = archive_scene(tmp_path / "info.ssp", {"me": (kinds("oscillator"), "ModelExchange", ""),
                                         "cs3": (kinds("oscillator", "3.0"), "", "")})
    assert main(["info", str(path)]) == 0
    text = capsys.readouterr().out
    assert "FMI 2.0 Model Exchange; state yes" in text and "integrated by dsim (DOP853" in text
    assert "FMI 3.0 co-simulation; state yes" in text


def test_model_exchange_and_fmi3_fmus_run_in_ray_workers_as_here(kinds, tmp_path, ray_local):
    """A Model Exchange oscillator glued to an FMI 3.0 co-simulation one, and the
    strongly coupled two-mass pair as Model Exchange FMUs: the Ray backend gives the
    in-process numbers to the last bit."""
    from tests.support.runs import same_run

    glued = archive_scene(tmp_path / "mixed.ssp",
                  {"a": (kinds("oscillator"), "ModelExchange", POSITION),
                   "b": (kinds("oscillator", "3.0"), "CoSimulation", "")},
                  gluing='<glue:Joint name="j" a="a.P" b="b.P" dofs="x" kind="flexible" '
                         'measure="displacement"><glue:Spring k0="50" k1="0"/>'
                         '<glue:Damper c0="1" c1="0"/></glue:Joint>', stop=0.1)
    here, there = dsim.simulate(glued), dsim.simulate(glued, backend="ray")
    assert here.ok and there.statistics["backend"] == "ray"
    same_run(here, there)
    components = there.statistics["components"]
    assert (components["a"]["interface"], components["b"]["fmi_version"]) == (
        "ModelExchange", "3.0")
    _, strong_here = _two_mass(kinds, tmp_path, "ModelExchange", "strong", 0.01)
    path = tmp_path / "two_ModelExchange_strong_0.01.ssp"
    same_run(strong_here, dsim.simulate(path, backend="ray"))


@pytest.mark.parametrize("interface", ["CoSimulation", "ModelExchange"])
def test_an_algebraic_loop_is_solved_at_every_communication_point(kinds, tmp_path, capsys,
                                                                  interface):
    """Two direct-feedthrough blocks y = g u + c fed into each other: y1 = (g1 c2 + c1) /
    (1 - g1 g2) from the first row on (the exchange passed the loop on unsolved: each
    value a step late, the start rows off); dsim info names the loop."""
    fmu = kinds("feedthrough")
    bound = ('<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>'
             '<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/'
             'SystemStructureParameterValues" version="1.0" name="p"><ssv:Parameters>'
             '<ssv:Parameter name="g"><ssv:Real value="-0.25"/></ssv:Parameter>'
             '<ssv:Parameter name="c"><ssv:Real value="2"/></ssv:Parameter>'
             "</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>"
             "</ssd:ParameterBinding></ssd:ParameterBindings>")
    path = archive_scene(tmp_path / "loop.ssp", {"b1": (fmu, interface, ""), "b2": (fmu, interface,
                                                                           bound)},
                 [("b1", "y", "b2", "u"), ("b2", "y", "b1", "u")], stop=0.1, step=0.01)
    result = dsim.simulate(path, out=tmp_path / "loop.csv")
    assert result.ok, result.statistics["message"]
    y1 = (0.5 * 2.0 + 1.0) / (1 + 0.5 * 0.25)
    assert np.max(np.abs(result["b1.y"] - y1)) < 1e-9
    assert np.max(np.abs(result["b2.y"] - (2.0 - 0.25 * y1))) < 1e-9
    assert main(["info", str(path)]) == 0
    assert "algebraic loop 1: " in capsys.readouterr().out


@pytest.mark.parametrize("interface, x2_start, damped", [
    ("CoSimulation", 8.4, False), ("ModelExchange", 8.4, False),
    ("CoSimulation", -0.7, True)])
def test_a_nonlinear_loop_across_two_fmus_converges_at_the_start(kinds, tmp_path, interface,
                                                                 x2_start, damped):
    """OMSimulator's equationPair: 2 x1^2 + 5 x2 = 42 in one FMU, x1 - 6 x2 = 4 in
    the other, from their inputs' start values (x1 = 4, x2 = 8.4 as OMSimulator's; the
    Jacobian measured once, a chord iteration, ends 20 iterations at a residual of 5.1).
    Newton with the Jacobian measured again when the residual stops falling fast
    reaches the root of 2.4 x1^2 + x1 - 54.4 = 0 that OMSimulator finds, at every row.
    From x2 = -0.7 the first Jacobian is nearly singular (x1 = -0.2 is fed back, and
    1 + 4.8 x1 = 0.04): the full correction makes the residual grow, and a halved one
    is taken."""
    from dataclasses import replace

    from tests.support.third_party.kinds.build import EQUATION_PAIR, Var

    second = replace(EQUATION_PAIR["equation2"], variables=(
        Var("x2", 0, "input", x2_start, description="input"),
        *EQUATION_PAIR["equation2"].variables[1:]))
    one = kinds(EQUATION_PAIR["equation1"])
    two = kinds(second, defines=(f"X2_START={x2_start!r}",))
    path = archive_scene(tmp_path / "pair.ssp", {"equation1": (one, interface, ""),
                                                 "equation2": (two, interface, "")},
                         [("equation1", "x2", "equation2", "x2"),
                          ("equation2", "x1", "equation1", "x1")], stop=0.02, step=0.01)
    result = dsim.simulate(path, out=tmp_path / "pair.csv")
    assert result.ok, result.statistics["message"]
    x1 = (-1 + np.sqrt(1 + 4 * 2.4 * 54.4)) / 4.8
    x2 = (x1 - 4) / 6
    # the loop's tolerance (1e-10 on each input, by default) times the loop's gains
    # (|d x1 / d x2| = 6, |d x2 / d x1| = 0.8 x1 < 4)
    assert np.max(np.abs(result["equation2.x1"] - x1)) < 6e-10
    assert np.max(np.abs(result["equation1.x2"] - x2)) < 4e-10
    loops = result.statistics["algebraic_loops"]
    assert loops["corrections"] <= 10, loops
    assert (loops["damped_corrections"] > 0) == damped, loops
    assert not [w for w in result.warnings if "coupling error" in w], result.warnings
    # a loop solved at every communication point passes no value on a step late: the
    # coupling error estimate weighs the values fed into it as iterated connections
    # (their bend over a step, not their change)
    from dsim.master.api import prepare
    from dsim.master.running.execution import Execution

    execution = Execution(prepare(path))
    execution.run(handle_signals=False)
    assert execution._watch._iterated.all(), execution._watch.labels


def test_a_loop_that_fails_at_the_start_time_is_a_failed_run(kinds, tmp_path, capsys):
    """The equationPair loop given 2 iterations fails after the FMUs' initialization, at
    the start time: a failure of the run (exit 1, one line, the statistics and the CSV
    written, no row converged), not bad input (it was exit 2, nothing written)."""
    from tests.support.third_party.kinds.build import EQUATION_PAIR

    one, two = (kinds(EQUATION_PAIR[name]) for name in ("equation1", "equation2"))
    path = archive_scene(tmp_path / "pair.ssp", {"equation1": (one, "", ""),
                                                 "equation2": (two, "", "")},
                         [("equation1", "x2", "equation2", "x2"),
                          ("equation2", "x1", "equation1", "x1")], stop=0.02, step=0.01)
    out = tmp_path / "pair.csv"
    assert main(["run", str(path), "--out", str(out), "--max-iterations", "2",
                 "--quiet"]) == 1
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 2, lines  # the failure, and where the converged rows are
    assert "step 0 (t = 0 s): algebraic loop" in lines[0]
    assert "did not converge in 2 iterations" in lines[0]
    statistics = json.loads(out.with_suffix(".stats.json").read_text())
    assert statistics["status"] == "failed" and statistics["steps"] == 0
    assert "did not converge in 2 iterations" in statistics["message"]
    assert out.read_text().splitlines()[0].startswith("time,")
    assert len(out.read_text().splitlines()) == 1


def test_the_run_summary_prints_only_what_the_coupling_does(kinds, tmp_path, capsys):
    """A causal run takes no Newton iteration and measures no Lambda: its summary says
    neither (it said "iterations 0.00 per step (max 0), Lambda refreshes 0"), and says
    the algebraic loops' corrections where it solves loops; the strong coupling's says
    its iterations."""
    from tests.support.third_party.kinds.build import EQUATION_PAIR

    one, two = (kinds(EQUATION_PAIR[name]) for name in ("equation1", "equation2"))
    pair = archive_scene(tmp_path / "pair.ssp", {"equation1": (one, "", ""),
                                                 "equation2": (two, "", "")},
                         [("equation1", "x2", "equation2", "x2"),
                          ("equation2", "x1", "equation1", "x1")], stop=0.02, step=0.01)
    halves = archive_scene(tmp_path / "halves.ssp",
                           {"mass1": (kinds("mass1"), "CoSimulation", ""),
                            "mass2": (kinds("mass2"), "CoSimulation", "")},
                           [("mass1", "x1", "mass2", "x1"), ("mass1", "v1", "mass2", "v1"),
                            ("mass2", "F", "mass1", "F")], stop=0.05, step=0.01)

    def work(path, *options) -> str:
        assert main(["run", str(path), "--out", str(tmp_path / "o.csv"), *options]) == 0
        out = capsys.readouterr().out.splitlines()
        return next(line for line in out if line.startswith(("steps ", "iterations ")))

    assert work(halves) == "steps       doSteps per FMU per step 1.00"
    assert work(pair) == ("steps       algebraic loops 9 corrections (7 Jacobians), "
                          "doSteps per FMU per step 1.00")
    assert work(halves, "--coupling", "strong").startswith("iterations  ")
    assert "Lambda refreshes" in work(halves, "--coupling", "strong")


def test_a_loop_free_causal_chain_finds_no_loop(kinds, tmp_path, capsys):
    """The two-mass halves pass x1 and v1 one way and F back, but no output depends on
    an input directly around the cycle (mass 1's x1, v1 are states): no loop."""
    path = tmp_path / "two_ModelExchange_causal_0.01.ssp"
    _two_mass(kinds, tmp_path, "ModelExchange", "causal", 0.01)
    assert not dsim.prepare(path).loops
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "algebraic loop" not in out and "exchanged once per step" in out


def test_the_solver_is_chosen_on_the_command_line_over_the_ssd(kinds, tmp_path, capsys):
    """--solver m.method=cvode --solver rtol=1e-10 wins over the SSD's annotation
    (DOP853 at rtol 1e-6): CVODE's error, not DOP853's; a name reaching no component
    and a method dsim lacks are one line each, exit 2."""
    annotation = ('<ssd:Annotations><ssc:Annotation type="org.dsim.solver"><glue:Solver '
                  'xmlns:glue="urn:dsim:gluing:1" method="DOP853" rtol="1e-6"/>'
                  "</ssc:Annotation></ssd:Annotations>")
    path = archive_scene(tmp_path / "osc.ssp", {"m": (kinds("oscillator"), "ModelExchange",
                                              POSITION + annotation)})
    out = tmp_path / "cvode.csv"
    assert main(["run", str(path), "--quiet", "--out", str(out), "--solver", "m.method=cvode",
                 "--solver", "rtol=1e-10"]) == 0
    rows = np.genfromtxt(out, delimiter=",", names=True)
    error = np.max(np.abs(rows["mP.u_x" if "mP.u_x" in rows.dtype.names else
                               rows.dtype.names[1]] - np.cos(rows["time"])))
    assert 1e-12 < error < 1e-6  # CVODE at 1e-10 (8e-8 measured), not DOP853's 2e-15
    assert main(["validate", str(path), "--solver", "n.rtol=1e-9", "--solver",
                 "method=euler"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 2
    assert "solver setting 'n.rtol'" in lines[0] and "solver method 'euler'" in lines[1]


K3 = ('<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>'
      '<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/'
      'SystemStructureParameterValues" version="1.0" name="p"><ssv:Parameters>'
      '<ssv:Parameter name="k"><ssv:Real value="3"/></ssv:Parameter></ssv:Parameters>'
      "</ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding>"
      "</ssd:ParameterBindings>")
SPRING = ('<glue:Joint name="j" a="a.P" b="b.P" dofs="x" kind="flexible" '
          'measure="displacement"><glue:Spring k0="10" k1="0"/><glue:Damper c0="0.1" '
          'c1="0"/></glue:Joint>')


def test_model_exchange_without_fmu_state_rolls_back_its_continuous_states(kinds, tmp_path):
    """An oscillator pair in a flexible joint: the Model Exchange FMUs that cannot save
    their state (canGetAndSetFMUstate false) are rolled back by their continuous states
    and give the numbers of those that can, bit for bit."""
    runs = {}
    for save in (True, False):
        fmu = kinds("oscillator", can_save_state=save)
        path = archive_scene(tmp_path / f"g{save}.ssp", {"a": (fmu, "ModelExchange", POSITION),
                                                 "b": (fmu, "ModelExchange", K3)},
                     gluing=SPRING, step=1e-3, stop=1.0)
        runs[save] = dsim.simulate(path)
        assert runs[save].ok, runs[save].statistics["message"]
    assert np.array_equal(runs[True]["a.P.u_x"], runs[False]["a.P.u_x"])
    assert np.ptp(runs[True]["a.P.u_x"] - np.cos(runs[True]["time"])) > 1e-3  # they interact
    functions = runs[False].statistics["components"]["a"]["functions"]
    assert "save continuous states" in functions and "fmi2GetFMUstate" not in functions


def test_an_event_in_an_iterated_step_without_fmu_state_fails_in_one_line(kinds, tmp_path):
    """A bouncing ball that cannot save its FMU state, iterated by the strong coupling
    (its height feeds a block: a chain): its first bounce, at 0.4515 s, changes its
    state at an event inside an iterated step, which its continuous states cannot take
    back: the run fails in that step (46, to 0.46 s), naming the component, the 45
    converged rows kept."""
    ball = kinds("bouncing_ball", can_save_state=False)
    path = archive_scene(tmp_path / "ball.ssp", {"ball": (ball, "ModelExchange", ""),
                                         "gain": (kinds("feedthrough"), "", "")},
                 [("ball", "h", "gain", "u")], stop=1.0, step=0.01,
                 master='coupling="strong" tolerance="1e-9"')
    result = dsim.simulate(path, out=tmp_path / "ball.csv")
    assert result.status == "failed" and result.exit_code == 1
    assert "component 'ball': an event in an iterated step at t = 0.46 s" in result.message
    assert "cannot save its state" in result.message
    assert result.steps == 45 and len(result["time"]) == 46


def test_fmi1_fmus_exchange_causally_and_converge_like_the_exchange(kinds, tmp_path,
                                                                    capsys):
    """The two-mass halves as FMI 1.0 co-simulation FMUs, connected causally: they run
    (fmiInitializeSlave before their first output), first order in the step like any
    exchange; asked for the strong coupling they are exchanged, and the run says so."""
    halves = {n: kinds(n, "1.0", ("CoSimulation",)) for n in ("mass1", "mass2")}
    links = [("mass1", "x1", "mass2", "x1"), ("mass1", "v1", "mass2", "v1"),
             ("mass2", "F", "mass1", "F")]
    system = np.array([[0, 1, 0, 0], [-110, 0, 100, 0], [0, 0, 0, 1], [100, 0, -110, 0]])
    errors = []
    for step in (0.01, 0.005):
        path = archive_scene(tmp_path / f"fmi1_{step}.ssp", {n: (f, "", "") for n, f in
                                                    halves.items()}, links, step=step)
        result = dsim.simulate(path)
        assert result.ok, result.statistics["message"]
        exact = np.array([(expm(system * t) @ [0.1, 0, 0, 0])[0] for t in result["time"]])
        errors.append(np.max(np.abs(result["mass1.x1"] - exact)))
    assert errors[0] < 0.2 and 1.5 < errors[0] / errors[1] < 3.0
    strong = dsim.simulate(path, coupling="strong")
    assert strong.ok and any("cannot roll back" in w for w in strong.statistics["warnings"])
    # --strict refuses that warning as every other, before running (it ran, exit 0)
    out = tmp_path / "strict.csv"
    assert main(["run", str(path), "--coupling", "strong", "--strict", "--out", str(out),
                 "--quiet"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "cannot roll back" in lines[0]
    assert lines[0].endswith("(a warning; refused with --strict)") and not out.exists()


def test_the_model_database_shows_each_fmus_version_and_interfaces(kinds, tmp_path):
    """dsim serve's model pages: an FMI 3.0 FMU with both interfaces and an FMI 2.0
    Model Exchange-only one are described as such (list and page)."""
    from tests.support.serve_fixtures import create_app, upload
    from fastapi.testclient import TestClient

    app = create_app(tmp_path / "db.sqlite", slots=1)
    with TestClient(app, base_url="http://127.0.0.1") as client:
        both = upload(client, kinds("oscillator", "3.0"), "osc3.fmu").json()
        only = upload(client, kinds("bouncing_ball", "2.0", ("ModelExchange",)),
                      "ball.fmu").json()
        described = client.get(f"/api/models/{both['id']}").json()["description"]
        assert (described["fmiVersion"], described["interfaces"]) == (
            "3.0", ["CoSimulation", "ModelExchange"])
        page = client.get(f"/models/{only['id']}").text
        assert "2.0 ModelExchange" in page
        assert "3.0 CoSimulation, ModelExchange" in client.get("/models").text


def _binding(values: dict) -> str:
    """A component's inline parameter set: name -> (SSV type, value)."""
    entries = "".join(f'<ssv:Parameter name="{n}"><ssv:{t} value="{v}"/></ssv:Parameter>'
                      for n, (t, v) in values.items())
    return ('<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>'
            '<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/'
            'SystemStructureParameterValues" version="1.0" name="p"><ssv:Parameters>'
            f"{entries}</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>"
            "</ssd:ParameterBinding></ssd:ParameterBindings>")


def _controlled_pair(kinds, built, folder: Path, coupling: str, step: float, **run):
    """Two SpringMass FMUs (1 kg on 10 N/m each, 1 N on the right one) glued by a
    100 N/m spring, and a C feedthrough FMU that reads the right mass's position and
    pushes the left mass with -20 N/m times it (through its free port Q): a joint and
    a loop of connections in one scene.  The largest position error against the
    closed form (expm of the linear system), and the result."""
    record = ('<ssd:Connectors><ssd:Connector name="x[1]" kind="output"><ssc:Real/>'
              "</ssd:Connector></ssd:Connectors>")
    mass = {"n": ("Integer", 1), "m[1]": ("Real", 1), "k_ground[1]": ("Real", 10),
            "P.mass": ("Integer", 1), "Q.mass": ("Integer", 1)}
    spring_mass = built["fmus"] / "SpringMass.fmu"
    path = archive_scene(folder / f"pair_{coupling}_{step}.ssp",
                 {"left": (spring_mass, "", record + _binding(mass)),
                  "right": (spring_mass, "", record + _binding({**mass, "F0[1]": ("Real", 1)})),
                  "ctrl": (kinds("feedthrough", "2.0", ("CoSimulation",)), "",
                           _binding({"g": ("Real", -20), "c": ("Real", 0)}))},
                 [("right", "x[1]", "ctrl", "u"), ("ctrl", "y", "left", "Q.f_x")],
                 gluing='<glue:Joint name="j" a="left.P" b="right.P" dofs="x" '
                        'kind="flexible" measure="displacement"><glue:Spring k0="100" '
                        'k1="0"/><glue:Damper c0="0" c1="0"/></glue:Joint>',
                 master=f'coupling="{coupling}" tolerance="1e-12"', step=step, stop=2.0)
    result = dsim.simulate(path, **run)
    assert result.ok, result.statistics["message"]
    system = np.zeros((5, 5))
    system[0, 1] = system[2, 3] = system[3, 4] = 1.0
    system[1, 0], system[1, 2] = -110.0, 100.0 - 20.0
    system[3, 0], system[3, 2] = 100.0, -110.0
    exact = np.array([(expm(system * t) @ [0, 0, 0, 0, 1])[[0, 2]] for t in result["time"]])
    error = max(np.max(np.abs(result["left.x[1]"] - exact[:, 0])),
                np.max(np.abs(result["right.x[1]"] - exact[:, 1])))
    return error, result, path


def test_joints_and_connections_are_iterated_together(kinds, built, tmp_path):
    """The glued pair with a feedback connection: the iterative coupling glues the
    joint and exchanges the connection once per step (5.7e-3 m off at 10 ms, first
    order); the strong coupling iterates the connection around the joint's Newton
    (1.4e-4 m, 41 times closer, second order like the trapezoidal FMUs)."""
    errors = {(c, h): _controlled_pair(kinds, built, tmp_path, c, h)[0]
              for c in ("iterative", "strong") for h in (0.01, 0.005)}
    assert errors["iterative", 0.01] > 10 * errors["strong", 0.01]
    assert errors["strong", 0.01] / errors["strong", 0.005] > 3.5
    assert errors["iterative", 0.01] / errors["iterative", 0.005] < 2.5


def test_strong_coupling_with_joints_runs_in_ray_workers_as_here(kinds, built, tmp_path,
                                                                  ray_local):
    from tests.support.runs import same_run

    _, here, path = _controlled_pair(kinds, built, tmp_path, "strong", 0.01)
    same_run(here, dsim.simulate(path, backend="ray"))


def test_an_fmi3_output_feeds_an_fmi2_input_in_another_unit(kinds, tmp_path, capsys):
    """A mixed system: the FMI 3.0 oscillator's position (Float64, m from its
    UnitDefinitions) feeds an FMI 2.0 feedthrough whose input the SSD declares in mm:
    y = 0.5 (1000 x) + 1, x = cos t; a connector in seconds is refused in one line."""
    def mixed(unit: str) -> Path:
        return archive_scene(tmp_path / f"mixed_{unit}.ssp",
                     {"osc": (kinds("oscillator", "3.0"), "CoSimulation", ""),
                      "gain": (kinds("feedthrough"), "CoSimulation",
                               '<ssd:Connectors><ssd:Connector name="u" kind="input">'
                               f'<ssc:Real unit="{unit}"/></ssd:Connector></ssd:Connectors>')},
                     [("osc", "P.u_x", "gain", "u")], stop=1.0,
                     units='<ssd:Units><ssc:Unit name="mm"><ssc:BaseUnit m="1" '
                           'factor="0.001"/></ssc:Unit><ssc:Unit name="s"><ssc:BaseUnit '
                           's="1"/></ssc:Unit></ssd:Units>')
    result = dsim.simulate(mixed("mm"))
    assert result.ok, result.statistics["message"]
    t = result["time"][1:]  # each step's input: the position at the step's start
    assert np.max(np.abs(result["gain.y"][1:] - (500.0 * np.cos(t - 0.01) + 1.0))) < 1e-9
    assert main(["validate", str(mixed("s"))]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "are not the same dimension" in lines[0]


@pytest.fixture(scope="module")
def typed(tmp_path_factory):
    """The FMI 3.0 co-simulation FMU of every value type (tests/support/third_party/kinds)."""
    from tests.support.third_party.kinds.build import build_typed_array

    return build_typed_array(tmp_path_factory.mktemp("typed"))


def test_fmi3_value_types_and_arrays_are_recorded_set_and_connected(kinds, typed, tmp_path):
    """FMI 3.0 arrays as name[i] columns, Float32, Int32, Boolean, Enumeration and
    String outputs recorded; an array element, an Int64, a UInt8 and a String set with
    --set-like parameters; a connection into one element of an input array.  x_i =
    c_i + (1 - c_i) exp(-k_i t) with c_i = gain8 u_i / k_i, exact per step."""
    path = archive_scene(tmp_path / "typed.ssp", {"t": (typed, "", ""),
                                          "src": (kinds("feedthrough"), "CoSimulation",
                                                  _binding({"c": ("Real", 2.0)}))},
                 [("src", "y", "t", "u[1]")], stop=0.1, step=0.01)
    result = dsim.simulate(path, out=tmp_path / "typed.csv", parameters={
        "t.k[2]": 4.0, "t.offset": 5, "t.gain8": 3, "t.label": "abc"})
    assert result.ok, result.statistics["message"]
    t = result["time"]
    c1 = 3 * 2.0 / 1.0  # gain8 u1 / k1, u1 = src.y = 0.5 * 0 + 2
    assert np.max(np.abs(result["t.x[1]"][1:] - (c1 + (1 - c1) * np.exp(-t[1:])))) < 1e-12
    assert np.max(np.abs(result["t.x[2]"] - np.exp(-4 * t))) < 1e-12
    assert np.max(np.abs(result["t.x[3]"] - np.exp(-3 * t))) < 1e-12
    x_sum = result["t.x[1]"] + result["t.x[2]"] + result["t.x[3]"]
    assert np.max(np.abs(result["t.x_sum"] - x_sum)) < 1e-6  # a Float32
    assert list(result["t.steps"]) == [5 + n for n in range(len(t))]
    assert set(result["t.positive"]) == {1.0} and result["t.mode"][-1] == 2.0  # On
    assert result["t.status"][-1] == f"abc:{5 + len(t) - 1}"
