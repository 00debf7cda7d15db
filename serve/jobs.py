"""Runs and sweeps in their own processes: a queue with a few slots, one thread
that starts queued jobs and reaps ended ones, cancelling, and putting the
database right after a server that died (:meth:`Jobs.reconcile`).

A job's process is :mod:`dsim.serve.worker`; whatever happens to it (an FMU that
aborts or crashes it, a kill) ends that job, never the server: the server only
ever sees a return code and the files the worker left.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from dsim.serve.owner import owner_alive
from dsim.serve.store import ACTIVE, Store

#: seconds a worker gets to stop after SIGTERM when the server shuts down
STOP_GRACE = 10.0
#: seconds a worker gets to end after a second cancel (it ends at once, with its rows
#: and statistics, unless something is badly wrong) before it is killed
KILL_GRACE = 5.0


def child_env() -> dict:
    """The environment of a child process (this interpreter, so the dsim installed
    here) with numeric libraries on one thread each, since runs are already processes
    side by side."""
    env = dict(os.environ)
    env.setdefault("OMP_NUM_THREADS", "1")
    return env


def salvage_csv(folder: Path) -> None:
    """A worker killed outright leaves its rows in ``.results.csv.partial``: keep its
    whole rows under the final name, as dsim does for a run that ends."""
    partial, target = folder / ".results.csv.partial", folder / "results.csv"
    if target.exists() or not partial.exists():
        return
    data = partial.read_bytes()
    partial.with_name(".results.csv.salvaged").write_bytes(data[:data.rfind(b"\n") + 1])
    os.replace(partial.with_name(".results.csv.salvaged"), target)
    partial.unlink(missing_ok=True)


def _read_json(path: Path):
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _csv_reach(folder: Path) -> tuple[int | None, float | None]:
    """Converged steps and time reached of the CSV a worker left (None: none)."""
    try:
        lines = (folder / "results.csv").read_text().splitlines()
    except OSError:
        return None, None
    if len(lines) < 2:
        return None, None
    return len(lines) - 2, float(lines[-1].split(",", 1)[0])


def _log_tail(folder: Path) -> str:
    try:
        lines = (folder / "worker.log").read_text(errors="replace").strip().splitlines()
    except OSError:
        return ""
    return lines[-1][:300] if lines else ""


class Jobs:
    """Starts queued runs of ``store`` (at most ``slots`` at once) and records how
    each ended."""

    def __init__(self, store: Store, slots: int = 2):
        self.store = store
        self.slots = max(1, slots)
        self.processes: dict[int, subprocess.Popen] = {}
        self.lock = threading.Lock()
        self.wake = threading.Event()
        #: run id -> when its worker is killed if it has not ended (after a second cancel)
        self.kill_at: dict[int, float] = {}
        self.stopping = False
        self.thread: threading.Thread | None = None

    # --- life of the server ----------------------------------------------------------
    def start(self) -> None:
        """Put the database right after the last server, then start the thread."""
        self.reconcile()
        self.thread = threading.Thread(target=self._loop, name="dsim-serve-jobs", daemon=True)
        self.thread.start()

    def reconcile(self) -> None:
        """Runs that a dead server left queued or running: ended as the files say,
        else interrupted (the worker notices its server is gone and stops).  A run
        whose server may still be alive is left alone: only its owner finalises it."""
        me = self.store.owner
        for run in self.store.all("SELECT * FROM runs WHERE status IN ('queued', 'running') "
                                  "AND owner IS NOT ?", me):
            if owner_alive(run["owner"]):
                continue
            with self.store.connect() as db:  # taken over once, by one server
                if not db.execute("UPDATE runs SET owner = ? WHERE id = ? AND owner IS ?",
                                  (me, run["id"], run["owner"])).rowcount:
                    continue
            if run["status"] == "queued":
                self.store.update_run(run["id"], status="interrupted", ended=time.time(),
                                      message="never started: the server stopped first")
                continue
            self._wait_gone(run["pid"])
            self.finalize(run["id"], None, server_died=True)

    @staticmethod
    def _wait_gone(pid: int | None, seconds: float = 5.0) -> None:
        """Give a worker whose server died the time to stop by itself."""
        if not pid:
            return
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            try:
                cmdline = Path(f"/proc/{pid}/cmdline").read_bytes()
            except OSError:
                return
            if b"dsim.serve.worker" not in cmdline:
                return
            time.sleep(0.1)

    def shutdown(self) -> None:
        """Stop every running job (they keep what they computed) and the thread."""
        self.stopping = True
        self.wake.set()
        if self.thread:
            self.thread.join(timeout=5)
        with self.lock:
            processes = dict(self.processes)
        for process in processes.values():
            _signal(process, signal.SIGTERM)
        deadline = time.monotonic() + STOP_GRACE
        for run_id, process in processes.items():
            try:
                process.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                _signal(process, signal.SIGKILL)
                process.wait()
            self.finalize(run_id, process.returncode, server_died=True)
        for run in self.store.all("SELECT id FROM runs WHERE status = 'queued' AND owner IS ?",
                                  self.store.owner):
            self.store.update_run(run["id"], status="interrupted", ended=time.time(),
                                  message="never started: the server stopped first")

    # --- the queue ---------------------------------------------------------------------
    def submit(self, run_id: int) -> None:
        """A queued run is ready to start."""
        self.wake.set()

    def _loop(self) -> None:
        while not self.stopping:
            self.wake.wait(0.2)
            self.wake.clear()
            try:
                self._reap()
                self._start_queued()
            except Exception as error:  # the thread must outlive one bad job
                print(f"dsim serve: jobs: {type(error).__name__}: {error}", file=sys.stderr)

    def _reap(self) -> None:
        with self.lock:
            ended = [(i, p) for i, p in self.processes.items() if p.poll() is not None]
            for run_id, _ in ended:
                del self.processes[run_id]
                self.kill_at.pop(run_id, None)
            late = [p for i, p in self.processes.items()
                    if self.kill_at.get(i, float("inf")) < time.monotonic()]
        for process in late:  # a second cancel did not end it: its whole session goes
            _kill_session(process)
        for run_id, process in ended:
            self.finalize(run_id, process.returncode)

    def _start_queued(self) -> None:
        while not self.stopping:
            with self.lock:
                if len(self.processes) >= self.slots:
                    return
            run = self.store.one("SELECT * FROM runs WHERE status = 'queued' AND owner IS ? "
                                 "ORDER BY id", self.store.owner)
            if run is None:
                return
            try:
                self._launch(run)
            except OSError as error:  # no process could be started: that run fails, once
                self.store.update_run(run["id"], status="failed", ended=time.time(),
                                      message=f"the run's process could not start: {error}")

    def _launch(self, run: dict) -> None:
        folder = self.store.run_folder(run["id"])
        folder.mkdir(parents=True, exist_ok=True)
        scene = self.store.one("SELECT sha256 FROM scenes WHERE id = ?", run["scene_id"])
        job = {"kind": run["kind"], "scene": str(self.store.blob_path(scene["sha256"])),
               "scene_sha256": scene["sha256"], "server_pid": os.getpid(),
               "signals": run["signals"]}
        if run["kind"] == "sweep":
            job.update(run["settings"])
        else:
            job["settings"] = run["settings"]
        (folder / "job.json").write_text(json.dumps(job))
        with open(folder / "worker.log", "ab") as log:
            process = subprocess.Popen(
                [sys.executable, "-m", "dsim.serve.worker", str(folder)], cwd=folder,
                stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                env=child_env(), start_new_session=True)  # Ctrl-C of the server is not theirs
        with self.lock:
            self.processes[run["id"]] = process
        with self.store.connect() as db:  # unless it was cancelled meanwhile
            started = db.execute("UPDATE runs SET status = 'running', pid = ?, started = ? "
                                 "WHERE id = ? AND status = 'queued' AND owner IS ?",
                                 (process.pid, time.time(), run["id"],
                                  self.store.owner)).rowcount
        if not started:
            _signal(process, signal.SIGKILL)

    # --- ends ------------------------------------------------------------------------------
    def cancel(self, run_id: int) -> bool:
        """Stop a run after its current step (SIGTERM); a queued run never starts.  A
        second cancel sends SIGTERM again, which ends the worker at once, also while an
        FMU hangs in its step, keeping its converged rows and statistics
        (master/running/interrupts.py); if it has not ended :data:`KILL_GRACE` seconds later,
        it is killed.  False when the run was not active."""
        run = self.store.run(run_id)
        if run is None or run["status"] not in ACTIVE:
            return False
        with self.lock:
            process = self.processes.get(run_id)
            if run["status"] == "queued" and process is None:
                self.store.update_run(run_id, status="interrupted", ended=time.time(),
                                      message="cancelled before it started")
                return True
        self.store.update_run(run_id, cancel_requested=run["cancel_requested"] + 1)
        if process is not None:
            if run["cancel_requested"]:
                with self.lock:
                    self.kill_at.setdefault(run_id, time.monotonic() + KILL_GRACE)
            _signal(process, signal.SIGTERM)
        self.wake.set()
        return True

    def finalize(self, run_id: int, returncode: int | None, server_died: bool = False) -> None:
        """Record how a job ended from what its worker left: ``outcome.json`` when it
        ended by itself, else the signal that killed it."""
        folder = self.store.run_folder(run_id)
        run = self.store.run(run_id)
        if run["status"] not in ACTIVE:  # cancelled before its process was running
            return
        if run["owner"] != self.store.owner:
            # another server's run: its CSV and status are that server's to write
            return
        salvage_csv(folder)
        outcome = _read_json(folder / "outcome.json")
        if outcome is None:
            steps, reached = _csv_reach(folder)
            outcome = {"steps": steps, "time": reached, "exit_code": returncode}
            if run["cancel_requested"] or server_died:
                reason = ("cancelled" if run["cancel_requested"] else
                          "the server stopped while it ran")
                outcome.update(status="interrupted", message=reason)
            else:
                how = (f"was killed by {signal.Signals(-returncode).name}"
                       if returncode is not None and returncode < 0
                       else f"exited with code {returncode}")
                tail = _log_tail(folder)
                outcome.update(status="failed", message=(
                    f"the run's process {how} (an FMU may have crashed it); every converged "
                    f"step is kept" + (f"; last words: {tail}" if tail else "")))
        statistics = _read_json(folder / ("results.stats.json" if run["kind"] == "run"
                                          else "sweep.json"))
        self.store.update_run(
            run_id, status=outcome["status"], message=outcome.get("message") or "",
            exit_code=outcome.get("exit_code"), steps=outcome.get("steps"),
            time_reached=outcome.get("time"), statistics=statistics,
            inputs=_read_json(folder / "inputs.json") or {}, ended=time.time(), pid=None)


def _kill_session(process: subprocess.Popen) -> None:
    """SIGKILL a worker and every process of its session (it was started in one of its
    own: the Ray instance of an isolated run is in it)."""
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except OSError:
        _signal(process, signal.SIGKILL)


def _signal(process: subprocess.Popen, number: int) -> None:
    try:
        process.send_signal(number)
    except ProcessLookupError:
        pass
