"""`dsim sweep`: the speed-accuracy trade of a scene, measured against a reference."""
import csv
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from dsim.build_fmus.twins.spring_mass import monolithic
from dsim.master.tools.cli import main
from tests.support.paths import ROOT


def reference_csv(path: Path, stop: float = 1.0, step: float = 2.5e-4) -> Path:
    """The monolithic chain of eq. 5.37 at a fine step: m3's position as right.x[2]."""
    times, positions = monolithic(False, stop=stop, step=step)
    with open(path, "w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(["time", "right.x[2]"])
        writer.writerows(zip(map(repr, times.tolist()), map(repr, positions[:, 2].tolist())))
    return path


def test_sweep_measures_error_time_and_names_the_cheapest_point(built, tmp_path, capsys):
    reference = reference_csv(tmp_path / "twin.csv")
    out = tmp_path / "sweep"
    code = main(["sweep", str(built["ssp"] / "spring_mass_linear.ssp"), "--stop", "1",
                 "--step", "0.005,0.01,0.02", "--coupling", "iterative,explicit",
                 "--reference", str(reference), "--columns", "right.x[2]",
                 "--out", str(out), "--target-error", "1e-3"])
    printed = capsys.readouterr().out
    assert code == 0
    with open(out / "sweep.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    assert len(rows) == 6 and {r["status"] for r in rows} == {"completed"}
    error = {(float(r["step"]), r["coupling"]): float(r["error"]) for r in rows}
    for step in (0.005, 0.01):  # iterative: the trapezoidal rule's second order
        assert 3.5 < error[(2 * step, "iterative")] / error[(step, "iterative")] < 4.5
    for step in (0.005, 0.01, 0.02):  # not iterating costs accuracy at every step
        assert error[(step, "explicit")] > error[(step, "iterative")]
    assert (out / "sweep.md").read_text().count("| yes |") >= 2  # the Pareto front
    assert (out / "sweep.png").read_bytes()[:4] == b"\x89PNG"
    assert len(list(out.glob("point_*.csv"))) == 6
    target = [line for line in printed.splitlines() if line.startswith("run it")]
    meeting = [r for r in rows if float(r["error"]) <= 1e-3]
    fastest = min(meeting, key=lambda r: float(r["wall_seconds"]))
    assert len(meeting) >= 2 and len(target) == 1  # the cheapest of those under 1e-3
    assert target[0].endswith(f"--step {fastest['step']} --coupling {fastest['coupling']}")


def test_sweep_measures_against_the_twin_the_scene_ships(built, tmp_path):
    out = tmp_path / "sweep"
    assert main(["sweep", str(built["ssp"] / "spring_mass_nonlinear.ssp"), "--stop", "1",
                 "--step", "0.01,0.02", "--tolerance", "1e-10", "--out", str(out)]) == 0
    with open(out / "sweep.csv", newline="") as file:
        error = {r["step"]: float(r["error"]) for r in csv.DictReader(file)}
    # the twin runs at a tenth of the scene's step: against it the error is the
    # trapezoidal rule's, second order, the gluing's (about 1e-9) far below
    assert 3.5 < error["0.02"] / error["0.01"] < 4.5
    assert "monolithic twin" in (out / "sweep.md").read_text()


def test_sweep_can_compare_with_its_tightest_point(built, tmp_path):
    out = tmp_path / "sweep"
    assert main(["sweep", str(built["ssp"] / "spring_mass_nonlinear.ssp"), "--stop", "1",
                 "--step", "0.01,0.0025", "--tolerance", "1e-6,1e-10",
                 "--reference", "tightest", "--out", str(out)]) == 0
    with open(out / "sweep.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    first = rows[0]  # the tightest runs first and is the reference: error 0
    assert (first["step"], first["tolerance"], float(first["error"])) == ("0.0025", "1e-10", 0.0)
    assert "the tightest point (step=0.0025 tolerance=1e-10)" in (out / "sweep.md").read_text()
    assert all(float(r["error"]) > 0 for r in rows[1:])


def test_bad_sweep_values_are_refused_before_anything_runs(built, tmp_path, capsys):
    out = tmp_path / "sweep"
    assert main(["sweep", str(built["ssp"] / "spring_mass_linear.ssp"), "--step", "0.01,-1",
                 "--coupling", "iterative,sideways", "--out", str(out)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines == ["dsim: error: sweep: step must be a finite number greater than 0, got -1",
                     "dsim: error: sweep: coupling 'sideways' is not one of: iterative, "
                     "explicit, causal, strong"]
    assert not out.exists()


def test_an_interrupted_sweep_keeps_its_finished_points(built, tmp_path):
    out = tmp_path / "sweep"
    process = subprocess.Popen(
        [sys.executable, "-m", "dsim", "sweep", str(built["ssp"] / "spring_mass_linear.ssp"),
         "--stop", "10", "--step", "0.01,0.005,0.0025,0.00125,0.000625", "--out", str(out)],
        cwd=ROOT, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not (out / "point_002.csv").exists() and not (
                out / ".point_002.csv.partial").exists():
            assert time.monotonic() < deadline and process.poll() is None
            time.sleep(0.05)
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=120)
    finally:
        process.kill()
    assert process.returncode == 130
    # the interrupted point is not finished: it runs again on a rerun
    assert "interrupted: 1 finished point kept" in err and "1 completed, 1 interrupted" in err
    with open(out / "sweep.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    assert [r["status"] for r in rows] == ["completed", "interrupted"]
    assert (out / "sweep.md").is_file() and (out / "sweep.png").is_file()
    assert np.isfinite(float(rows[0]["error"]))


def test_a_sweep_over_fidelity_sets_ranks_them_against_the_finest(built, tmp_path):
    """four_post's parameter sets against its default fine plate: more Craig-Bampton
    modes, less error; a rigid body misses the plate's bending altogether."""
    scene = built["ssp"] / "four_post_flexible.ssp"
    fine = tmp_path / "fine.csv"
    assert main(["run", str(scene), "--stop", "0.6", "--out", str(fine), "--quiet"]) == 0
    out = tmp_path / "sweep"
    assert main(["sweep", str(scene), "--stop", "0.6", "--parameter-set", "rigid,cb4,cb12,cb30",
                 "--reference", str(fine), "--out", str(out)]) == 0
    with open(out / "sweep.csv", newline="") as file:
        error = {r["parameter_set"]: float(r["error"]) for r in csv.DictReader(file)}
    assert error["cb30"] < error["cb12"] < error["cb4"] < 0.01 < error["rigid"]
