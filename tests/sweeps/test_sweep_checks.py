"""A sweep checks what it is asked before its first point (a misspelled KPI column or
--vary name is one line, with the closest, and nothing is written), and says each
point's state in one word, in its summary and its table."""
from __future__ import annotations

import csv

import dsim
from dsim.master.sweeps.table import Point, count_states, state
from dsim.master.tools.cli import main
from tests.support.runs import one_error


def test_a_misspelled_kpi_is_refused_before_the_first_point(built, tmp_path, capsys):
    """Regression: --kpi 'max(right.y[2])' ran every point, printed nan and exited 0."""
    out = tmp_path / "sweep"
    assert main(["sweep", str(built["ssp"] / "spring_mass_nonlinear.ssp"), "--stop", "0.1",
                 "--step", "0.01,0.02", "--kpi", "max(right.y[2])", "--out", str(out)]) == 2
    line = one_error(capsys)
    assert "no recorded column matches 'right.y[2]'" in line and "closest: right.x[2]" in line
    assert not out.exists()  # nothing ran, nothing written
    assert main(["sweep", str(built["ssp"] / "spring_mass_nonlinear.ssp"), "--stop", "0.1",
                 "--step", "0.01,0.02", "--kpi", "final(right.x*)", "--out", str(out)]) == 2
    assert "final needs one column; 'right.x*' matches 2" in one_error(capsys)
    # the columns checked are those a run writes: outputs, joint forces, as chosen
    from dsim.master.sweeps.sweep import recorded_columns

    scene = built["ssp"] / "spring_mass_nonlinear.ssp"
    every = recorded_columns(dsim.prepare(scene))
    with open(dsim.simulate(scene, stop=0.02, out=tmp_path / "r.csv",
                            handle_signals=False).files["csv"]) as file:
        assert every == file.readline().strip().split(",")
    assert "j1.f_x" in every
    assert recorded_columns(dsim.prepare(scene, outputs=["right.x*"])) == [
        "time", "right.x[1]", "right.x[2]"]


def test_a_misspelled_vary_name_is_refused_with_the_closest(built, tmp_path, capsys):
    scene = str(built["ssp"] / "spring_mass_nonlinear.ssp")
    out = tmp_path / "sweep"
    assert main(["sweep", scene, "--vary", "stepp=0.01,0.02", "--out", str(out)]) == 2
    assert "'stepp' is not a setting (closest: step" in one_error(capsys)
    assert main(["sweep", scene, "--vary", "right.m[3]=5,6", "--out", str(out)]) == 2
    assert "m[3] would have no effect" in one_error(capsys)
    assert main(["sweep", scene, "--vary", "j1.k3=5,6", "--out", str(out)]) == 2
    assert "it has: k0, k1, c0, c1; closest: k1" in one_error(capsys)
    assert not out.exists()


def test_each_point_has_one_state_word():
    points = [Point({}, "completed", True), Point({}, "completed", False),
              Point({}, "failed"), Point({}, "bad input"), Point({}, "interrupted")]
    assert [state(p) for p in points] == ["completed", "unstable", "failed", "refused",
                                          "interrupted"]
    assert count_states(points) == ("1 completed, 1 unstable, 1 failed, 1 refused, "
                                    "1 interrupted")
    assert [p.finished for p in points] == [True, True, True, True, False]


def test_the_sweep_summary_says_each_points_state(built, tmp_path, capsys):
    out = tmp_path / "sweep"
    assert main(["sweep", str(built["ssp"] / "spring_mass_nonlinear.ssp"), "--stop", "2",
                 "--step", "0.02", "--predictor", "quadratic", "--vary",
                 "coupling=explicit,iterative", "--out", str(out)]) == 0
    shown = capsys.readouterr().out
    assert "sweep       2 points (1 completed, 1 failed)" in shown
    with open(out / "sweep.csv", newline="") as file:
        failed = [r["point"] for r in csv.DictReader(file) if r["status"] == "failed"]
    assert f"failed      point {failed[0]}: the run failed" in shown
    table = (out / "sweep.md").read_text()
    assert "(unstable)" not in table and "| failed |" in table
