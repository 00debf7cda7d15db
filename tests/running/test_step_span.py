"""A step that does not fit the span (longer than it, or not dividing it) is said, in
validate, run and the Python API, and refused with --strict (master/running/timeline.py)."""
import pytest

import dsim
from dsim.master.tools.cli import main
from tests.support.runs import one_error


@pytest.mark.parametrize("step, said", [
    ("20", "step 20 s is longer than the span 0 .. 10 s: the run takes one step of 10 s"),
    ("3", "step 3 s does not divide the span 0 .. 10 s: the run takes 3 steps of 3 s and "
          "a last one of 1 s")])
def test_a_step_that_does_not_fit_the_span_is_said_and_refused_when_strict(
        built, tmp_path, capsys, step, said):
    scene = str(built["ssp"] / "spring_mass_linear.ssp")
    assert main(["validate", scene, "--stop", "10", "--step", step]) == 0
    assert said in capsys.readouterr().err
    assert main(["validate", scene, "--stop", "10", "--step", step, "--strict"]) == 2
    assert said in one_error(capsys)
    assert main(["run", scene, "--stop", "10", "--step", step, "--out",
                 str(tmp_path / "r.csv")]) == 0
    shown = capsys.readouterr()
    assert said in shown.err and f"({said.split(': ', 1)[1]})" in shown.out
    result = dsim.simulate(scene, stop=10.0, step=float(step), handle_signals=False)
    assert result.ok and any(said in w for w in result.warnings)
    assert result.steps == (1 if step == "20" else 4)
    assert dsim.simulate(scene, stop=10.0, step=2.5, handle_signals=False).warnings == []
