"""What the checkpoint tests share (docs/checkpoints.md): statistics without what a
clock measured, a run with checkpoints, and a sweep from one checked on a backend."""
from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import time
from pathlib import Path

import dsim
from tests.support.paths import DSIM, ROOT


def timeless(statistics):
    """The statistics without what a clock measured and what says how the run went
    on (checkpoints written, the checkpoint resumed from, the supervisor's restarts)."""
    if isinstance(statistics, dict):
        return {k: timeless(v) for k, v in statistics.items()
                if "seconds" not in k and k not in ("phases", "checkpoints", "resumed",
                                                    "restarts")}
    if isinstance(statistics, list):
        return [timeless(v) for v in statistics]
    return statistics


def checkpoints_of(built, tmp_path, **settings) -> Path:
    """A run of spring_mass_nonlinear to 1 s with a checkpoint every 0.25 s, all kept:
    its checkpoint folder."""
    result = dsim.simulate(built["ssp"] / "spring_mass_nonlinear.ssp", stop=1.0,
                           out=tmp_path / "run.csv", checkpoint_every=0.25,
                           checkpoint_keep=10, handle_signals=False, **settings)
    assert result.status == "completed"
    return tmp_path / "run.checkpoints"


def sweep_from_checkpoint(built, tmp_path, capsys, backend: str) -> None:
    """``dsim sweep --from`` on ``backend``: run to 1 s once, then two tolerances from
    its last checkpoint (0.75 s) to 1.5 s; each point's rows start there with the
    checkpoint's state (the same first row)."""
    from dsim.master.tools.cli import main

    scene = built["ssp"] / "spring_mass_nonlinear.ssp"
    folder = checkpoints_of(built, tmp_path)
    first = (tmp_path / "run.csv").read_text().splitlines()[76]  # the row at 0.75 s
    out = tmp_path / "sweep"
    assert main(["sweep", str(scene), "--from", str(folder), "--stop", "1.5", "--tolerance",
                 "1e-6,1e-9", "--out", str(out), "--backend", backend]) == 0, \
        capsys.readouterr().err
    for point in ("point_001", "point_002"):
        rows = (out / f"{point}.csv").read_text().splitlines()
        assert rows[1] == first and rows[-1].startswith("1.5,")
        started = json.loads((out / f"{point}.stats.json").read_text())["started_from"]
        assert started["time"] == 0.75


def _dsim(*args, env=None):
    return subprocess.run([*DSIM, *map(str, args)], capture_output=True, text=True,
                          timeout=300, cwd=ROOT, env=env)


def stepping_process(supervisor: subprocess.Popen) -> int:
    """The pid of the child that steps a supervised ``dsim run`` (master/tools/
    supervisor.py): ``python -m dsim run`` below the supervisor."""
    from dsim.master.running.interrupts import descendants

    deadline = time.monotonic() + 60
    while True:
        for pid in sorted(descendants(supervisor.pid)):
            try:
                argv = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
            except OSError:
                continue
            if b"dsim" in argv and b"run" in argv:
                return pid
        assert supervisor.poll() is None and time.monotonic() < deadline
        time.sleep(0.02)


def killed_and_resumed(path, folder: Path, stop: float, every: float, *options,
                       stepping: bool = False, env=None, both=()) -> tuple:
    """``dsim run PATH --checkpoint-every EVERY OPTIONS`` killed with SIGKILL at a random
    moment after its first checkpoint (``stepping``: its stepping child, which the
    supervisor starts again from the last checkpoint by itself; else ``dsim`` itself,
    then ``dsim run --resume``), and the same run never stopped, in-process: each
    one's CSV bytes and statistics (``env``: the environment of the killed run's
    commands, a Ray cluster's token; ``both``: options of both runs, a scenario)."""
    reference = folder / "reference" / "run.csv"
    done = _dsim("run", path, "--stop", stop, "--out", reference, "--checkpoint-every",
                 every, "--quiet", *both)
    assert done.returncode == 0, done.stderr
    out = folder / "killed" / "run.csv"
    process = subprocess.Popen([*DSIM, "run", str(path), "--stop", str(stop), "--out",
                                str(out), "--checkpoint-every", str(every), "--quiet",
                                *map(str, both), *map(str, options)], cwd=ROOT,
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                               env=env)
    checkpoints = out.with_name("run.checkpoints")
    deadline = time.monotonic() + 180
    while not (checkpoints.is_dir() and any(checkpoints.glob("step-*"))):
        assert process.poll() is None and time.monotonic() < deadline, process.communicate()
        time.sleep(0.02)
    time.sleep(random.uniform(0.0, 0.5))
    if stepping:
        os.kill(stepping_process(process), signal.SIGKILL)
        _, err = process.communicate(timeout=300)
        assert process.returncode == 0, err
        assert "going on from its checkpoint" in err, err
    else:
        process.send_signal(signal.SIGKILL)
        process.wait()
        resumed = _dsim("run", "--resume", checkpoints, "--quiet", env=env)
        assert resumed.returncode == 0, resumed.stderr
    return ((reference.read_bytes(), json.loads(reference.with_name("run.stats.json")
                                                .read_text())),
            (out.read_bytes(), json.loads(out.with_name("run.stats.json").read_text())))
