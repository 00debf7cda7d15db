"""How a run answers SIGINT and SIGTERM, also while an FMU is stuck in native code.

The first signal asks the run to stop after the current step
(:meth:`~dsim.master.running.execution.Execution.stop`): the step ends, the subsystems are
released, every file is finished, and the command exits with 128 + the signal.  A step
that has not finished :data:`GRACE` seconds later (a hung FMU, a frozen worker), or a
set-up (a first signal stops the run at its start), is not waited for: the run ends as
on a second signal.

A second signal ends the process at once.  A Python signal handler runs only in the
main thread, between two bytecodes: while the main thread is inside an FMU's
``fmi2DoStep`` (native code), or in ``ray.get`` waiting for a worker whose FMU is
stuck, no handler runs, ever.  So :class:`SignalWatch` installs its handlers with a
wakeup file descriptor (``signal.set_wakeup_fd``): the interpreter's C-level handler
writes the signal's number into a pipe the moment the signal arrives, whatever the
main thread is doing, and a watchdog thread reading that pipe acts on it.  The FMU
call has released the interpreter lock (ctypes does, and so does ``ray.get``), so
the watchdog runs.

On the second signal the watchdog, without touching the FMUs and without any lock
the stuck main thread may hold:

1. arms a deadline: whatever else hangs, the process ends :data:`DEADLINE` seconds
   later;
2. makes the run's result as far as it got
   (:meth:`~dsim.master.running.execution.Execution.abandon`: converged steps, status
   ``interrupted``; no FMU is called, no worker asked);
3. lets every observer write what it can (:meth:`~dsim.master.recording.observers.Observer.abandoned`:
   the CSV's last rows written and the file renamed, the statistics JSON);
4. stops what the run started elsewhere (the backend's workers) and kills every
   process this one started (a local Ray instance: its GCS, raylet, agents and
   workers), so that no process of the run outlives it;
5. says so on stderr and ends the process with ``os._exit(128 + signal)``.
"""
from __future__ import annotations

import os
import signal
import sys
import threading
import time

from dsim.master.processes import process_alive
from dsim.master.recording.results import RunResult
from dsim.master.running.backends import log_lines

#: seconds after a second signal by which the process has ended, whatever hangs
DEADLINE = 3.0
#: seconds the step under way has after the first signal: a step that has not finished
#: by then (an FMU or a worker that hangs, a frozen worker) ends the run as a second
#: signal would, with every converged row
GRACE = 5.0
#: the signals a run answers
SIGNALS = (signal.SIGINT, signal.SIGTERM)
#: what the watch writes into its own pipe to stop its thread (no signal has number 0)
_STOP = b"\0"


class SignalWatch:
    """SIGINT and SIGTERM for one run of ``execution``, while in a ``with`` block
    (main thread only: see the module docstring)."""

    def __init__(self, execution):
        self.execution = execution
        self.count = 0
        self._previous: dict[int, object] = {}
        self._previous_fd = -1
        self._pipe: tuple[int, int] | None = None
        self._thread: threading.Thread | None = None

    def __enter__(self) -> "SignalWatch":
        read, write = os.pipe()
        os.set_blocking(write, False)  # the C-level handler must never block
        self._pipe = (read, write)
        self._thread = threading.Thread(target=self._watch, name="dsim-signals", daemon=True)
        self._thread.start()
        # the pipe first, the handlers after (and the other way round at the end): no
        # signal may reach the handler below without reaching the pipe
        self._previous_fd = signal.set_wakeup_fd(write, warn_on_full_buffer=False)
        for number in SIGNALS:
            # the handler itself does nothing: the watchdog acts, also while the main
            # thread cannot run a handler (it is a Python handler, not SIG_IGN, so that
            # the interpreter's C-level handler catches the signal and writes the pipe)
            self._previous[number] = signal.signal(number, _nothing)
        return self

    def __exit__(self, *exc) -> None:
        for number, handler in self._previous.items():
            signal.signal(number, handler)
        signal.set_wakeup_fd(self._previous_fd)
        read, write = self._pipe
        os.set_blocking(write, True)
        os.write(write, _STOP)
        self._thread.join()
        os.close(read)
        os.close(write)

    def _watch(self) -> None:
        read = self._pipe[0]
        while True:
            for number in os.read(read, 64):
                if number == 0:
                    return
                if number not in SIGNALS:
                    continue  # another signal with a Python handler: not ours
                self.count += 1
                name = signal.Signals(number).name
                if self.count == 1:
                    self.execution.stop(f"interrupted by {name}", number)
                    grace = threading.Timer(GRACE, self._graced,
                                            (self.execution.index, number))
                    grace.daemon = True
                    grace.start()
                else:
                    end_at_once(self.execution, number)


    def _graced(self, index: int, number: int) -> None:
        """The grace after the first signal is over: a run still in the step it was in,
        or still setting up (instantiating thousands of FMUs, or an FMU stuck in its
        initialization), ends at once (see :data:`GRACE`)."""
        execution = self.execution
        setting_up = execution.status == "created"
        if self.count == 1 and (setting_up or (execution.status == "running"
                                               and execution.index == index)):
            what = "the set-up" if setting_up else "the step under way"
            execution.stop(f"interrupted by {signal.Signals(number).name}; {what} did not "
                           f"finish within {GRACE:g} s", number)
            end_at_once(execution, number)


def _nothing(number, frame) -> None:
    """The Python-level handler of SIGINT and SIGTERM during a run (see SignalWatch)."""


def end_at_once(execution, number: int) -> None:
    """End the process now, keeping what can be kept (see the module docstring)."""
    code = 128 + number
    deadline = threading.Timer(DEADLINE, _last_resort, (code,))
    deadline.daemon = True
    deadline.start()
    try:
        result = execution.abandon(number)
    except Exception as error:  # the rows matter more than complete statistics
        result = _bare_result(execution, number, error)
    _abandon_observers(execution, result)
    try:
        if execution.backend is not None:
            execution.backend.abandon()
    except Exception:  # its processes are killed below (those on this machine)
        pass
    kill_descendants()
    where = result.files.get("csv")
    _say(f"dsim: interrupted: {result.message}"
         + (f"; the {result.steps} converged steps are in {where}" if where else ""))
    os._exit(code)


def _abandon_observers(execution, result) -> None:
    """Let every observer keep what it can of an abandoned run (rows, statistics) and
    note the files each wrote in ``result``."""
    for observer in execution.observers:
        try:
            observer.abandoned(result)
        except Exception as error:  # one observer must not stop the others
            _say(f"dsim: {type(observer).__name__}: {error}")
        result.files.update(getattr(observer, "files", {}))


def end_lost(execution, what: str) -> None:
    """End the process now as a failed run (exit 1), keeping what can be kept, when
    ``what`` is lost and the run cannot go on (the Ray head: no call to a worker
    would ever come back), from the watchdog's thread."""
    deadline = threading.Timer(DEADLINE, _last_resort, (1,))
    deadline.daemon = True
    deadline.start()
    try:
        result = execution.abandon(None, lost=what)
    except Exception as error:  # the rows matter more than complete statistics
        result = _bare_result(execution, signal.SIGTERM, error)
        result.status = result.statistics["status"] = "failed"
    _abandon_observers(execution, result)
    kill_descendants()
    where, stats = result.files.get("csv"), result.files.get("statistics")
    _say(f"dsim: simulation failed: {result.message}")
    if where:
        _say(f"dsim: the {result.steps} converged steps are in {where}, statistics in "
             f"{stats or 'nowhere'}")
    for line in log_lines():
        _say(line)
    os._exit(1)


def _last_resort(code: int) -> None:
    """The deadline: something below hung (an observer, Ray); end anyway."""
    kill_descendants()
    os._exit(code)


def _bare_result(execution, number: int, error: Exception):
    """The result of an abandoned run whose statistics could not be made: how it ended
    and how far it got."""
    message = (f"interrupted, then ended at once by {signal.Signals(number).name} (stopped "
               f"at t = {execution.time:g} s, step {execution.index}); the statistics could "
               f"not be made: {type(error).__name__}: {error}")
    result = RunResult("interrupted", message, execution.time, execution.index, signal=number)
    result.statistics = {"status": "interrupted", "message": message,
                         "time_reached": execution.time, "steps": execution.index,
                         "planned_steps": execution.planned_steps}
    return result


def _say(line: str) -> None:
    """One line on stderr, written to the descriptor: the stream's lock may be held by
    the main thread."""
    try:
        os.write(sys.stderr.fileno(), (line + "\n").encode(errors="replace"))
    except (OSError, ValueError):
        pass


def descendants(root: int) -> set[int]:
    """The processes descended from ``root`` (children, their children...), from /proc
    (empty where there is none)."""
    children: dict[int, list[int]] = {}
    try:
        entries = os.listdir("/proc")
    except OSError:
        return set()
    for entry in entries:
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat", "rb") as stat:
                data = stat.read()
        except OSError:  # it has just ended
            continue
        parent = int(data[data.rindex(b")") + 2:].split()[1])  # after "pid (name) state"
        children.setdefault(parent, []).append(int(entry))
    found, todo = set(), [root]
    while todo:
        for child in children.get(todo.pop(), ()):
            if child not in found:
                found.add(child)
                todo.append(child)
    return found


def kill_descendants() -> None:
    """Kill every process this one started, and theirs.  They are stopped first, tree
    by tree, until no new one appears: a stopped process starts no other, and stays
    its parent's child (a killed one's children would move to init, out of sight)."""
    stopped: set[int] = set()
    for _ in range(20):
        new = descendants(os.getpid()) - stopped
        if not new:
            break
        for pid in new:
            _send(pid, signal.SIGSTOP)
        stopped |= new
    for pid in stopped:
        _send(pid, signal.SIGKILL)
    # a kill is done when the process has exited (a large one takes a moment to free
    # its memory): wait for that, briefly, so that none of them outlives this process
    deadline = time.monotonic() + 1.0
    while stopped and time.monotonic() < deadline:
        stopped = {pid for pid in stopped if process_alive(pid, zombies=False)}
        time.sleep(0.01)


def _send(pid: int, number: int) -> None:
    try:
        os.kill(pid, number)
    except OSError:  # ended meanwhile
        pass
