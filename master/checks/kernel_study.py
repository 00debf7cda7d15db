"""The kernel study: how far a scene's results move when only the BLAS kernels change.

numpy's and scipy's OpenBLAS choose their kernels by CPU when they load, so the
last bits of every factorization differ between machines (and numpy releases).
``OPENBLAS_CORETYPE=<name>`` in the environment forces a kernel; this module runs
one case in a subprocess per kernel the CPU can execute (``python -m dsim.master.tools.cli
run``: the same code path as a user's run, nothing new to trust) and measures,
per column, the largest difference seen between any two kernels.  That spread is
the round-off a regression band must not hang on (:mod:`dsim.master.checks.compare` uses it
as a floor; ``dsim regress --update`` stores it in the baseline's JSON).
"""
from __future__ import annotations

import ctypes
import json
import os
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np
import scipy

from dsim.master.errors import InputError
from dsim.master.recording.results import read_columns
from dsim.master.settings import SETTINGS

#: The x86-64 kernels a study may force, oldest first, with the CPU flags each one's
#: instructions need (/proc/cpuinfo names).  A kernel the CPU lacks would end the
#: subprocess with SIGILL, so it is never forced.  SkylakeX needs more of AVX-512
#: than the foundation (Knights Landing has avx512f alone and gets Haswell kernels).
#: /proc/cpuinfo calls SSE3 "pni".
KERNELS = {
    "Prescott": ("pni",),
    "Nehalem": ("pni", "ssse3", "sse4_1", "sse4_2"),
    "Sandybridge": ("avx",),
    "Haswell": ("avx2", "fma"),
    "Zen": ("avx2", "fma"),
    "SkylakeX": ("avx512f", "avx512bw", "avx512dq", "avx512vl", "avx512cd"),
}

#: The ways OpenBLAS builds name a function (plain, and the prefixed and suffixed
#: names of the scipy-openblas wheels numpy and scipy bundle).
_NAMINGS = ("openblas_{}", "openblas_{}64_", "scipy_openblas_{}", "scipy_openblas_{}64_")


def cpu_flags() -> set[str]:
    """The CPU's feature flags (empty where /proc/cpuinfo does not say)."""
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return set()
    for line in text.splitlines():
        if line.startswith("flags"):
            return set(line.partition(":")[2].split())
    return set()


def supported_kernels(flags=None) -> list[str]:
    """The kernels of :data:`KERNELS` this CPU can execute."""
    flags = cpu_flags() if flags is None else flags
    return [name for name, needs in KERNELS.items() if all(f in flags for f in needs)]


def _ask_openblas(function: str) -> dict[str, str]:
    """``openblas_<function>()`` (a string) of every OpenBLAS library this process has
    loaded for numpy and scipy, by file name; empty when their BLAS is not OpenBLAS."""
    import numpy.linalg  # noqa: F401  (loads numpy's BLAS)
    import scipy.linalg  # noqa: F401  (and scipy's, a separate copy in the wheels)

    try:
        with open("/proc/self/maps") as maps:
            paths = sorted({line.split()[-1] for line in maps
                            if "openblas" in line.rsplit("/", 1)[-1].lower()})
    except OSError:
        return {}
    answers = {}
    for path in paths:
        try:
            library = ctypes.CDLL(path)
        except OSError:
            continue
        for symbol in (naming.format(function) for naming in _NAMINGS):
            if hasattr(library, symbol):
                call = getattr(library, symbol)
                call.restype = ctypes.c_char_p
                answers[Path(path).name] = call().decode().strip()
                break
    return answers


def openblas_cores() -> dict[str, str]:
    """The kernel set (corename) each loaded OpenBLAS runs, by library file name."""
    return _ask_openblas("get_corename")


def blas_name() -> str:
    """numpy's BLAS as its build configuration names it."""
    try:
        return str(np.show_config(mode="dicts")["Build Dependencies"]["blas"]["name"])
    except Exception:  # older numpy: no dict mode; the study says "unknown"
        return "unknown"


_PROBE = ("import json; from dsim.master.checks.kernel_study import openblas_cores; "
          "print(json.dumps(openblas_cores()))")


def kernel_environment(kernel: str | None) -> dict:
    """This process's environment for a subprocess under ``kernel`` (None: the CPU's
    default).  The subprocess runs this interpreter, so it imports the dsim installed
    here (a wheel, or the checkout's editable install)."""
    env = dict(os.environ)
    env.pop("OPENBLAS_CORETYPE", None)
    if kernel:
        env["OPENBLAS_CORETYPE"] = kernel
    return env


@lru_cache(maxsize=None)  # one probe per kernel and process: the library does not change
def forced_core(kernel: str) -> str:
    """The corename OpenBLAS reports when ``kernel`` is forced (builds alias some
    kernels to others: Prescott reports Katmai, and Zen may be Haswell's)."""
    done = subprocess.run([sys.executable, "-c", _PROBE], env=kernel_environment(kernel),
                          capture_output=True, text=True, timeout=60)
    cores = set(json.loads(done.stdout or "{}").values()) if done.returncode == 0 else set()
    return "/".join(sorted(cores)) or "?"


def command_line(scene, settings: dict, out, allow_outside=()) -> list[str]:
    """``python -m dsim.master.tools.cli run SCENE --out OUT`` with the case's settings as
    options (values exactly as given: a float's repr round-trips) and an
    ``--allow-outside`` per folder of ``allow_outside``."""
    unknown = [k for k in settings if k not in SETTINGS]
    if unknown:
        raise InputError(f"settings {', '.join(unknown)} are not settings of dsim run "
                         f"(settings: {', '.join(SETTINGS)})")
    options = []
    for keyword, value in settings.items():
        if value is not None:
            options += [SETTINGS[keyword].option, repr(value) if isinstance(value, float)
                        else str(value)]
    for folder in allow_outside:
        options += ["--allow-outside", str(Path(folder).resolve())]
    return [sys.executable, "-m", "dsim.master.tools.cli", "run", str(Path(scene).resolve()),
            "--out", str(out), "--quiet"] + options


@dataclass
class KernelRun:
    """One run of the case under a forced kernel: its CSV, or why there is none."""

    kernel: str
    core: str
    csv: Path | None
    seconds: float
    problem: str = ""


def run_with_kernel(scene, settings: dict, kernel: str, out: Path,
                    timeout: float = 600.0, allow_outside=()) -> KernelRun:
    """Run the case in a subprocess with ``OPENBLAS_CORETYPE=kernel`` (``allow_outside``:
    the folders it may name files in besides its own)."""
    core = forced_core(kernel)
    start = time.perf_counter()
    try:
        done = subprocess.run(command_line(scene, settings, out, allow_outside),
                              env=kernel_environment(kernel),
                              capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return KernelRun(kernel, core, None, time.perf_counter() - start,
                         f"no result within {timeout:g} s")
    seconds = time.perf_counter() - start
    if done.returncode != 0:
        lines = (done.stderr or done.stdout).strip().splitlines() or ["no message"]
        return KernelRun(kernel, core, None, seconds,
                         f"exit {done.returncode}: {lines[-1]}")
    return KernelRun(kernel, core, Path(out), seconds)


def spread(csv_files) -> dict[str, float]:
    """Per numeric column of the first CSV, the largest difference between any two of
    the files at any time (the others interpolated onto the first's times where
    their grids differ; a column missing from one is skipped for it)."""
    runs = [read_columns(path) for path in csv_files]
    times = runs[0]["time"]
    noise = {}
    for name, values in list(runs[0].items())[1:]:
        if values.dtype == object:
            continue  # a String column: equal or not, there is no round-off
        low, high = values.copy(), values.copy()
        for other in runs[1:]:
            if name not in other or other[name].dtype == object:
                continue
            theirs = other[name]
            if len(other["time"]) != len(times) or not np.array_equal(other["time"], times):
                theirs = np.interp(times, other["time"], theirs)
            low, high = np.fmin(low, theirs), np.fmax(high, theirs)
        noise[name] = float(np.max(high - low)) if len(times) else 0.0
    return noise


@dataclass
class Study:
    """What a kernel study measured: per column the largest difference between
    kernels (``noise``), which kernels ran (``kernels``: requested name -> the
    corename OpenBLAS reported), those not run because this build aliases them to a
    kernel that ran (``same``), the ones that failed, and the versions used.
    ``skipped`` says why there was no study (then nothing was measured)."""

    noise: dict[str, float] = field(default_factory=dict)
    kernels: dict[str, str] = field(default_factory=dict)
    failed: dict[str, str] = field(default_factory=dict)
    same: dict[str, str] = field(default_factory=dict)
    versions: dict[str, str] = field(default_factory=dict)
    seconds: float = 0.0
    skipped: str = ""
    runs: list = field(default_factory=list)

    def record(self) -> dict:
        """The study as stored in a baseline's JSON (``"study"``)."""
        record = {"kernels": self.kernels, **self.versions}
        if self.same:
            record["same code as"] = self.same
        if self.failed:
            record["failed"] = self.failed
        return record


def _versions() -> dict[str, str]:
    configs = sorted(set(_ask_openblas("get_config").values()))
    return {"numpy": np.__version__, "scipy": scipy.__version__, "blas": blas_name(),
            "openblas": "; ".join(configs)}


def choose_kernels(requested=None, flags=None) -> list[str]:
    """The kernels to force: ``requested`` (checked: known, and executable here) or
    every one this CPU supports; InputError naming the problem."""
    flags = cpu_flags() if flags is None else flags
    if requested is None:
        return supported_kernels(flags)
    unknown = [k for k in requested if k not in KERNELS]
    if unknown:
        raise InputError(f"kernels {', '.join(unknown)}: not OpenBLAS kernels dsim can force "
                         f"(kernels: {', '.join(KERNELS)})")
    lacking = [f"{k} needs {', '.join(f for f in KERNELS[k] if f not in flags)}"
               for k in requested if not all(f in flags for f in KERNELS[k])]
    if lacking:
        raise InputError(f"this CPU cannot run every kernel asked for: {'; '.join(lacking)} "
                         f"(it can run: {', '.join(supported_kernels(flags)) or 'none'})")
    return list(dict.fromkeys(requested))


def study(scene, settings: dict, baseline_csv, kernels=None, jobs: int | None = None,
          timeout: float = 600.0, keep=None, allow_outside=()) -> Study:
    """Run the case under each kernel (default: every one the CPU supports, less those
    that are the same code as the kernel this process runs) and measure the spread
    of every column among those runs and ``baseline_csv`` (the run with the default
    kernel).  ``keep``: a folder for the kernels' CSVs (default: a temporary one);
    ``allow_outside``: the folders the scene may name files in besides its own."""
    start = time.perf_counter()
    cores = openblas_cores()
    if not cores:
        return Study(skipped=f"numpy's BLAS is {blas_name()}, not OpenBLAS: its kernels "
                             "cannot be forced, so no study")
    names = choose_kernels(kernels)
    result = Study(versions=_versions())
    default = set(cores.values())
    result.kernels["default"] = "/".join(sorted(default))
    with tempfile.TemporaryDirectory(prefix="dsim-kernels-") as temp:
        folder = Path(keep) if keep else Path(temp)
        folder.mkdir(parents=True, exist_ok=True)
        stem = Path(baseline_csv).stem
        # kernels that are aliases of one another in this build run the same code:
        # one run per distinct corename (the default's is the baseline itself)
        seen, chosen = set(default), []
        for name in names:
            core = forced_core(name)
            if core in seen:
                result.same[name] = core
                continue
            seen.add(core)
            chosen.append(name)
        workers = max(1, min(len(chosen), jobs or os.cpu_count() or 1))
        with ThreadPoolExecutor(workers) as pool:
            runs = list(pool.map(lambda name: run_with_kernel(
                scene, settings, name, folder / f"{stem}.{name}.csv", timeout,
                allow_outside), chosen))
        result.runs = runs
        for run in runs:
            if run.csv is None:
                result.failed[run.kernel] = run.problem
            else:
                result.kernels[run.kernel] = run.core
        result.noise = spread([baseline_csv] + [r.csv for r in runs if r.csv is not None])
    result.seconds = time.perf_counter() - start
    return result
