"""One server per database, and who owns a run.

Two servers on one database would each take the other's live runs for leftovers
of a dead server (marking them interrupted, moving their temporary CSV into
place) and launch queued runs twice.  So:

* :func:`lock_database`: a server holds an exclusive ``flock`` on ``<db>.lock``
  (its pid written in it) for as long as it runs; a second one is refused with
  the first one's pid.  The kernel drops the lock when the process dies, however
  it dies, so a stale lock file never blocks the next server.
* :func:`server_identity` / :func:`owner_alive`: each run records the server
  that owns it (pid, the process's start time, a random part); only that server
  launches, cancels and finalises it, and a later server takes over only runs
  whose owner is provably dead (no such pid, or a pid reused by a process that
  started at another time).
"""
from __future__ import annotations

import fcntl
import os
import secrets
from pathlib import Path

from dsim import InputError, process_alive, process_start_time


def server_identity() -> str:
    """``pid:start-time:random`` of this server (the random part tells apart two
    applications in one process, as tests make)."""
    pid = os.getpid()
    return f"{pid}:{process_start_time(pid) or '-'}:{secrets.token_hex(4)}"


def owner_alive(owner: str | None) -> bool:
    """Whether the server that ``owner`` names may still be running.  A run without
    an owner was recorded before owners were (its server is gone: the lock shows
    no server holds the database)."""
    if not owner:
        return False
    try:
        pid_text, started, _ = owner.split(":", 2)
        pid = int(pid_text)
    except ValueError:
        return False
    return process_alive(pid, started)


class DatabaseLock:
    """The exclusive lock of one database, held until :meth:`release` (or the
    process ends)."""

    def __init__(self, db_path):
        db = Path(db_path).resolve()
        self.path = db.with_name(db.name + ".lock")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        # O_NOFOLLOW: a link planted under the lock's name is not followed
        try:
            self.fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o600)
        except OSError as error:
            raise InputError(f"--db {db}: cannot open its lock file {self.path} "
                             f"({error.strerror or error})") from None
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(self.fd, 64, 0).decode(errors="replace").strip() or "unknown"
            os.close(self.fd)
            raise InputError(f"--db {db}: another dsim serve (pid {holder}) uses this "
                             "database; one server per database") from None
        os.ftruncate(self.fd, 0)
        os.pwrite(self.fd, f"{os.getpid()}\n".encode(), 0)

    def release(self) -> None:
        if self.fd is not None:
            os.close(self.fd)  # closing the descriptor drops the flock
            self.fd = None


def lock_database(db_path) -> DatabaseLock:
    """Hold ``<db>.lock``; InputError (one line, the holder's pid) when another
    server holds it."""
    return DatabaseLock(db_path)
