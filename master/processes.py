"""Whether a process still runs: the one answer for the run folders of the unpacker
(a killed run's folder may be removed), the signal handling (a worker killed is done
when it has exited) and dsim serve (a run whose server is gone is salvaged).

On Linux /proc says it, with the process's state (a zombie has ended: only its exit
status is left) and its start time (a pid the system gave again to a later process
is not the same process); elsewhere signal 0 says whether the pid exists."""
from __future__ import annotations

import os
from pathlib import Path

_PROC = Path("/proc")


def _stat_fields(pid: int) -> list[str] | None:
    """The fields of /proc/PID/stat after the command name, or None (no such entry)."""
    try:
        data = (_PROC / str(pid) / "stat").read_bytes().decode("ascii", "replace")
    except OSError:
        return None
    # the command name (field 2) is in parentheses and may hold spaces
    return data.rsplit(")", 1)[1].split()


def process_start_time(pid: int) -> str | None:
    """The process's start time (clock ticks since boot, as /proc gives it), or None
    where there is no such process or no /proc."""
    fields = _stat_fields(pid)
    return fields[19] if fields is not None else None


def process_alive(pid: int, started: str | None = None, zombies: bool = True) -> bool:
    """Whether process ``pid`` still runs.  ``started``: the start time
    :func:`process_start_time` gave for it (``"-"``: none was known): only that process counts,
    not a later one the pid was given to again (and, without /proc, an identity that
    cannot be checked counts as gone).  ``zombies``: whether a process that has ended
    but whose exit status nobody collected yet counts as running."""
    fields = _stat_fields(pid)
    if fields is not None:
        if not zombies and fields[0] in ("Z", "X"):
            return False
        return started in (None, "-") or started == fields[19]
    if _PROC.is_dir():
        return False  # /proc lists every process: this one has gone
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return started in (None, "-")
    return started in (None, "-")
