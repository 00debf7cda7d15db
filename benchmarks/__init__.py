"""dsim's benchmarks: each module measures one thing and writes the page of docs/ that
quotes it (``python -m benchmarks.NAME``)."""
from __future__ import annotations

import platform
import time
from pathlib import Path


def machine(cpuinfo: Path = Path("/proc/cpuinfo")) -> str:
    """The processor a page was measured on, named as its reader compares pages: the
    model Linux reports (``AMD EPYC``, ``Intel(R) Xeon(R) ...``) and the architecture;
    the architecture alone where no model is known.  The same page measured on another
    kind of CPU can give other ratios (Python's overhead and the solvers' arithmetic do
    not scale alike), so every page says which one it saw."""
    try:
        for line in cpuinfo.read_text(errors="replace").splitlines():
            key, _, value = line.partition(":")
            if key.strip() == "model name" and value.strip():
                return f"{' '.join(value.split())}, {platform.machine()}"
    except OSError:  # not Linux, or no /proc: what the platform module knows
        pass
    return platform.machine()


def cpu_seconds(function):
    """``function()``'s CPU seconds in this process (a shared machine makes wall time
    mostly waiting) and its value."""
    start = time.process_time()
    value = function()
    return time.process_time() - start, value
