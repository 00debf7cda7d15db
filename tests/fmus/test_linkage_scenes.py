"""Linkage scenes (crank slider, four bar) run through dsim from their .ssp
archives, against their monolithic references; the Linkage2D and FlexibleLink2D
FMUs alone (validation, rollback)."""
import numpy as np
import pytest

from examples import crank_slider, four_bar
from dsim.fmus.linkage.description import mechanism_to_text
from dsim.fmus.linkage.scenes import crank_slider_part
from dsim.master.api import simulate
from dsim.master.recording.results import read_csv
from dsim.master.tools.cli import main as dsim


@pytest.mark.parametrize("name", ["Linkage2D", "FlexibleLink2D"])
def test_fmu_is_valid(built, name):
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(built["fmus"] / f"{name}.fmu")) == []


def _stepper(path, start_values):
    """An initialised fmpy FMU2Slave with start values set in initialization mode."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    description = read_model_description(str(path))
    refs = {v.name: v for v in description.modelVariables}
    fmu = FMU2Slave(guid=description.guid, unzipDirectory=extract(str(path)),
                    modelIdentifier=description.coSimulation.modelIdentifier,
                    instanceName="rollback")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    for name, value in start_values.items():
        setter = fmu.setString if isinstance(value, str) else fmu.setReal
        setter([refs[name].valueReference], [value])
    fmu.exitInitializationMode()
    outputs = [v.valueReference for v in description.modelVariables
               if v.causality == "output"]
    return fmu, refs, outputs


@pytest.mark.parametrize("name, start, force", [
    ("Linkage2D", {"mechanism": mechanism_to_text(crank_slider_part("coupler"))}, "B.f_y"),
    ("FlexibleLink2D", {"omega0": 1.0}, "B.f_y")])
def test_rollback_bit_for_bit_through_the_fmu(built, name, start, force):
    fmu, refs, outputs = _stepper(built["fmus"] / f"{name}.fmu", start)
    try:
        h = 1e-3
        fmu.setReal([refs[force].valueReference], [250.0])
        for n in range(50):
            fmu.doStep(n * h, h)
        state = fmu.getFMUstate()
        fmu.setReal([refs[force].valueReference], [-400.0])
        for n in range(50, 55):
            fmu.doStep(n * h, h)
        first = np.array(fmu.getReal(outputs))
        fmu.setReal([refs[force].valueReference], [0.0])   # wreck inputs and state
        fmu.doStep(0.055, h)
        fmu.setFMUstate(state)
        fmu.setReal([refs[force].valueReference], [-400.0])
        for n in range(50, 55):
            fmu.doStep(n * h, h)
        again = np.array(fmu.getReal(outputs))
        assert np.any(first != 0.0)
        assert np.array_equal(first, again)
        fmu.freeFMUstate(state)
    finally:
        fmu.terminate()
        fmu.freeInstance()


def test_crank_slider_rigid_matches_monolithic(built, tmp_path):
    """Penalized gluing (xi = 1, omega = 1000, the parts' own Baumgarte row) solves
    the monolithic discrete equations: joint force at A to 1e-6 of its peak
    (a 0.3 s run; the full 5 s run is in docs/linkage_benchmark.md)."""
    out = tmp_path / "crank_slider_rigid.csv"
    statistics = simulate(built["ssp"] / "crank_slider_rigid.ssp", out=out, stop=0.3).statistics
    result = crank_slider.compare(out)
    assert statistics["steps"] == 300
    assert result["force_peak"] > 1e3                 # a real load, not zeros
    assert result["force_relative"] < 1e-6            # measured ~1e-9
    assert result["slider_error"] < 1e-9
    header, _ = read_csv(out)
    assert {"A.f_x", "A.f_y", "slider.P.u_x", "coupler.omega"} <= set(header)


def test_crank_slider_flexible_matches_monolithic(built, tmp_path):
    """The glued flexible crank slider against the monolithic one (rigid crank and
    slider, the same floating-frame coupler, joints as Baumgarte rows, one Newton per
    step: fmus/flexible_link/mechanism.py).  Both solve the same discrete equations,
    so they differ by the iteration tolerances only (master 1e-7 m/s^2 on the
    penalized residual, PIM 1e-10): 1e-6 of the peak force, as the rigid scene
    (measured 1.3e-8 over 0.3 s; coupler omega 3e-12 rad/s, slider 1.5e-13 m).  The
    rigid monolithic model is 4 % of the peak away (the coupler's flexibility)."""
    out = tmp_path / "crank_slider_flexible.csv"
    statistics = simulate(built["ssp"] / "crank_slider_flexible.ssp", out=out, stop=0.3).statistics
    assert statistics["steps"] == 300
    result = crank_slider.compare(out, flexible=True)
    assert result["force_peak"] > 1e3
    assert result["force_relative"] < 1e-6
    assert result["omega_error"] < 1e-9
    assert result["slider_error"] < 1e-9
    rigid = crank_slider.compare(out, flexible=False)
    assert rigid["force_relative"] > 1e4 * result["force_relative"]


def test_four_bar_flexible_passes_the_singular_point(built, tmp_path):
    """The crank is collinear with the ground at t = 0.375 s; with flexible joints
    the glued run goes through and the rocker keeps following the crank."""
    out = tmp_path / "four_bar_flexible.csv"
    statistics = simulate(built["ssp"] / "four_bar_singular_flexible.ssp", out=out, stop=0.5,
                     tolerance=1e-7).statistics
    assert statistics["status"] == "completed" and statistics["steps"] == 50
    header, data = read_csv(out)
    assert np.all(np.isfinite(data))
    crank, rocker = data[:, header.index("crank.theta")], data[:, header.index("rocker.theta")]
    assert crank[-1] > np.pi > crank[0]
    assert np.max(np.abs(rocker - crank)) < 1e-3       # parallelogram kept (rad)
    result = four_bar.compare(out, "flexible")
    # the master integrates the joint rate from port positions, the monolithic
    # bushing uses point velocities: O(H^2) apart, measured 2 % of the peak at H = 0.01
    assert result["force_relative"] < 0.05


def test_four_bar_fixed_fails_cleanly_at_the_singular_point_under_the_trapezoidal_rule(
        built, tmp_path, capsys):
    """The fixed scene as it was (trapezoidal parts: its parameter set, dsim's default
    refresh and convergence test): the index-3 glue's period-2 force oscillation grows
    towards the collinear position and the run stops there, cleanly."""
    out = tmp_path / "four_bar_fixed.csv"
    code = dsim(["run", str(built["ssp"] / "four_bar_singular_fixed.ssp"), "--out", str(out),
                 "--tol", "1e-8", "--stop", "0.5", "--quiet", "--parameter-set", "trapezoidal",
                 "--refresh", "adaptive", "--convergence", "residual"])
    message = capsys.readouterr().err
    assert code == 1
    assert "step 38" in message and "joint '" in message and "t = 0.38" in message
    assert "singular configuration" in message and "ill-posed" in message
    header, data = read_csv(out)
    assert data.shape[0] == 38 and data[-1, 0] == pytest.approx(0.37)
    assert np.all(np.isfinite(data))


@pytest.mark.parametrize("tolerance, bound", [(1e-8, 1e-5), (1e-10, 1e-6)])
def test_four_bar_fixed_passes_the_singular_point_on_the_displacement_measure(
        built, tolerance, bound):
    """Fixed joints on the displacement measure through the first collinear position
    (t = 0.375 s) with the scene's means (generalized-alpha parts, a fresh Lambda every
    step, the forces test): the joint force at A equals the twin's, the whole four bar
    with index-3 rows at A and B under the same rule, closer than the flexible joints
    equal theirs, in fewer iterations per step."""
    from dsim.build_fmus.twins import four_bar_twin
    from dsim.master.sweeps.sweep import error_against

    runs = {joints: simulate(built["ssp"] / f"four_bar_singular_{joints}.ssp",
                             tolerance=tolerance, stop=0.5)
            for joints in ("fixed", "flexible")}
    errors = {joints: error_against(run.signals, four_bar_twin(joints, 1), ["A.f_x", "A.f_y"])
              for joints, run in runs.items()}
    fixed = runs["fixed"]
    assert fixed.status == "completed" and fixed.steps == 50
    assert fixed.statistics["master"]["refresh"] == "step"
    crank, rocker = fixed["crank.theta"], fixed["rocker.theta"]
    assert crank[-1] > np.pi > crank[0]                       # through the collinear pass
    assert np.max(np.abs(rocker - crank)) < 1e-6              # parallelogram kept (rad)
    assert errors["fixed"] < bound        # measured 2.7e-6 (1e-8 m), 1.4e-7 (1e-10 m)
    assert errors["fixed"] <= errors["flexible"]      # measured 4.9e-5, 1.9e-7 there
    iterations = {joints: run.statistics["iterations"]["mean_per_step"]
                  for joints, run in runs.items()}
    assert iterations["fixed"] <= iterations["flexible"]      # measured 2.1, 2.2 against 5.3, 5.0


def test_four_bar_penalized_passes_at_1e10(built):
    """Fixed joints on the penalized measure at 1e-10 m/s^2, below most of its steps'
    round-off floor: those steps end on the round-off test, counted, and the run
    passes the singular point as close to its twin as at 1e-8."""
    from dsim.build_fmus.twins import four_bar_twin
    from dsim.master.sweeps.sweep import error_against

    run = simulate(built["ssp"] / "four_bar_singular_penalized.ssp", tolerance=1e-10,
                   stop=0.5)
    assert run.status == "completed" and run.steps == 50
    assert run.statistics["roundoff_steps"] > 10                # measured 38
    assert error_against(run.signals, four_bar_twin("penalized", 1),
                         ["A.f_x", "A.f_y"]) < 1e-8             # measured 2.9e-10


def _joint_a_errors(csv_path):
    header, data = read_csv(csv_path)
    column = lambda name: data[:, header.index(name)]  # noqa: E731
    return {kind: np.hypot(column(f"coupler.A.{kind}_x") - column(f"crank.A.{kind}_x"),
                           column(f"coupler.A.{kind}_y") - column(f"crank.A.{kind}_y"))
            for kind in ("u", "a")}


def test_penalized_bounds_the_drift_that_acceleration_only_gluing_lets_grow(built, tmp_path):
    errors = {}
    for scene in ("crank_slider_penalized", "crank_slider_penalized_acceleration"):
        simulate(built["ssp"] / f"{scene}.ssp", out=tmp_path / f"{scene}.csv", stop=0.4)
        errors[scene] = _joint_a_errors(tmp_path / f"{scene}.csv")
    penalized = errors["crank_slider_penalized"]["u"]
    accelerated = errors["crank_slider_penalized_acceleration"]["u"]
    assert np.max(penalized) < 1e-7                    # m; measured 2e-8 over 0.5 s
    assert accelerated[-1] > 20 * np.max(penalized)    # measured 4.7e-6 m at 0.5 s
    assert accelerated[-1] > accelerated[len(accelerated) // 2]   # and it grows
    # acceleration-only keeps its own measure tight, as it should
    assert np.max(errors["crank_slider_penalized_acceleration"]["a"][1:]) < 1e-6


def test_consistent_start_finds_the_four_bars_centripetal_joint_forces(built, tmp_path):
    """The crank turns at full speed from t = 0, so the fixed joints carry load at
    once; start="consistent" solves the initial acceleration compatibility before
    the first step: the t = 0 forces are the whole mechanism's reactions."""
    from dsim.fmus.linkage.scenes import four_bar

    out = tmp_path / "start.csv"
    simulate(built["ssp"] / "four_bar_singular_fixed.ssp", out=out, stop=0.05)
    header, data = read_csv(out)
    whole = four_bar("whole")
    whole.initialize(0.0)
    reactions = whole.reactions()
    for name in ("A.f_x", "A.f_y", "B.f_x", "B.f_y"):
        expected = reactions[name]
        assert abs(expected) > 20.0  # centripetal load, about 28 N per component
        assert data[0, header.index(name)] == pytest.approx(expected, rel=1e-8)
