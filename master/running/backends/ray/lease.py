"""The worker side of a cluster's spare workers (pool.py): how long a spare waits
to be taken, who took it, and its end when that driver is gone.

A spare kept in a cluster outlives the command that started it (a detached Ray actor),
so nothing of Ray's ends it: it ends itself when no run has taken it within its
waiting time, and, once taken, when the Ray job of the driver that took it has ended
(a driver killed outright, whose run could not end its workers).  Only the standard
library here: the worker module's import is on the path of every worker's start.
"""
from __future__ import annotations

import os
import threading
import time as clock

#: seconds between two looks at whether the driver that took a spare is still there
OWNER_EVERY = 2.0


def job_alive(job: str) -> bool:
    """Whether the Ray job ``job`` (hex id) is still running, from the cluster's job
    table (Ray's own record of its drivers).  Raises when the table cannot be read."""
    from ray._private import state  # Ray's; a spare is taken only where it answers

    for entry in state.state.job_table():
        if entry.get("JobID") == job:
            return not entry.get("IsDead", False)
    return False


class Lease:
    """A spare worker's wait for a run: :meth:`take` once (the first caller wins), the
    process ends after ``seconds`` untaken, or once the taker's job has ended."""

    def __init__(self, seconds: float, alive=job_alive, end=os._exit):
        self._lock = threading.Lock()
        self._owner: str | None = None
        self._ended = False
        self._alive, self._end = alive, end
        self._seconds = float(seconds)
        self._turn = 0  # a new one each time it is taken or given back
        self._wait()

    def take(self, job: str) -> bool:
        """Whether the driver of Ray job ``job`` takes this worker now: only the first
        caller does, only before the wait has run out, and only where the job table
        can be read (else nothing would end the worker if that driver were killed)."""
        with self._lock:
            if self._ended or self._owner is not None:
                return False
            try:
                if not self._alive(job):
                    return False
            except Exception:  # no job table: an unwatched worker could outlive its run
                return False
            self._owner = job
            self._turn += 1
            turn = self._turn
        threading.Thread(target=self._watch, args=(job, turn), name="dsim-spare-owner",
                         daemon=True).start()
        return True

    def give_back(self, job: str) -> bool:
        """The driver of ``job`` lets go of this worker unused (its scene was refused):
        it waits again, as long as at first.  Whether ``job`` held it."""
        with self._lock:
            if self._owner != job or self._ended:
                return False
            self._owner = None
            self._turn += 1
        self._wait()
        return True

    def _wait(self) -> None:
        with self._lock:
            turn = self._turn
        threading.Thread(target=self._expire, args=(turn,), name="dsim-spare-wait",
                         daemon=True).start()

    def _expire(self, turn: int) -> None:
        clock.sleep(self._seconds)
        with self._lock:
            if self._owner is None and self._turn == turn:
                self._ended = True
                self._end(0)

    def _watch(self, job: str, turn: int) -> None:
        while True:
            clock.sleep(OWNER_EVERY)
            with self._lock:
                if self._turn != turn:  # given back
                    return
            try:
                gone = not self._alive(job)
            except Exception:  # the head restarting: Ray ends its workers if it is lost
                continue
            if gone:
                self._end(1)
                return
