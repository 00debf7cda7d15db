"""A memory cgroup of its own for a test: a process moved into it meets the kernel's
out-of-memory killer when its new allocations pass the limit, as a run on a machine
out of memory does (tests/tools/test_supervisor.py).

cgroup v2 (``memory.max``, ``memory.events``) or v1 (``memory.limit_in_bytes``,
``memory.oom_control``), whichever the machine mounts; a test that cannot make one (not
root, no memory controller, a read-only /sys/fs/cgroup) is skipped, and says why.
Pages a process had before it moved stay charged where they were, so the limit applies
to what it allocates afterwards only."""
from __future__ import annotations

import os
import re
import time
import uuid
from contextlib import contextmanager
from pathlib import Path

import pytest

V2 = Path("/sys/fs/cgroup")
V1 = Path("/sys/fs/cgroup/memory")


class MemoryCgroup:
    """A memory cgroup made for one test: :meth:`add` moves a process into it,
    :meth:`oom_kills` counts the processes the out-of-memory killer ended in it."""

    def __init__(self, folder: Path, version: int):
        self.folder, self.version = folder, version

    def add(self, pid: int) -> None:
        (self.folder / "cgroup.procs").write_text(str(pid))

    def oom_kills(self) -> int:
        name = "memory.events" if self.version == 2 else "memory.oom_control"
        found = re.search(r"^oom_kill (\d+)$", (self.folder / name).read_text(), re.M)
        return int(found.group(1)) if found else 0


def _make(limit: int) -> MemoryCgroup:
    """A new cgroup limited to ``limit`` bytes (no swap: what passes it is killed)."""
    name = f"dsim-test-{uuid.uuid4().hex[:12]}"
    if "memory" in (V2 / "cgroup.controllers").read_text().split() \
            if (V2 / "cgroup.controllers").exists() else False:
        folder = V2 / name
        folder.mkdir()
        (folder / "memory.max").write_text(str(limit))
        if (folder / "memory.swap.max").exists():
            (folder / "memory.swap.max").write_text("0")
        return MemoryCgroup(folder, 2)
    folder = V1 / name
    folder.mkdir()
    (folder / "memory.limit_in_bytes").write_text(str(limit))
    (folder / "memory.swappiness").write_text("0")
    return MemoryCgroup(folder, 1)


@contextmanager
def memory_limit(limit: int):
    """A :class:`MemoryCgroup` of ``limit`` bytes for the ``with`` block, removed after
    (once the processes in it have ended)."""
    try:
        cgroup = _make(limit)
    except OSError as error:
        pytest.skip(f"no memory cgroup can be made here ({error}): the out-of-memory "
                    "killer cannot be met on purpose")
    try:
        yield cgroup
    finally:
        deadline = time.monotonic() + 10
        while True:
            try:
                os.rmdir(cgroup.folder)
                break
            except OSError:  # a process of it not reaped yet
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.05)
