"""Causal systems: dsim's per-step time against fmpy's own SSP runner and libcosim on
the same .ssp.

A ring of n first-order lag blocks (tests/support/third_party/block.c, compiled here with
gcc into a real FMI 2.0 co-simulation FMU) connected causally, b1.y -> b2.u ->
... -> bn.y -> b1.u, no joints (n = 4: the four-FMU causal scene).  Every master runs
the same archive: ``fmpy.ssp.simulation.simulate_ssp``, ``dsim.simulate`` (with its
CSV and statistics written, as ``dsim run`` does, and with the signals kept in
memory as fmpy does) and, where libcosimpy is installed, libcosim (C++, the Open
Simulation Platform's library) with its CSV file observer and with none.

Per-step time is the slope between a short and a long run of the same master
(start-up cancels), in CPU seconds of the process (a shared machine makes wall time
mostly waiting); the runs of the masters are interleaved and repeated, and the table
reports the median of the repetitions and the ratio to fmpy of each repetition (a
ratio of runs made side by side).  dsim and fmpy must agree: fmpy's row k holds the
values after step k + 1, dsim's row k + 1 the same; the largest difference is
reported.  A profile of dsim's steps (the long run less the short one) says where its
time goes.

    pip install -e '.[bench]'                # libcosimpy, for the libcosim columns
    python -m benchmarks.causal_benchmark   # writes docs/causal_benchmark.md
"""
from __future__ import annotations

import argparse
import cProfile
import platform
import pstats
import statistics as stats
import tempfile
import threading
import time
from datetime import date
from pathlib import Path

import numpy as np
from fmpy.ssp.simulation import simulate_ssp

from benchmarks import machine
import dsim
from dsim.master.recording.observers import CsvRecorder, StepRecord
from dsim.master.recording.observers.csv_recorder import csv_block
from tests.support.third_party.build import c_fmu, causal_ring_ssp

ROOT = Path(__file__).resolve().parent.parent
STEP = 1e-3


def _seconds(function) -> float:
    """CPU seconds of this process (every thread) that ``function`` takes: on a machine
    shared with other work, wall time is mostly waiting for a core."""
    start = time.process_time()
    function()
    return time.process_time() - start


def measure(ssp: Path, folder: Path, short: float, long: float, repetitions: int) -> dict:
    """Per-step microseconds of each master (from the least time of the short and of
    the long run over the repetitions) and the dsim / fmpy ratio of each repetition."""
    runners = {
        "fmpy": lambda stop: simulate_ssp(str(ssp), stop_time=stop, step_size=STEP),
        "dsim (CSV + statistics)": lambda stop: dsim.simulate(
            ssp, out=folder / "run.csv", stop=stop, handle_signals=False, force=True),
        "dsim (in memory)": lambda stop: dsim.simulate(ssp, stop=stop, handle_signals=False),
    }
    if libcosim_available():
        runners["libcosim (CSV files)"] = lambda stop: libcosim(ssp, stop, folder / "cosim")
        runners["libcosim (last values)"] = lambda stop: libcosim(ssp, stop)
    steps = round((long - short) / STEP)
    for run in runners.values():  # what a first run does once (imports, caches)
        run(short)
    seconds = {name: {short: [], long: []} for name in runners}
    slopes = {name: [] for name in runners}
    for _ in range(repetitions):
        for name, run in runners.items():
            for stop in (short, long):
                seconds[name][stop].append(_seconds(lambda: run(stop)))
            slopes[name].append((seconds[name][long][-1] - seconds[name][short][-1]) / steps)
    # the least time of each run length is the one least disturbed by other work
    return {name: {"us": (min(seconds[name][long]) - min(seconds[name][short])) / steps * 1e6,
                   "ratios": [a / b for a, b in zip(slopes[name], slopes["fmpy"])],
                   "slopes": slopes[name]} for name in runners}


def libcosim_available() -> bool:
    """Whether libcosim's Python binding (libcosimpy, from PyPI) is installed."""
    try:
        from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    except ImportError:
        return False
    log_output_level(CosimLogLevel.ERROR)  # it logs every call at debug level otherwise
    return True


def libcosim(ssp: Path, stop: float, folder: Path | None = None) -> None:
    """One libcosim run of ``ssp`` to ``stop`` (s) with its fixed-step algorithm:
    every variable of every FMU written to CSV files in ``folder`` (its file observer,
    6 significant digits), or only the last values kept (``folder`` None).  libcosimpy
    is imported here: an optional library the benchmark runs without."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver

    execution = CosimExecution.from_ssp_file(str(ssp), step_size=round(STEP * 1e9))
    if folder is not None:
        folder.mkdir(exist_ok=True)
        observer = CosimObserver.create_to_dir(str(folder))
    else:
        observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    execution.simulate_until(round(stop * 1e9))
    del execution, observer  # files closed, instances freed, now


def _profiled(ssp: Path, folder: Path, stop: float) -> tuple[dict, dict]:
    """cProfile's entries of one dsim run (CSV + statistics) to ``stop``, and its
    statistics."""
    profiler = cProfile.Profile(time.process_time)
    profiler.enable()
    result = dsim.simulate(ssp, out=folder / "profiled.csv", stop=stop, handle_signals=False,
                           force=True)
    profiler.disable()
    return pstats.Stats(profiler).stats, result.statistics


def profile(ssp: Path, folder: Path, short: float, long: float, shown: int = 12) -> list[str]:
    """Where a dsim run (CSV + statistics) spends its time per step: the functions of
    most own time under cProfile, the difference of a long and a short run over the
    steps between them (start-up cancels, as in the timing), in microseconds per step
    (cProfile's own cost included: the sum is above the plain run's; CPU time of the
    main thread, the only one cProfile follows), as table lines."""
    before, _ = _profiled(ssp, folder, short)
    after, _ = _profiled(ssp, folder, long)
    plain = [dsim.simulate(ssp, out=folder / "plain.csv", stop=stop, handle_signals=False,
                           force=True).statistics for stop in (short, long)]
    steps = round((long - short) / STEP)
    # (file, line, function) -> (calls, own seconds) of the steps between the two runs
    each = {key: (entry[1] - before.get(key, (0, 0, 0.0))[1],
                  entry[2] - before.get(key, (0, 0, 0.0))[2]) for key, entry in after.items()}
    # what the set-up calls as often in both runs only differs by the machine's noise
    each = {key: found for key, found in each.items() if found[0] > 0}
    total = sum(seconds for _, seconds in each.values())
    lines = ["| function | calls per step | own us per step | share |", "|---|---|---|---|"]
    for (file, line, name), (calls, seconds) in sorted(each.items(),
                                                        key=lambda e: -e[1][1])[:shown]:
        where = f"{Path(file).name}:{line} {name}" if line else name
        lines.append(f"| `{where}` | {calls / steps:.1f} | {seconds / steps * 1e6:.2f} | "
                     f"{seconds / total:.0%} |")
    inside = (plain[1]["seconds_in_fmus"] - plain[0]["seconds_in_fmus"]) / steps
    wall = (plain[1]["wall_seconds"] - plain[0]["wall_seconds"]) / steps
    lines += ["", f"Total under the profiler: {total / steps * 1e6:.1f} us per step. Without "
              f"it (the same two runs, wall time), {inside / wall:.0%} of a step is inside "
              "the FMUs' functions (statistics `seconds_in_fmus`: from entering to leaving "
              "each FMI call, the ctypes crossing included), the rest in the master."]
    return lines


def _loop(kernel, steps: int, clock: str) -> float:
    """CPU seconds of ``steps`` macro steps of ``kernel``'s FMUs called the kernel's way
    (its argument objects, statuses checked) with nothing else: no gather, no copy, no
    record; ``clock``: "none", "pair" (one clock reading before and one after each
    FMU's three calls, their seconds added together) or "calls" (a reading between
    calls, each function's seconds its own: what the kernel does)."""
    entries = [entry[:6] for entry in kernel.entries]
    now = time.perf_counter
    seconds = {"": 0.0}
    start = time.process_time()
    for n in range(steps):
        kernel._time.value = 10.0 + n * STEP  # after the run's stop time: no clash
        for put, put_args, step, step_args, get, get_args in entries:
            if clock == "none":
                if put.function(*put_args) > 1 or step.function(*step_args) > 1 \
                        or get.function(*get_args) > 1:
                    raise RuntimeError("an FMI call failed")
            elif clock == "pair":
                begin = now()
                if put.function(*put_args) > 1 or step.function(*step_args) > 1 \
                        or get.function(*get_args) > 1:
                    raise RuntimeError("an FMI call failed")
                seconds[""] += now() - begin
            else:
                begin = now()
                status = put.function(*put_args)
                end = now()
                put.seconds += end - begin
                if status > 1:
                    raise RuntimeError("fmi2SetReal failed")
                status = step.function(*step_args)
                begin = now()
                step.seconds += begin - end
                if status > 1:
                    raise RuntimeError("fmi2DoStep failed")
                status = get.function(*get_args)
                get.seconds += now() - begin
                if status > 1:
                    raise RuntimeError("fmi2GetReal failed")
    return time.process_time() - start


def kernel_floor(ssp: Path, steps: int, repetitions: int) -> dict:
    """Microseconds per macro step of the FMUs' calls alone, as dsim's causal kernel
    makes them (:func:`_loop`), least of ``repetitions``: what a master in Python
    cannot go below with these FMUs and ctypes, with the clock readings of two ways of
    timing the calls."""
    execution = dsim.Execution(dsim.prepare(ssp), keep_signals=False)
    execution.start()
    try:
        kernel = execution.coupling.kernel
        if kernel is None or any(entry[-1] is not None or entry[0] is None
                                 or entry[4] is None for entry in kernel.entries):
            return {}
        return {clock: min(_loop(kernel, steps, clock) for _ in range(repetitions))
                / steps * 1e6 for clock in ("none", "pair", "calls")}
    finally:
        execution.finish()


def flush_threads(ssp: Path, folder: Path, stop: float) -> dict:
    """Which thread wrote the CSV's rows in one dsim run to ``stop``: thread name ->
    [blocks written, rows] (the recorder's own method, wrapped for the run)."""
    written: dict[str, list[int]] = {}
    original = CsvRecorder._write_pending

    def counted(recorder):
        rows = len(recorder._pending)
        original(recorder)
        entry = written.setdefault(threading.current_thread().name, [0, 0])
        entry[0] += 1
        entry[1] += rows

    CsvRecorder._write_pending = counted
    try:
        dsim.simulate(ssp, out=folder / "threads.csv", stop=stop, handle_signals=False,
                      force=True)
    finally:
        CsvRecorder._write_pending = original
    return written


def csv_formats(ssp: Path, stop: float, repetitions: int) -> dict:
    """Microseconds per row of ways to write the ring's rows as dsim's CSV text, least of
    ``repetitions``, each checked to give the same text: dsim's ``csv_block`` (one
    ``map(repr)`` over a table of the block), ``repr`` of the table's ``tolist()`` with
    its brackets and spaces replaced, and numpy's ``astype(str)`` of the table (the
    same shortest round-trip digits)."""
    result = dsim.simulate(ssp, stop=stop, handle_signals=False)
    signals = result.signals
    names = [name for name in signals if name != "time"]
    table = np.column_stack([signals["time"]] + [signals[name] for name in names])
    times = table[:, 0].tolist()
    records = [StepRecord(n, t, row[1:]) for n, (t, row) in enumerate(zip(times, table))]

    def listed():
        text = repr(np.column_stack((times, np.array([r.values for r in records]))).tolist())
        return text[2:-2].replace("], [", "\n").replace(", ", ",") + "\n"

    def numpy_text():
        cells = np.column_stack((times, np.array([r.values for r in records]))).astype(str)
        return "\n".join(map(",".join, cells.tolist())) + "\n"

    ways = {"map(repr) (dsim)": lambda: csv_block(records), "repr of tolist()": listed,
            "numpy astype(str)": numpy_text}
    expected = csv_block(records)
    costs = {}
    for name, way in ways.items():
        if way() != expected:
            raise RuntimeError(f"{name} does not give dsim's CSV text")
        best = float("inf")
        for _ in range(repetitions):
            start = time.process_time()
            way()
            best = min(best, time.process_time() - start)
        costs[name] = best / len(records) * 1e6
    return costs


def recurrence(count: int, steps: int, inputs_start_at_zero: bool) -> np.ndarray:
    """The ring's outputs after each step, by the blocks' own exact update with the
    inputs held over a step (Jacobi): rows 1 .. steps, columns b1 .. b<count>."""
    gain, tau = 0.9, 0.1  # the block's start values
    decay = np.exp(-STEP / tau)
    y = np.ones(count)  # the block's start value y0
    rows = []
    for n in range(steps):
        u = np.zeros(count) if (n == 0 and inputs_start_at_zero) else np.roll(y, 1)
        y = gain * u + (y - gain * u) * decay
        rows.append(y)
    return np.array(rows)


def agreement(ssp: Path, count: int, stop: float) -> tuple[float, float]:
    """Largest |dsim - recurrence| and |fmpy - recurrence| over every block output.
    dsim feeds each input from the outputs at the step start, the first step too;
    fmpy's runner starts every input at 0 (its row k holds the values after step k+1)."""
    steps = round(stop / STEP)
    result = dsim.simulate(ssp, stop=stop, handle_signals=False)
    reference = simulate_ssp(str(ssp), stop_time=stop, step_size=STEP)
    ours = np.column_stack([result[f"b{i + 1}.y"][1:] for i in range(count)])
    theirs = np.column_stack([reference[f"b{i + 1}.y"][:steps] for i in range(count)])
    return (float(np.max(np.abs(ours - recurrence(count, steps, False)))),
            float(np.max(np.abs(theirs - recurrence(count, steps, True)))))


def _ratio(ratios) -> str:
    return f"{stats.median(ratios):.2f} ({min(ratios):.2f} .. {max(ratios):.2f})"


def table(rows: list[tuple[int, dict, float]]) -> str:
    """One row per ring: each master's time per step and its ratio to fmpy's, dsim's
    (CSV) ratio to libcosim's (CSV files), and both masters' errors."""
    others = [name for name in rows[0][1] if name != "fmpy"]
    cosim = "libcosim (CSV files)" in rows[0][1]
    lines = ["| blocks | fmpy simulate_ssp (us/step) | "
             + " | ".join(f"{name} (us/step) | / fmpy" for name in others)
             + (" | dsim CSV / libcosim CSV" if cosim else "") + " | error dsim | error fmpy |",
             "|---|---|" + "---|---|" * len(others) + ("---|" if cosim else "") + "---|---|"]
    for count, result, (ours, theirs) in rows:
        cells = [str(count), f"{result['fmpy']['us']:.1f}"]
        for name in others:
            cells += [f"{result[name]['us']:.1f}", _ratio(result[name]["ratios"])]
        if cosim:
            cells.append(_ratio([a / b for a, b in zip(result["dsim (CSV + statistics)"]["slopes"],
                                                       result["libcosim (CSV files)"]["slopes"])]))
        cells += [f"{ours:.1e}", f"{theirs:.1e}"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _libcosim_summary(rows) -> list[str]:
    """How far dsim is from libcosim on the smallest ring (from the times per step)."""
    count, result, _ = rows[0]
    if "libcosim (last values)" not in result:
        return ["libcosimpy is not installed here: no libcosim columns.", ""]
    us = {name: r["us"] for name, r in result.items()}
    return [f"How far from libcosim ({count} blocks, times per step): dsim keeping its rows "
            f"in memory takes {us['dsim (in memory)'] / us['libcosim (last values)']:.2f} "
            "times libcosim recording nothing, and dsim writing its CSV "
            f"{us['dsim (CSV + statistics)'] / us['libcosim (CSV files)']:.2f} times libcosim "
            "writing its CSV files (which hold every variable, at 6 digits). libcosim steps "
            "its FMUs from a pool of threads: its CPU time includes theirs.", ""]


def _where(rows, count: int, floor: dict, formats: dict, writers: dict,
           stop: float) -> list[str]:
    """Where a step of the ``count``-block ring goes, from the times per step of the
    table and the kernel's floor, as page lines."""
    found = [result for n, result, _ in rows if n == count]
    if not found or not floor:
        return []
    us = {name: entry["us"] for name, entry in found[0].items()}
    memory, csv = us["dsim (in memory)"], us["dsim (CSV + statistics)"]
    calls, timed, pair = floor["none"], floor["calls"], floor["pair"]
    lines = [
        f"Where a step goes ({count} blocks, CPU microseconds per step; the FMUs' calls "
        "alone measured by running the kernel's own calls with their argument objects "
        "and status checks in a bare loop, `kernel_floor`):",
        "",
        "| part | us per step |",
        "|---|---|",
        f"| the {3 * count} FMI calls alone (`fmi2SetReal`, `fmi2DoStep`, `fmi2GetReal` per "
        f"FMU: the ctypes crossing and the FMUs' code) | {calls:.2f} |",
        f"| timing each call for the statistics ({4 * count} clock readings) | "
        f"{timed - calls:.2f} |",
        f"| the rest of dsim's step in memory (the gather of the connections, the copy of "
        f"the outputs, the finite check, the step record, the statistics' counters) | "
        f"{memory - timed:.2f} |",
        f"| writing the CSV (the `repr` of every double, the rows' text, the writes) | "
        f"{csv - memory:.2f} |",
        f"| total, dsim writing its CSV | {csv:.2f} |",
        ""]
    if "libcosim (last values)" in us:
        cosim = us["libcosim (last values)"]
        lines += [f"libcosim recording nothing takes {cosim:.2f} us per step here: dsim in "
                  f"memory {memory / cosim:.2f} times that, and the FMI calls alone "
                  f"{calls / cosim:.2f} times (libcosim calls the same functions from C++, "
                  "without a ctypes crossing, but hands each step to its pool of threads: "
                  "its CPU time includes theirs).", ""]
    lines += [
        "Measured and dropped: timing each FMU's three calls with one pair of clock "
        f"readings instead of one reading between calls costs {pair - calls:.2f} us per "
        f"step instead of {timed - calls:.2f}, but would merge the three functions' "
        "seconds in the statistics (`functions.<name>.seconds`): kept per call. Ways to "
        "write the same CSV text (microseconds per row of the ring's rows, each checked "
        "to give dsim's text): " + ", ".join(f"{name} {cost:.2f}" for name, cost in
                                              formats.items())
        + "; dsim keeps the first. Who formats and writes the rows, in a "
        f"{stop:g} s run (thread: blocks written, rows): " + ", ".join(
            f"{name}: {blocks}, {rows}" for name, (blocks, rows) in
            {"MainThread": [0, 0], "dsim-csv-flush": [0, 0], **writers}.items())
        + ". The main thread writes a block when the recorder's flush interval has passed "
        "at the end of a step; the flush thread writes only rows that waited longer than "
        "that (behind an FMU stuck in its step). The Python code of two threads never runs "
        "at once (one interpreter lock): formatting in the flush thread could overlap only "
        "the FMUs' own code, a fraction of a microsecond per call, while the steps wait for "
        "the lock; formatting in another process would move the CPU time (counted here), "
        "not save it.", ""]
    return lines


def main(argv=None) -> str:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--blocks", default="4,10,50", help="ring sizes, comma-separated")
    parser.add_argument("--profile-blocks", type=int, default=4,
                        help="the ring whose dsim run is profiled and broken down")
    parser.add_argument("--repetitions", type=int, default=7)
    parser.add_argument("--short", type=float, default=0.5, help="short run, s")
    parser.add_argument("--long", type=float, default=5.0, help="long run, s")
    parser.add_argument("--docs", default=str(ROOT / "docs" / "causal_benchmark.md"))
    args = parser.parse_args(argv)
    rows, profiled, floor, formats, writers = [], [], {}, {}, {}
    with tempfile.TemporaryDirectory(prefix="dsim-causal-") as temp:
        folder = Path(temp)
        fmu = c_fmu(folder, "block")
        for count in (int(n) for n in args.blocks.split(",")):
            ssp = causal_ring_ssp(folder / f"ring_{count}.ssp", fmu, count, stop=args.long,
                                  step=STEP)
            result = measure(ssp, folder, args.short, args.long, args.repetitions)
            rows.append((count, result, agreement(ssp, count, args.short)))
            print(f"{count} blocks: " + ", ".join(
                f"{name} {r['us']:.1f} us/step" for name, r in result.items()), flush=True)
            if count == args.profile_blocks:
                profiled = profile(ssp, folder, args.short, args.long)
                steps = round((args.long - args.short) / STEP)
                floor = kernel_floor(ssp, steps, args.repetitions)
                formats = csv_formats(ssp, args.short, args.repetitions)
                writers = flush_threads(ssp, folder, args.long)
    text = "\n".join([
        "# Causal systems: dsim against fmpy's SSP runner and libcosim",
        "",
        f"Written by `python -m benchmarks.causal_benchmark` on {date.today()} "
        f"({machine()}, Python {platform.python_version()}). A ring of n first-order "
        "lag blocks, each a plain-C FMI 2.0 co-simulation FMU compiled in the run "
        "(tests/support/third_party/block.c), connected causally (no joints), step 1 ms. Both masters "
        "run the same .ssp archive; so does libcosim (the C++ co-simulation library of the "
        "Open Simulation Platform, through libcosimpy from PyPI, its fixed-step algorithm) "
        "where it is installed. Times are CPU seconds of the process (every thread of it: "
        "dsim's CSV flush thread too), which a machine shared with other work disturbs far "
        "less than wall time. Per-step time is the slope between a "
        f"{args.short:g} s and a {args.long:g} s run of the same master (start-up cancels); the "
        f"runs are interleaved and repeated {args.repetitions} times: the time per step comes "
        "from the least time of each run (the least disturbed by the other work of a shared "
        "machine); the ratio is the median (min .. max) of the repetitions' ratios dsim / "
        "fmpy.",
        "",
        table(rows),
        "",
        *_libcosim_summary(rows),
        "dsim runs a system without joints with its causal coupling: no state is saved or "
        "restored and no Newton runs. Unless the system has an algebraic loop to solve, its "
        "steps go through the in-process backend's causal kernel, specialised once at the "
        "start: one gather of every connection's value into one input buffer, then for each "
        "FMU one batched `fmi2SetReal` from that buffer, one `fmi2DoStep` and one batched "
        "`fmi2GetReal` into one output buffer, each called with ctypes argument objects "
        "made at the start (value-reference arrays, the buffers, the step's time), each "
        "timed, its status checked before the next call and counted per step; then one copy "
        "of the outputs as the step's row. "
        "The CSV column includes formatting and writing every output of every step in full "
        "precision (Python's `repr` of each double, the shortest text that reads back the "
        "same: most of the difference between dsim's two columns; rows are formatted a "
        "block at a time on the recorder's flush) and the statistics; fmpy keeps its rows "
        "in memory, as dsim's in-memory column does. The error columns: the largest "
        "difference of every block output from "
        "the blocks' exact update computed in numpy (benchmarks/causal_benchmark.py, "
        "`recurrence`): dsim feeds every input from the outputs at the step start, the first "
        "step too; fmpy's runner starts every input at 0. libcosim's CSV files hold every "
        "variable of every FMU at 6 significant digits; its last-values column records "
        "nothing.",
        "",
        f"## Where dsim's time goes ({args.profile_blocks} blocks)",
        "",
        *_where(rows, args.profile_blocks, floor, formats, writers, args.long),
        f"dsim (CSV + statistics) on the {args.profile_blocks}-block ring under cProfile, "
        f"the {args.long:g} s run less the {args.short:g} s one (start-up cancels): the "
        "functions of most own time, per macro step (cProfile's own cost included: its "
        "total is well above the plain run's). The kernel's `__call__` makes every FMI "
        "call: its own time includes the FMUs' functions, which run in C through ctypes and "
        "show in no Python frame, and the clock readings that time them "
        "(`time.perf_counter`). What is left is the execution's step (`Execution.step`), the "
        "finite check of the row, the recorder's queue (`stepped`) and the CSV rows, "
        "formatted in blocks on the recorder's flush (`csv_block`: one `repr` of each "
        "double of a block of rows).",
        "",
        *profiled,
        ""])
    Path(args.docs).write_text(text)
    return text


if __name__ == "__main__":
    print(main())
