"""A hung FMU can be stopped, and its rows are kept: the C oscillator built with
-DHANG_TIME never returns from the step that reaches t = 0.0505 s (step 51 of 1 ms),
so a run of `python -m dsim.master.tools.cli run` converges exactly 50 steps and then hangs in
fmi2DoStep (native code, where no Python signal handler runs).  The first signal asks
for a stop after a step that never ends; the second must end the process at once
with every converged row and the statistics on disk, and no process of the run left
(the isolated backend's Ray instance and workers)."""
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from dsim.master.recording.results import read_csv
from tests.support.hung_fmu import CONVERGED, ROWS, hung_scene  # noqa: F401 (a fixture)
from tests.support.paths import ROOT
from tests.support.results import rows_on_disk
from tests.support.scene_files import component, scene_folder, ssd
from tests.support.third_party.build import OSCILLATOR_VARIABLES, c_fmu


def start(scene: Path, target: Path, *options: str, **env: str) -> subprocess.Popen:
    """dsim run in a session of its own: every process it starts is found by it."""
    return subprocess.Popen([sys.executable, "-m", "dsim.master.tools.cli", "run", str(scene), "--out",
                             str(target), "--quiet", *options], cwd=ROOT,
                            stderr=subprocess.PIPE, text=True, start_new_session=True,
                            env={**os.environ, "OMP_NUM_THREADS": "1", **env})


def wait_for_the_hang(process, target: Path, seconds: float = 60) -> None:
    """Until every converged row is in the temporary file: the run hangs then (the
    rows came from the OS, so they survive whatever happens to the process)."""
    partial = target.with_name(f".{target.name}.partial")
    deadline = time.monotonic() + seconds
    while rows_on_disk(partial) < ROWS:
        assert process.poll() is None, process.stderr.read()
        assert time.monotonic() < deadline, f"{rows_on_disk(partial)} rows on disk"
        time.sleep(0.05)
    time.sleep(0.3)  # stuck: no row after these
    assert rows_on_disk(partial) == ROWS and process.poll() is None


def ended_by_one_signal(process, target: Path, stuck) -> dict:
    """``stuck()`` returns once the run is stuck; then one SIGINT: the process must end
    GRACE to GRACE + 5 s later with exit code 130.  The run's statistics."""
    from dsim.master.running.interrupts import GRACE

    try:
        stuck()
        process.send_signal(signal.SIGINT)
        sent = time.monotonic()
        _, err = process.communicate(timeout=60)
        took = time.monotonic() - sent
    finally:
        process.kill()
        process.wait()
    assert process.returncode == 130, err
    assert GRACE <= took < GRACE + 5.0, took
    return json.loads(target.with_suffix(".stats.json").read_text())


def _stat(pid) -> tuple[bytes, list[bytes]] | None:
    """A process's /proc stat line and its fields after the command's name (state,
    parent, group, session, ...), or None once it is gone."""
    try:
        data = Path(f"/proc/{pid}/stat").read_bytes()
    except OSError:
        return None
    return data, data[data.rindex(b")") + 2:].split()


def _live(fields: list[bytes]) -> bool:
    """Whether a process's state is a running one (a zombie has ended: only its exit
    status waits for a parent that may be gone too)."""
    return fields[0] not in (b"Z", b"X")


def alive(pid: int) -> bool:
    """Whether a process runs."""
    stat = _stat(pid)
    return stat is not None and _live(stat[1])


def session_processes(session: int) -> list[str]:
    """The live processes of a session: pid, state, command."""
    found = []
    for entry in os.listdir("/proc"):
        stat = _stat(entry)
        try:
            command = Path(f"/proc/{entry}/cmdline").read_bytes()
        except OSError:
            stat = None
        if stat is None:  # not a process, or gone
            continue
        data, fields = stat
        if _live(fields) and int(fields[3]) == session:
            found.append(f"{entry} {fields[0].decode()} {data[:60]!r} "
                         + command.replace(b"\0", b" ").decode(errors="replace")[:100])
    return found


@pytest.mark.parametrize("backend, name", [
    ("in-process", "SIGINT"), ("in-process", "SIGTERM"), ("isolated", "SIGINT"),
    ("isolated", "SIGTERM"), ("ray", "SIGTERM")])
def test_a_second_signal_ends_a_run_stuck_in_an_fmu_at_once_with_every_row(
        hung_scene, tmp_path, backend, name):
    number = signal.Signals[name]
    target = tmp_path / "out" / "run.csv"
    process = start(hung_scene, target, *{"in-process": [], "isolated": ["--isolate"],
                                          "ray": ["--backend", "ray"]}[backend])
    try:
        wait_for_the_hang(process, target)
        process.send_signal(number)
        time.sleep(0.5)
        assert process.poll() is None  # the first asks for a stop after a step never done
        process.send_signal(number)
        sent = time.monotonic()
        _, err = process.communicate(timeout=10)
        took = time.monotonic() - sent
    finally:
        process.kill()
        process.wait()
    assert process.returncode == 128 + number, err
    assert took < 2.0, took  # measured: 0.01 s in-process, 0.2 s isolated (deadline: 3 s)
    header, data = read_csv(target)
    assert header[:2] == ["time", "osc.s"] and data.shape[0] == ROWS
    assert np.allclose(np.diff(data[:, 0]), 1e-3) and abs(data[-1, 0] - 0.05) < 1e-12
    stats = json.loads(target.with_suffix(".stats.json").read_text())
    assert (stats["status"], stats["steps"], stats["time_reached"]) == (
        "interrupted", CONVERGED, data[-1, 0])
    assert stats["message"].startswith(f"interrupted by {name}, then ended at once by {name}")
    assert sorted(p.name for p in target.parent.iterdir()) == ["run.csv", "run.stats.json"]
    assert err.strip().splitlines()[-1].endswith(
        f"the {CONVERGED} converged steps are in {target}")
    assert session_processes(process.pid) == []  # the Ray instance and its workers too
    if backend != "in-process":
        worker = stats["components"]["osc"]["worker"]["pid"]
        assert worker != process.pid and not alive(worker)


def test_the_first_signal_ends_a_run_stuck_in_an_fmu_after_the_grace_period(hung_scene,
                                                                           tmp_path):
    """One Ctrl-C is enough: the step under way has GRACE seconds to finish; it never
    does, so the run ends as on a second signal, with every converged row."""
    from dsim.master.running.interrupts import GRACE

    target = tmp_path / "out" / "run.csv"
    process = start(hung_scene, target)
    stats = ended_by_one_signal(process, target, lambda: wait_for_the_hang(process, target))
    assert read_csv(target)[1].shape[0] == ROWS
    assert (stats["status"], stats["steps"]) == ("interrupted", CONVERGED)
    assert stats["message"].startswith(f"interrupted by SIGINT; the step under way did not "
                                       f"finish within {GRACE:g} s, then ended at once")


def test_the_first_signal_ends_a_set_up_stuck_in_an_fmu_after_the_grace_period(tmp_path):
    """An FMU that never leaves its initialization: the run never starts stepping, and
    one Ctrl-C still ends it GRACE seconds later, with the statistics and an empty CSV
    (before, only a second signal did)."""
    from dsim.master.running.interrupts import GRACE

    if shutil.which("gcc") is None:
        pytest.skip("no C compiler")
    fmu = c_fmu(tmp_path / "c", "oscillator", "oscillator.c", OSCILLATOR_VARIABLES,
                defines=("HANG_INITIALIZATION",))
    text = ssd("stuck", [component("osc", "resources/oscillator.fmu",
                                   {"m": 1.0, "k": 100.0, "s0": 0.01}, outputs=["s"])],
               stop=1.0, master='step="0.001"')
    scene = scene_folder(tmp_path / "scene", text, {"oscillator.fmu": fmu})
    target = tmp_path / "out" / "run.csv"
    hung = tmp_path / "hung"  # the FMU creates it as it starts to hang
    process = start(scene, target, OSCILLATOR_HUNG=str(hung))

    def stuck():
        # not a fixed sleep: on a loaded machine the import alone may take seconds, and
        # a signal before the run is under way is a plain KeyboardInterrupt
        deadline = time.monotonic() + 60
        while not hung.exists():
            assert process.poll() is None, process.stderr.read()
            assert time.monotonic() < deadline, "the FMU never reached its initialization"
            time.sleep(0.05)
        time.sleep(0.3)
        assert process.poll() is None and rows_on_disk(target) == -1  # no row, no start

    stats = ended_by_one_signal(process, target, stuck)
    assert (stats["status"], stats["steps"]) == ("interrupted", 0)
    assert stats["message"].startswith(f"interrupted by SIGINT; the set-up did not finish "
                                       f"within {GRACE:g} s, then ended at once")
    assert read_csv(target)[0] == ["time", "osc.s"]


def test_rows_are_on_disk_when_the_process_is_killed_outright(hung_scene, tmp_path):
    """The 50 steps take a few milliseconds, less than the 50 ms between two writes:
    the rows still reach the file while the step hangs, so SIGKILL keeps them (under
    the temporary name: nothing renames it)."""
    target = tmp_path / "run.csv"
    process = start(hung_scene, target)
    try:
        wait_for_the_hang(process, target)
    finally:
        process.kill()
        process.wait()
    partial = target.with_name(".run.csv.partial")
    assert not target.exists() and rows_on_disk(partial) == ROWS
    shutil.copy(partial, target)
    assert read_csv(target)[1].shape[0] == ROWS  # whole rows only


def test_two_signals_at_once_leave_a_consistent_run_when_no_fmu_hangs(block_fmus, tmp_path):
    """SIGINT twice in a row while the run steps (the main thread in Python, perhaps
    already finishing): the process ends with 130 and the files agree, whichever
    thread wrote them."""
    from tests.support.scenes import block_scene

    folder = block_scene(tmp_path / "scene", block_fmus["state"], stop=1e6)
    target = tmp_path / "run.csv"
    process = start(folder, target)
    try:
        partial = target.with_name(".run.csv.partial")
        deadline = time.monotonic() + 60
        while rows_on_disk(partial) < 100:
            assert time.monotonic() < deadline and process.poll() is None
            time.sleep(0.05)
        process.send_signal(signal.SIGINT)
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=10)
    finally:
        process.kill()
        process.wait()
    assert process.returncode == 130, err
    header, data = read_csv(target)
    stats = json.loads(target.with_suffix(".stats.json").read_text())
    assert stats["status"] == "interrupted" and stats["steps"] == data.shape[0] - 1 >= 99
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.csv", "run.stats.json",
                                                          "scene"]
