"""The process that supervises ``dsim run`` (master/tools/supervisor.py; docs/results.md,
"A run whose process dies"): whatever ends the process that steps the run (SIGKILL, as
the out-of-memory killer sends it; a crash in an FMU's native code), the files of a
failed run are finished, one line is said and the exit code is 1; with checkpoints
the run goes on from the last one by itself, to the bytes of a run never stopped."""
import json
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from dsim.master.running.interrupts import descendants
from tests.support.checkpoints import stepping_process
from tests.support.paths import DSIM, ROOT
from tests.support.scenes import oscillator_scene
from tests.support.third_party.build import OSCILLATOR_VARIABLES, c_fmu


def start(*args) -> subprocess.Popen:
    return subprocess.Popen([*DSIM, "run", *map(str, args), "--quiet"], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def rows_written(target: Path, process, count: int) -> None:
    partial = target.with_name(f".{target.name}.partial")
    deadline = time.monotonic() + 120
    while not (partial.exists() and partial.read_bytes().count(b"\n") > count):
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline
        time.sleep(0.02)


def test_a_stepping_process_killed_outright_leaves_a_failed_runs_files(built, tmp_path):
    """SIGKILL (what the kernel's out-of-memory killer sends) to the process that steps:
    the CSV under its name with every whole row, the statistics saying so, one line,
    exit 1, no temporary file left."""
    target = tmp_path / "run.csv"
    process = start(built["ssp"] / "spring_mass_nonlinear.ssp", "--stop", 1000, "--out",
                    target)
    rows_written(target, process, 500)
    os.kill(stepping_process(process), signal.SIGKILL)  # the child, not the supervisor
    out, err = process.communicate(timeout=60)
    assert process.returncode == 1, err
    [line] = err.splitlines()
    assert line.startswith("dsim: simulation failed: the process stepping the run ended "
                           "without finishing it (killed by SIGKILL) at t = ")
    lines = target.read_text().splitlines()
    assert len(lines) > 500 and lines[0].startswith("time,")
    assert all(len(row.split(",")) == len(lines[0].split(",")) for row in lines)
    stats = json.loads(target.with_suffix(".stats.json").read_text())
    assert (stats["status"], stats["signal"], stats["rows"]) == ("failed", "SIGKILL",
                                                                len(lines) - 1)
    assert stats["time_reached"] == float(lines[-1].split(",")[0])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.csv", "run.stats.json"]


def test_an_fmu_that_ends_its_process_leaves_a_failed_runs_files(built, tmp_path):
    """The C oscillator that calls _exit(70) in its step at t = 8 s: the rows on the disk
    kept (all but those of the last 50 ms at most, docs/results.md), exit 1 (not 70),
    the statistics say how it ended and where."""
    fmu = c_fmu(tmp_path / "c", "oscillator", "oscillator.c", OSCILLATOR_VARIABLES,
                defines=("CRASH_TIME=7.9995",))
    folder = oscillator_scene(tmp_path / "scene", built, fmu)
    target = tmp_path / "run.csv"
    process = start(folder, "--stop", 10, "--step", 0.001, "--out", target)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 1, err
    [line] = err.splitlines()
    assert "ended without finishing it (exit code 70) at t = " in line, line
    stats = json.loads(target.with_suffix(".stats.json").read_text())
    last = float(target.read_text().splitlines()[-1].split(",")[0])
    assert (stats["status"], stats["exit_code"], stats["time_reached"]) == ("failed", 70,
                                                                           last)
    assert 1.0 < last < 7.9995  # the step to 8 s crashed (7.999 carries round-off)


def test_an_out_of_memory_kill_of_the_stepping_process_leaves_a_failed_runs_files(
        built, tmp_path):
    """The real thing: the stepping process moved into a memory cgroup of 256 MiB, then
    its C FMU allocates without end (oscillator.c with HOG): the kernel's out-of-memory
    killer ends it, and the supervisor finishes the files as for any SIGKILL: every
    whole row, the statistics saying so, one line, exit 1."""
    from tests.support.memory_limit import memory_limit

    fmu = c_fmu(tmp_path / "c", "oscillator", "oscillator.c", OSCILLATOR_VARIABLES,
                defines=("HOG",))
    folder = oscillator_scene(tmp_path / "scene", built, fmu)
    target, trigger = tmp_path / "run.csv", tmp_path / "allocate-now"
    with memory_limit(256 << 20) as cgroup:
        process = subprocess.Popen(
            [*DSIM, "run", str(folder), "--stop", "1000", "--step", "0.001", "--out",
             str(target), "--quiet"], cwd=ROOT, stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, text=True, env={**os.environ, "OSCILLATOR_HOG": str(trigger)})
        rows_written(target, process, 200)
        cgroup.add(stepping_process(process))
        trigger.touch()
        _, err = process.communicate(timeout=120)
        kills = cgroup.oom_kills()
    assert process.returncode == 1, err
    assert kills == 1  # the kernel's killer, not the FMU's own end (exit code 71)
    [line] = err.splitlines()
    assert "ended without finishing it (killed by SIGKILL) at t = " in line, line
    lines = target.read_text().splitlines()
    stats = json.loads(target.with_suffix(".stats.json").read_text())
    assert (stats["status"], stats["signal"], stats["rows"]) == ("failed", "SIGKILL",
                                                                len(lines) - 1)
    assert stats["time_reached"] == float(lines[-1].split(",")[0]) > 0.2
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "allocate-now", "c", "run.csv", "run.stats.json", "scene"]


@pytest.mark.parametrize("restarts", [None, 0])
def test_with_checkpoints_the_run_goes_on_by_itself(built, tmp_path, restarts):
    """The stepping process killed after its second checkpoint: started again from the
    last one (one line says so) to the bytes of the run never stopped, the restart in
    its statistics; ``--restarts 0``: a failed run's files instead."""
    scene = built["ssp"] / "spring_mass_nonlinear.ssp"
    target = tmp_path / "run.csv"
    options = [] if restarts is None else ["--restarts", restarts]
    process = start(scene, "--stop", 40, "--out", target, "--checkpoint-every", 8, *options)
    folder = tmp_path / "run.checkpoints"
    deadline = time.monotonic() + 120
    while len(list(folder.glob("step-*"))) < 2:
        assert process.poll() is None and time.monotonic() < deadline, process.communicate()
        time.sleep(0.02)
    os.kill(stepping_process(process), signal.SIGKILL)
    _, err = process.communicate(timeout=300)
    stats = json.loads(target.with_suffix(".stats.json").read_text())
    if restarts == 0:
        assert process.returncode == 1 and stats["status"] == "failed", err
        return
    reference = tmp_path / "reference" / "run.csv"
    done = subprocess.run([*DSIM, "run", str(scene), "--stop", "40", "--out",
                           str(reference), "--quiet", "--no-supervisor"], cwd=ROOT,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert process.returncode == 0, err
    [line] = err.splitlines()
    assert "(killed by SIGKILL)" in line and "going on from its checkpoint at t = " in line
    assert target.read_bytes() == reference.read_bytes()
    [restart] = stats["restarts"]
    assert restart["ended"] == "killed by SIGKILL" and stats["status"] == "completed"
    assert stats["resumed"]["time"] == restart["time"]


def test_a_supervisor_killed_outright_takes_its_run_with_it(built, tmp_path):
    """SIGKILL to ``dsim`` itself: the stepping process dies with it (nothing runs on
    unseen), its rows under the temporary name for the next run to end."""
    target = tmp_path / "run.csv"
    process = start(built["ssp"] / "spring_mass_nonlinear.ssp", "--stop", 1000, "--out",
                    target)
    rows_written(target, process, 100)
    stepping = stepping_process(process)
    process.kill()
    process.wait()
    deadline = time.monotonic() + 10
    while Path(f"/proc/{stepping}").exists() and b"Z" not in Path(
            f"/proc/{stepping}/stat").read_bytes().split(b") ")[1][:1]:
        assert time.monotonic() < deadline, "the stepping process lives on"
        time.sleep(0.02)
    assert target.with_name(".run.csv.partial").exists()


def test_without_a_supervisor_dsim_steps_in_its_own_process(built, tmp_path):
    target = tmp_path / "run.csv"
    process = start(built["ssp"] / "spring_mass_nonlinear.ssp", "--stop", 1000, "--out",
                    target, "--no-supervisor")
    rows_written(target, process, 10)
    try:
        assert not descendants(process.pid)
    finally:
        process.kill()
        process.wait()
