"""Sweep points per second, one after the other against one per Ray worker, measured
in the same run; writes docs/doe_benchmark.md and docs/doe_benchmark.csv.

The sweep is examples/parameter_study.py's design (a Latin hypercube over k_ground, k
and m3 of spring_mass_linear, 0 .. 10 s, two KPIs) with ``--samples`` points.  Each
repetition runs it serially, then on Ray (one point per task, one task per CPU of a
local instance started once; its start-up is reported on its own), each into a new
folder, so both see the same load of a shared machine; the table gives each
repetition's points per second and the ratio, and the median ratio.  The two runs'
KPIs must be equal bit for bit (checked): the same points give the same numbers
wherever they run.

    OMP_NUM_THREADS=1 python -m benchmarks.doe_throughput
"""
from __future__ import annotations

import argparse
import os
import platform
import statistics as stats
import tempfile
import time
from datetime import date
from pathlib import Path

from benchmarks import machine
from examples import parameter_study as study

ROOT = Path(__file__).resolve().parent.parent


def one_pair(folder: Path, samples: int) -> dict:
    """Wall seconds of the study serially and on Ray (and the sum of the Ray points'
    own wall times), the machine's ceiling just before, and their KPIs compared."""
    from benchmarks.ray_speedup import machine_ceiling
    from dsim.master.sweeps.sweep import run_sweep

    timings = {"ceiling": machine_ceiling(2)}
    kpis = {}
    for where in ("serial", "ray"):
        sweep = study.sweep_of(samples, backend="ray" if where == "ray" else None)
        started = time.perf_counter()
        points, _ = run_sweep(study.SCENE, sweep, folder / where)
        timings[where] = time.perf_counter() - started
        timings[f"{where}_points"] = sum(p.wall_seconds for p in points)
        assert all(p.status == "completed" for p in points), where
        kpis[where] = [(p.index, p.kpis) for p in points]
    assert kpis["serial"] == kpis["ray"], "the same points gave other KPIs on Ray"
    return timings


def report(samples: int, startup: float, cpus: int, pairs: list[dict]) -> tuple[str, str]:
    """The markdown page and the CSV table."""
    ratios = [p["serial"] / p["ray"] for p in pairs]
    lines = [
        "# Sweep throughput: serial against Ray",
        "",
        f"Written by `python -m benchmarks.doe_throughput` on {date.today()} (Python "
        f"{platform.python_version()}, {machine()}, {os.cpu_count()} cores, a "
        f"local Ray instance of {cpus} CPUs started once in {startup:.1f} s, not counted "
        "below). The sweep: examples/parameter_study.py's Latin hypercube over "
        f"`left.k_ground[1]`, `right.k[1]`, `right.m[2]` of spring_mass_linear, {samples} "
        "points of 0 .. 10 s (1000 macro steps each), two KPIs. Serial: the points one "
        "after the other in this process; Ray: one point per task, as many tasks at a "
        "time as the instance has CPUs. Each repetition runs both, one after the other, "
        "into new folders; the KPIs of the two are equal bit for bit (checked).",
        "",
        "The machine's ceiling is how much faster two processes did two equal pieces of "
        "CPU work than one process did both, measured just before the pair "
        "(benchmarks/ray_speedup.py): 2 on an idle 2-core machine, less when other work "
        "holds its cores; no parallel backend can beat it. Ray's overlap is the sum of "
        "its points' own wall times over the sweep's wall time: how many points were "
        "running at once, on average.",
        "",
        "| repetition | machine ceiling | serial (s) | serial points/s | Ray (s) | "
        "Ray points/s | Ray / serial | Ray's overlap |",
        "|---|---|---|---|---|---|---|---|",
    ]
    rows = ["repetition,samples,ceiling,serial_seconds,ray_seconds,serial_points_per_second,"
            "ray_points_per_second,ratio,ray_overlap"]
    for k, (pair, ratio) in enumerate(zip(pairs, ratios), start=1):
        overlap = pair["ray_points"] / pair["ray"]
        lines.append(f"| {k} | {pair['ceiling']:.2f} | {pair['serial']:.2f} | "
                     f"{samples / pair['serial']:.2f} | {pair['ray']:.2f} | "
                     f"{samples / pair['ray']:.2f} | {ratio:.2f} | {overlap:.2f} |")
        rows.append(f"{k},{samples},{pair['ceiling']!r},{pair['serial']!r},{pair['ray']!r},"
                    f"{samples / pair['serial']!r},{samples / pair['ray']!r},{ratio!r},"
                    f"{overlap!r}")
    ceiling = stats.median(p["ceiling"] for p in pairs)
    overlap = stats.median(p["ray_points"] / p["ray"] for p in pairs)
    per_point = stats.median(p["serial_points"] / samples for p in pairs)
    lines += ["", f"Median Ray / serial: **{stats.median(ratios):.2f}** points per second, "
              f"against a median machine ceiling of {ceiling:.2f}, with {cpus} Ray CPUs; "
              f"Ray's median overlap {overlap:.2f}. A point took {per_point:.2f} s in the "
              "serial sweep (median over repetitions), so Ray's cost per task "
              "(scheduling, the scene shipped, the results' bytes back) is a small share "
              "of it: the ratio follows the ceiling, which is what the machine had left "
              "to give, and grows with the cores of a cluster (docs/distributed.md). The "
              "sweep's own work outside the points (checks, plots, sensitivity) is in "
              "both columns."]
    return "\n".join(lines) + "\n", "\n".join(rows) + "\n"


def main(argv=None) -> str:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--samples", type=int, default=32)
    parser.add_argument("--repetitions", type=int, default=2)
    parser.add_argument("--docs", default=str(ROOT / "docs" / "doe_benchmark.md"))
    args = parser.parse_args(argv)
    from dsim.master.running.backends.ray.cluster import connect

    started = time.perf_counter()
    connection = connect()  # one local instance; the Ray sweeps join it
    startup = time.perf_counter() - started
    try:
        with tempfile.TemporaryDirectory(prefix="dsim-doebench-") as temp:
            pairs = []
            for k in range(args.repetitions):
                pairs.append(one_pair(Path(temp) / f"r{k}", args.samples))
                print(f"repetition {k + 1}: {pairs[-1]}")
        cpus = connection.cpus()
    finally:
        connection.close()
    page, table = report(args.samples, startup, cpus, pairs)
    Path(args.docs).write_text(page)
    Path(args.docs).with_suffix(".csv").write_text(table)
    print(page)
    return page


if __name__ == "__main__":
    main()
