"""Stability at the extremes: a diverging run is told from a hard one, a failed step
is cut where the FMUs allow it, and a mechanism passes its singular configuration."""
import numpy as np
import pytest

import dsim
from dsim.master.recording.results import read_columns
from dsim.master.running.couplings.divergence import EnvelopeWatch, newton_diverging
from dsim.master.sweeps.sweep import error_against


def envelope_verdict(residuals) -> int | None:
    """The step (1-based) at which the explicit coupling's watch calls divergence."""
    watch = EnvelopeWatch()
    for k, residual in enumerate(residuals, start=1):
        if watch.add(float(residual)) is not None:
            return k
    return None


def test_the_envelope_watch_tells_geometric_growth_from_a_start_from_rest():
    steps = np.arange(1, 1001)
    # an unstable explicit coupling: oscillating, growing 1.6x per step in envelope
    unstable = 1e-8 * 1.6 ** steps * np.abs(np.cos(2.0 * steps))
    assert envelope_verdict(unstable) <= 60
    # a response from rest that grows like t^5, and a steady oscillation: not divergence
    assert envelope_verdict(1e-12 * steps ** 5.0) is None
    assert envelope_verdict(1e-6 * np.abs(np.sin(0.3 * steps))) is None


def test_newton_divergence_needs_a_fresh_flexibility_to_be_called():
    growing = [50.0, 3.0, 8e4]
    assert newton_diverging(growing, refreshed=1)
    assert not newton_diverging(growing, refreshed=0)  # a stale Lambda: refresh first
    assert not newton_diverging([50.0, 3.0, 2.0e4], refreshed=1)


def test_the_forces_test_sees_the_force_error_a_small_residual_hides():
    """Two joint dofs whose forces, pulled together, barely move anything (a gluing
    matrix of compliances 1e-5 m/N with a 1e-6 relative gap between its rows, a four
    bar's axial loop near collinear): a residual within 1e-8 m leaves a force correction
    of 500 N to come, which the forces test counts and the residual test does not."""
    from dsim.master.running.couplings.convergence import CONVERGENCE_TESTS, what_is_left
    from dsim.master.running.couplings.iterative import DenseFactor

    jacobian = 1e-5 * np.array([[1.0, 1.0], [1.0, 1.0 + 1e-6]])
    residual = np.array([0.0, 5e-9])                   # m, within the tolerance
    tolerance = np.full(2, 1e-8)
    factor, compliance = DenseFactor(jacobian), np.diag(jacobian)
    correction = factor.solve(residual)
    assert np.max(np.abs(correction)) == pytest.approx(500.0, rel=1e-3)   # N
    assert CONVERGENCE_TESTS["residual"](residual, tolerance, factor, compliance) == 0.5
    assert CONVERGENCE_TESTS["forces"](residual, tolerance, factor, compliance) == \
        pytest.approx(500.0 * 1e-5 / 1e-8, rel=1e-3)
    _, left = what_is_left(residual, tolerance, factor, compliance)   # what a failure says
    assert "residual within the tolerance" in left and "worth 5.00" in left
    # a well-conditioned matrix: the two tests agree on what is converged
    diagonal = 1e-5 * np.eye(2)
    factor = DenseFactor(diagonal)
    assert CONVERGENCE_TESTS["forces"](residual, tolerance, factor, np.diag(diagonal)) == \
        pytest.approx(0.5)
    # before the first factor there is no correction to judge
    assert CONVERGENCE_TESTS["forces"](residual, tolerance, None, None) == 0.5


def test_the_dense_gluing_solve_is_scipys_lu_solve_to_the_bit():
    """The factored gluing matrix solves through the LAPACK routine lu_solve calls,
    looked up once: the same bits for vectors and blocks of any scale, and lu_solve
    itself for what that routine cannot take (integers)."""
    from scipy.linalg import lu_solve

    from dsim.master.running.couplings.iterative import DenseFactor

    rng = np.random.default_rng(2)
    for n in (2, 17, 64):
        factor = DenseFactor(rng.normal(size=(n, n)) + n * np.eye(n))
        for rhs in (rng.normal(size=n) * 1e-9, rng.normal(size=n) * 1e7,
                    rng.normal(size=(n, 3))):
            expected = lu_solve((factor.lu, factor.pivots), rhs, check_finite=False)
            assert factor.solve(rhs).tobytes() == expected.tobytes()
        whole = rng.integers(-3, 3, size=n)
        assert np.array_equal(factor.solve(whole),
                              lu_solve((factor.lu, factor.pivots), whole, check_finite=False))


def test_an_unstable_explicit_run_stops_before_its_values_overflow(built):
    result = dsim.simulate(built["ssp"] / "frame_split.ssp", coupling="explicit", stop=0.05)
    assert result.status == "failed" and result.exit_code == 1
    assert "the explicit coupling diverged: the interface residual grew" in result.message
    assert result.steps < 60  # caught within the watch's first window
    assert all(np.all(np.isfinite(result[name])) for name in result.signals)


def test_a_stable_explicit_run_is_not_called_diverging(built):
    result = dsim.simulate(built["ssp"] / "spring_mass_linear.ssp", coupling="explicit",
                           predictor="quadratic")
    assert result.status == "completed"


def test_a_step_newton_cannot_finish_is_cut_and_the_run_passes(built):
    """Two iterations at 1e-12 are too few for some steps of the nonlinear joint: the
    master halves those steps (the SpringMass FMU accepts variable steps) and the run
    stays as close to the monolithic twin as the uncut one."""
    scene = built["ssp"] / "spring_mass_nonlinear.ssp"
    cut = dsim.simulate(scene, stop=2.0, max_iterations=2, tolerance=1e-12)
    uncut = dsim.simulate(scene, stop=2.0, tolerance=1e-12)
    refused = dsim.simulate(scene, stop=2.0, max_iterations=2, tolerance=1e-12, step_cuts=0)
    assert cut.status == "completed" and refused.status == "failed"
    assert cut.statistics["step_cuts"] > 10 and uncut.statistics["step_cuts"] == 0
    assert "it passed in steps of 0.005 s" in cut.warnings[0]
    twin = read_columns(dsim.load_scene(scene).reference)  # the twin the scene ships
    error_cut, error_uncut = (error_against(run.signals, twin, ["right.x[2]"])
                              for run in (cut, uncut))
    assert error_cut <= 1.01 * error_uncut


def test_fixed_joints_pass_the_four_bar_singular_points_on_the_penalized_measure(built):
    """Table 5.1's fixed four bar fails on the displacement measure under the
    trapezoidal rule (tests/fmus/test_linkage_scenes.py); on the penalized one it passes
    both kinds of collinear position (crank and coupler folded at 0.375 s, stretched at
    0.875 s; the second turn repeats them) and equals the monolithic four bar; at
    H = 0.005 s steps land exactly on them, where the gluing matrix loses rank and Newton
    solves in the least-squares sense."""
    scene = built["ssp"] / "four_bar_singular_penalized.ssp"
    twin = read_columns(dsim.load_scene(scene).reference)
    on_grid = dsim.simulate(scene, stop=1.0)
    assert on_grid.status == "completed"
    assert error_against(on_grid.signals, twin, ["A.f_x", "A.f_y"]) < 1e-8
    landing = dsim.simulate(scene, step=0.005, stop=1.0)
    assert landing.status == "completed"
    assert landing.statistics["least_squares_steps"] == 2
    assert [w.split(":")[0] for w in landing.warnings] == [
        f"step {k} (t = {t} s)" for k, t in ((75, 0.375), (175, 0.875))]
    # the step that lands on the singular point leaves the axial split of the joint
    # forces where the predictor had it: a dip of under 2 % of the peak force there
    force = np.hypot(landing["A.f_x"], landing["A.f_y"])
    assert abs(force[75] - 0.5 * (force[74] + force[76])) < 0.02 * force.max()


def run_testbed(bed, tmp_path, step, stop, coupling="iterative", **settings):
    """A glued run of the testbed and its error against the monolithic twin."""
    from examples.testbed import monolithic, write_scene

    scene = write_scene(bed, tmp_path, f"testbed_{coupling}", step, stop, tolerance=1e-12)
    result = dsim.simulate(scene, coupling=coupling, **settings)
    twin = monolithic(bed, step, stop)
    return result, twin, error_against(result.signals, twin,
                                       ["left.x[1]", "right.x[1]", "right.x[2]"])


@pytest.mark.parametrize("change", [dict(k0=1e9, c0=0.0), dict(k0=1e2),
                                    dict(joint="fixed", m2=1e-3), dict(joint="fixed", m2=1e5)])
def test_the_iterative_coupling_equals_the_twin_at_extreme_stiffness_and_mass_ratio(
        built, tmp_path, change):
    """Joint stiffness 1e2 and 1e9 N/m (a shortest period 22 times below the step),
    mass ratio 1e-4 and 1e4 across a fixed joint: two iterations a step, the twin's
    positions to 1e-9 of their peak."""
    from examples.testbed import Testbed

    result, _, error = run_testbed(Testbed(**change), tmp_path, 0.01, 2.0)
    assert result.status == "completed" and error < 1e-9
    assert result.statistics["iterations"]["max_per_step"] <= 2


def test_a_macro_step_above_the_shortest_period_stays_with_the_twin(built, tmp_path):
    from examples.testbed import Testbed

    bed = Testbed(k0=1e4, c0=0.0)
    step = 3.0 * bed.highest_period()
    result, _, error = run_testbed(bed, tmp_path, step, 40 * step)
    assert result.status == "completed" and error < 1e-12
    explicit, _, _ = run_testbed(bed, tmp_path, step, 200 * step, coupling="explicit")
    assert explicit.status == "failed" and "explicit coupling diverged" in explicit.message


def test_undamped_energy_drifts_no_more_than_the_twins(built, tmp_path):
    """3,000 undamped steps of a free vibration: the trapezoidal rule keeps
    the energy of the linear twin to round-off, and the iterative coupling keeps it as
    well (1e-14 of it measured); the explicit one leaks it (1.4 % measured)."""
    from examples.testbed import Testbed, energy

    bed = Testbed(F0=0.0, x0=0.01, k0=1e4, c0=0.0)
    result, twin, error = run_testbed(bed, tmp_path, 1e-3, 3.0)
    glued, reference = energy(bed, result.signals), energy(bed, twin)
    assert np.max(np.abs(glued - glued[0])) < 1e-10 * reference[0]
    assert error < 1e-9
    explicit, _, _ = run_testbed(bed, tmp_path, 1e-3, 3.0, coupling="explicit")
    leaked = energy(bed, explicit.signals)
    assert np.max(np.abs(leaked - leaked[0])) > 1e-4 * reference[0]


def test_zero_and_huge_loads(built, tmp_path):
    """At rest nothing moves (exact zeros, no NaN from a zero residual); a 1e12 N load
    moves the masses by about 1e10 m, where an absolute 1e-12 m tolerance is below
    round-off: a tolerance relative to the motion keeps the run with the twin."""
    from examples.testbed import Testbed

    still, _, _ = run_testbed(Testbed(F0=0.0), tmp_path, 0.01, 1.0)
    assert still.status == "completed"
    assert all(not np.any(still[name]) for name in still.signals if name != "time")
    huge, _, error = run_testbed(Testbed(F0=1e12), tmp_path, 0.01, 2.0,
                                 relative_tolerance=1e-12)
    assert huge.status == "completed" and error < 1e-12
