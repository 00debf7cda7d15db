"""Newton loops that round-off cannot defeat, and a build that a failed reference
does not stop (issue: results must not hang on the last bits)."""
import shutil

import numpy as np
import pytest

from dsim.fmus.newton import at_roundoff, failure_message, reciprocal_condition
from tests.support.paths import ROOT


def _four_bar_through(steps: int, perturb=None):
    """The monolithic parallelogram four bar (index-3 rows, H = 0.01 s) over ``steps``
    steps; ``perturb(bar)`` may change it first."""
    from dsim.build_fmus.twins.four_bar import whole_model

    bar = whole_model("fixed")
    if perturb:
        perturb(bar)
    for n in range(steps):
        bar.step(n * 0.01, 0.01)
    return bar


def test_roundoff_floor_is_relative_to_the_terms():
    assert at_roundoff([1e-14], 1.0)             # 45 ulps of 1
    assert not at_roundoff([1e-13], 1.0)         # 450 ulps
    assert at_roundoff([1e-5], 1e12)             # the same, scaled
    assert at_roundoff(np.zeros(3), np.zeros(3))
    assert not at_roundoff([1e-300], 0.0)        # exact terms: only an exact zero is round-off


def test_a_stalled_increment_with_the_residual_at_round_off_is_converged():
    """The four bar at its first collinear pass (t = 0.38 s): whatever BLAS kernel,
    Newton reaches the residual's round-off floor; a tolerance the increment can never
    meet there (1e-16 of the unknowns) does not fail the step, it ends on the
    round-off test and is counted."""
    def strict(bar):
        bar.newton_tolerance = 1e-16

    bar = _four_bar_through(60, strict)
    assert bar.newton.roundoff_steps >= 1
    assert bar.outputs()["newton_roundoff_steps"] == bar.newton.roundoff_steps
    # and the motion is the mechanism's: the coupler still translates
    assert abs(bar.q[1, 2]) < 1e-9


def test_a_step_that_does_not_converge_still_fails_and_says_why():
    """Two Newton iterations cannot solve a step from a poor predictor: the step fails
    with the time, the increment and the residual against its round-off floor."""
    from dsim.fmus.linkage import LinkageConvergenceError

    def short(bar):
        bar.max_newton = 1

    with pytest.raises(LinkageConvergenceError) as error:
        _four_bar_through(3, short)
    message = str(error.value)
    assert "linkage Newton did not converge at t = 0.01 s after 1 iterations" in message
    assert "times its round-off floor" in message


def test_near_singular_newton_matrix_is_named_in_the_message():
    singular = np.array([[1.0, 1.0], [1.0, 1.0 + 1e-12]])
    assert reciprocal_condition(singular) < 1e-11
    message = failure_message("linkage Newton", 0.38, 30, [1e-8], singular)
    assert "near-singular" in message and "ill-posed" in message
    assert "near-singular" not in failure_message("linkage Newton", 0.38, 30, [1e-8],
                                                  np.eye(2))


def test_interface_newton_accepts_the_round_off_floor_and_counts_it(built, tmp_path):
    """A tolerance below what double precision resolves in the ports' positions
    (1e-20 m on positions of about 1 m): the steps end at the residual's round-off
    floor (counted in the statistics) instead of failing on the iteration limit."""
    import dsim

    result = dsim.simulate(built["ssp"] / "spring_mass_nonlinear.ssp", stop=0.2,
                           tolerance=1e-20, out=tmp_path / "r.csv")
    assert result.status == "completed", result.message
    assert result.statistics["roundoff_steps"] > 0
    reference = dsim.simulate(built["ssp"] / "spring_mass_nonlinear.ssp", stop=0.2,
                              tolerance=1e-12, out=tmp_path / "ref.csv")
    assert result.statistics["roundoff_steps"] <= result.steps
    assert reference.statistics["roundoff_steps"] == 0
    gap = np.max(np.abs(result["right.x[2]"] - reference["right.x[2]"]))
    assert gap < 1e-11


def test_a_failed_reference_does_not_stop_the_build(built, tmp_path, monkeypatch):
    """The twin of a scene fails to compute (as the four bar's did on some CPUs): the
    build says so in one line, packs the scene without a reference and goes on."""
    import dsim.build_fmus.twins as twins
    from dsim.build_fmus.build import pack_scenes
    from dsim.fmus.linkage import LinkageConvergenceError

    root = tmp_path / "root"
    for scene in ("spring_mass_linear", "spring_mass_nonlinear"):
        shutil.copytree(ROOT / "ssp" / scene, root / "ssp" / scene)
    (root / "build" / "fmus").mkdir(parents=True)
    shutil.copy2(built["fmus"] / "SpringMass.fmu", root / "build" / "fmus")

    def fails():
        raise LinkageConvergenceError("linkage Newton did not converge at t = 0.37 s")

    monkeypatch.setitem(twins.TWINS, "spring_mass_linear", fails)
    said = []
    packed = pack_scenes(root, log=said.append)
    assert [p.name for p in packed] == ["spring_mass_linear.ssp", "spring_mass_nonlinear.ssp"]
    assert all(p.is_file() for p in packed)
    refusals = [line for line in said if "no monolithic reference" in line]
    assert len(refusals) == 1 and "spring_mass_linear" in refusals[0]
    assert "t = 0.37 s" in refusals[0]
    import zipfile
    assert "resources/reference.csv" not in zipfile.ZipFile(packed[0]).namelist()
    assert "resources/reference.csv" in zipfile.ZipFile(packed[1]).namelist()
