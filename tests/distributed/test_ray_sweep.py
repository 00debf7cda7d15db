"""`dsim sweep --backend ray`: points side by side as Ray tasks, each run in-process in
its worker; the same points, errors and files as the serial sweep, progress as points
finish, and an interrupt that ends the running points after their current step."""
import csv
import glob
import os
import shutil
import signal
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from dsim.master.tools.cli import main
from dsim.master.sweeps.sweep import TIGHTEST, Sweep, run_sweep
from tests.support.paths import DSIM, ROOT
from tests.support.scenes import block_scene


def rows(path: Path) -> list[dict]:
    with open(path, newline="") as file:
        return list(csv.DictReader(file))


def test_a_ray_sweep_measures_what_the_serial_sweep_measures(built, ray_local, tmp_path):
    scene = built["ssp"] / "spring_mass_nonlinear.ssp"
    grid = {"step": ["0.005", "0.01", "0.02", "0.04"], "predictor": ["linear", "constant"]}
    serial, _ = run_sweep(scene, Sweep(dict(grid), fixed={"stop": "2"}, reference=TIGHTEST),
                          tmp_path / "serial")
    seen = []
    spread, interrupted = run_sweep(scene, Sweep(dict(grid), fixed={"stop": "2",
                                                                    "backend": "ray"},
                                                 reference=TIGHTEST),
                                    tmp_path / "spread", lambda *args: seen.append(args))
    assert interrupted is None and len(spread) == len(serial) == 8
    assert [done for done, total, _ in seen] == list(range(1, 9))
    assert {total for _, total, _ in seen} == {8}
    for a, b in zip(serial, spread):
        assert (a.settings, a.status, a.steps, a.lambda_refreshes) == \
            (b.settings, b.status, b.steps, b.lambda_refreshes)
        assert a.error == b.error and a.iterations_per_step == b.iterations_per_step
        assert b.results.read_bytes() == a.results.read_bytes()
        assert b.results.with_suffix(".stats.json").is_file()
    assert serial[0].error == 0.0 and max(p.error for p in serial) > 1e-4
    spread_rows = rows(tmp_path / "spread" / "sweep.csv")
    assert sorted(r["step"] + r["predictor"] for r in spread_rows) == \
        sorted(r["step"] + r["predictor"] for r in rows(tmp_path / "serial" / "sweep.csv"))
    assert (tmp_path / "spread" / "sweep.md").is_file()
    assert (tmp_path / "spread" / "sweep.png").is_file()


def test_a_point_whose_fmu_crashes_its_worker_is_a_failed_row_and_the_sweep_goes_on(
        block_fmus, ray_local, tmp_path, capsys):
    """The block aborts its process at t = 0.0505 s: the 0.04 s point completes, the
    0.2 s point takes its worker down (in-process it would take dsim down)."""
    folder = block_scene(tmp_path / "scene", block_fmus["state"], failure=4, fail_time=0.0505)
    code = main(["sweep", str(folder), "--stop", "0.2,0.04,0.03", "--backend", "ray",
                 "--out", str(tmp_path / "sweep")])
    assert code == 0
    found = {r["stop"]: r for r in rows(tmp_path / "sweep" / "sweep.csv")}
    assert found["0.2"]["status"] == "failed" and "worker process" in found["0.2"]["message"]
    assert found["0.04"]["status"] == found["0.03"]["status"] == "completed"
    # the first point that completed is the reference; both follow the same trajectory
    assert float(found["0.04"]["error"]) == float(found["0.03"]["error"]) == 0.0
    assert "point 3/3" in capsys.readouterr().err


def test_an_interrupted_ray_sweep_ends_its_running_points_and_starts_no_other(built):
    """Three long points on a local Ray instance of two CPUs: SIGINT once the two first
    are running ends both after their current step, and the third never starts."""
    folder = Path(tempfile.mkdtemp(prefix="dsimtmp", dir="/tmp"))  # the workers' TMPDIR
    out = folder / "sweep"
    process = subprocess.Popen(
        DSIM + ["sweep", str(built["ssp"] / "spring_mass_linear.ssp"), "--stop", "100",
                "--step", "0.01,0.005,0.0025", "--out", str(out), "--backend", "ray"],
        cwd=ROOT, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "TMPDIR": str(folder), "OMP_NUM_THREADS": "1"})
    try:
        deadline = time.monotonic() + 180
        while len(glob.glob(str(folder / "dsim-point-*" / ".point_*.csv.partial"))) < 2:
            assert time.monotonic() < deadline and process.poll() is None
            time.sleep(0.05)
        time.sleep(0.5)  # a few steps in
        signalled = time.monotonic()
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=120)
        took = time.monotonic() - signalled
        assert process.returncode == 130, err
        assert "interrupted: 0 finished points kept" in err and "2 interrupted" in err
        found = rows(out / "sweep.csv")
        assert [r["status"] for r in found] == ["interrupted", "interrupted"]
        points = sorted(out.glob("point_*.csv"))
        assert len(points) == 2 and (out / "sweep.md").is_file()
        kept = sorted(np.loadtxt(p, delimiter=",", skiprows=1, ndmin=2).shape[0] for p in points)
        assert kept == sorted(int(r["steps"]) + 1 for r in found)
        assert 1 < kept[0] and kept[1] < 10001  # stopped between the start and the end
        assert took < 60
    finally:
        process.kill()
        shutil.rmtree(folder, ignore_errors=True)


def test_a_point_goes_on_when_the_sweeps_stop_flag_is_lost(ray_local):
    """The flag a running point looks at between steps (a Ray actor) lost, as with a
    node of the cluster that held it: the point is not failed for it, it runs on (a
    rerun of a sweep with a point lost with its node failed that point when the flag
    had been on the lost node)."""
    from dsim.master.running.backends.ray.points import POLL_SECONDS, StopFlag, _StopRequested

    flag = ray_local.remote(StopFlag).options(num_cpus=0).remote()
    ray_local.get(flag.get.remote())
    ray_local.kill(flag)
    stop_requested = _StopRequested(flag)
    deadline = time.monotonic() + 20 * POLL_SECONDS
    answers = set()
    while time.monotonic() < deadline:  # asks, finds the answer an error, asks no more
        answers.add(stop_requested())
        time.sleep(POLL_SECONDS / 5)
    assert answers == {0} and stop_requested.lost
