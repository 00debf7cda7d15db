"""Glued scenes, run through dsim from their .ssp archives, against their
monolithic references."""
import json

import numpy as np
import pytest

from examples import chain, spring_mass
from dsim.master.api import simulate
from dsim.master.recording.results import read_csv


@pytest.mark.parametrize("nonlinear", [False, True], ids=["linear", "nonlinear"])
def test_spring_mass_glued_equals_monolithic(built, tmp_path, nonlinear):
    name = "spring_mass_nonlinear" if nonlinear else "spring_mass_linear"
    out = tmp_path / f"{name}.csv"
    statistics = simulate(built["ssp"] / f"{name}.ssp", out=out)
    result = spring_mass.compare(out, nonlinear)
    assert statistics.statistics["steps"] == 1000
    assert result["peak"] > 0.3  # the scene moves (x3 peaks at 0.57 m / 0.42 m)
    assert result["relative_error"] < 1e-8


def test_linear_joint_needs_two_do_steps_per_macro_step_once_lambda_is_known(built, tmp_path):
    """Once Lambda is known, a linear problem converges in one Newton update:
    one doStep with the predicted force, one with the corrected force."""
    out = tmp_path / "linear.csv"
    statistics = simulate(built["ssp"] / "spring_mass_linear.ssp", out=out).statistics
    steps = statistics["steps"]
    assert statistics["lambda_refreshes"] == 1
    # every step has the same size to the last bit: the gluing matrix is factored once
    assert statistics["lambda_factorizations"] == 1
    for name, component in statistics["components"].items():
        do_steps = component["functions"]["fmi2DoStep"]["calls"]
        perturbations = 1  # one glued dof, perturbed once at the single refresh
        assert (do_steps - perturbations) / steps <= 2.0, name
    assert statistics["iterations"]["max_per_step"] == 2


def test_chain_10_follows_the_rigid_monolithic_chain(built, tmp_path):
    out = tmp_path / "chain_10.csv"
    statistics = simulate(built["ssp"] / "chain_10.ssp", out=out, stop=0.2).statistics
    result = chain.compare(out, 10)
    header, data = read_csv(out)
    positions = data[:, [header.index(f"m{i}.x[1]") for i in range(1, 11)]]
    # fixed joints: every mass at the same place, to the interface tolerance
    assert np.max(np.abs(positions - positions[:, :1])) <= statistics["master"]["tolerance"]
    assert result["relative_error"] < 1e-8 and result["peak"] > 1e-5
    assert statistics["iterations"]["mean_per_step"] <= 2.0


def test_stats_file_has_the_results_contract(built, tmp_path):
    out = tmp_path / "run.csv"
    simulate(built["ssp"] / "spring_mass_linear.ssp", out=out, stop=0.5)
    stats = json.loads(out.with_suffix(".stats.json").read_text())
    assert stats["status"] == "completed" and stats["steps"] == 50
    assert set(stats["components"]) == {"left", "right"}
    assert stats["components"]["left"]["functions"]["fmi2DoStep"]["calls"] >= 50
    assert 0 < stats["seconds_in_fmus"] < stats["wall_seconds"]
    header, data = read_csv(out)
    assert header == ["time", "left.x[1]", "right.x[1]", "right.x[2]", "right.a[2]", "j1.f_x"]
    assert data.shape == (51, 6) and data[0, 0] == 0.0 and data[-1, 0] == pytest.approx(0.5)


def test_explicit_coupling_is_a_one_trial_baseline(built, tmp_path):
    """The non-iterative baseline: one doStep per FMU per step (plus the first
    step's flexibility measurement), compatible only to what the predictor misses."""
    out = tmp_path / "explicit.csv"
    statistics = simulate(built["ssp"] / "spring_mass_linear.ssp", out=out, coupling="explicit",
                     predictor="quadratic").statistics
    steps = statistics["steps"]
    for component in statistics["components"].values():
        assert component["functions"]["fmi2DoStep"]["calls"] == steps + 2  # +perturb, redo
    result = spring_mass.compare(out, nonlinear=False)
    assert 1e-8 < result["relative_error"] < 1e-4  # measured 3.6e-6: worse than iterative
    assert statistics["master"]["coupling"] == "explicit"


def test_spring_mass_nonlinear_under_step_auto_stays_within_its_fixed_steps_band(built):
    """Against the monolithic twin the scene ships (a tenth of its step), --step auto at
    E = 1e-5 is at least as close as the scene's own fixed 0.01 s step over 0..2 s
    (measured: 1.53e-5 m against 3.11e-5 m, 0.49 of it), in 144 steps that start at
    7.8 ms while the start transient lasts (t < 0.25 s) and grow to 15.6 ms after."""
    import dsim
    from dsim.master.recording.results import read_columns

    ssp = built["ssp"] / "spring_mass_nonlinear.ssp"
    twin = read_columns(dsim.prepare(ssp).scene.reference)

    def off(result):
        return np.max(np.abs(result["right.x[2]"] - np.interp(
            result["time"], twin["time"], twin["right.x[2]"])))

    fixed = simulate(ssp, stop=2.0, handle_signals=False)
    execution = dsim.Execution(dsim.prepare(ssp, stop=2.0, step="auto",
                                            error_tolerance=1e-5, output_interval=0.5))
    auto = execution.run(handle_signals=False)
    assert auto.ok and fixed.ok
    print(f"auto {off(auto):.3g} m, fixed {off(fixed):.3g} m off the twin")
    assert off(auto) <= off(fixed)
    times = np.array(execution.controller.times)
    sizes = np.array(execution.controller.sizes)
    assert sizes.max() >= 2 * sizes.min()
    assert times[sizes == sizes.min()].max() < 0.5  # the small steps are at the start
