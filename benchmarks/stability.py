"""Stability at the extremes: the iterative T-T coupling and the explicit baseline side by
side on the testbed of examples/testbed.py (two SpringMass FMUs glued at one joint)
and on the four bar's singular points, each run against its monolithic twin.

Cases: joint stiffness 1e2 .. 1e9 N/m; mass ratio across a fixed joint 1e-4 .. 1e4;
macro step from 1/100 of the glued system's shortest period to 3 times it; 1e5
undamped steps (energy drift against the twin's); zero and very large loads; the four
bar through its singular points with fixed joints (displacement and penalized
measure) and flexible ones.

    python -m benchmarks.stability [--out docs/stability.md]
"""
from __future__ import annotations

import argparse
import math
import platform
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from benchmarks import machine
from examples.testbed import Testbed, energy, monolithic, write_scene
from dsim.build_fmus.twins import four_bar_twin
from dsim.master.api import simulate
from dsim.master.sweeps.sweep import error_against

ROOT = Path(__file__).resolve().parent.parent
COUPLINGS = ("iterative", "explicit")
POSITIONS = ["left.x[1]", "right.x[1]", "right.x[2]"]


def run_case(bed: Testbed, folder: Path, step: float, stop: float, coupling: str,
             **settings) -> dict:
    """One glued run of the testbed and its error against the twin (the largest
    position difference relative to the peak; over the converged steps of a failed
    run)."""
    scene = write_scene(bed, folder, "testbed", step, stop, tolerance=1e-12)
    result = simulate(scene, coupling=coupling, **settings)
    twin = monolithic(bed, step, stop)
    error = error_against(result.signals, twin, POSITIONS) if result.steps else math.nan
    row = {"coupling": coupling, "status": result.status, "error": error,
           "iterations": result.statistics["iterations"]["mean_per_step"],
           "cuts": result.statistics["step_cuts"], "steps": result.steps,
           "message": result.message, "wall": result.statistics["wall_seconds"]}
    if bed.F0 == 0 and bed.Fa == 0 and bed.x0 != 0:  # a free vibration: energy drift
        glued, reference = energy(bed, result.signals), energy(bed, twin)
        row["drift"] = float(glued[-1] - glued[0]) / reference[0]
        row["twin_drift"] = float(reference[-1] - reference[0]) / reference[0]
    return row


def verdict(row: dict) -> str:
    """stable; completed but off by more than the peak (unstable, or lost in phase
    over a long run); or failed at the step where dsim stopped it."""
    if row["status"] == "completed":
        return "stable" if row["error"] <= 1.0 else "completed, error above the peak"
    return f"{row['status']} at step {row['steps'] + 1}"


def table(title: str, label: str, cases, folder: Path, extra=()) -> list[str]:
    """A markdown table: one row per case and coupling."""
    header = f"| {label} | H / shortest period | coupling | result | error / peak | " \
             "iterations per step | steps cut |" + "".join(f" {e} |" for e, _ in extra)
    lines = [f"### {title}", "", header, "|" + "---|" * (7 + len(extra))]
    for value, bed, step, stop, settings in cases:
        for coupling in COUPLINGS:
            row = run_case(bed, folder, step, stop, coupling, **settings)
            cells = [value, f"{step / bed.highest_period():.3g}", coupling, verdict(row),
                     f"{row['error']:.2e}", f"{row['iterations']:.2f}", str(row["cuts"])]
            cells += [show(row) for _, show in extra]
            lines.append("| " + " | ".join(cells) + " |")
            print(lines[-1], flush=True)
    return lines + [""]


def four_bar_rows() -> list[str]:
    """The four bar's scenes, both couplings, against their twins at the same step
    (the one-model four bar with index-3 rows at A and B and the parts' generalized-alpha
    rule for the fixed scene, with the parts' Baumgarte rows for the penalized one, with
    the bushings for the flexible one: examples/four_bar.py)."""
    lines = ["### The four bar through its singular points (0 to 2 s, H = 0.01 s)", "",
             "| joints | coupling | result | force at A vs monolithic / peak | iterations "
             "per step | steps cut | least-squares steps |", "|" + "---|" * 7]
    for joints in ("fixed", "penalized", "flexible"):
        scene = ROOT / "build" / "ssp" / f"four_bar_singular_{joints}.ssp"
        twin = four_bar_twin(joints, 1)
        for coupling in COUPLINGS:
            result = simulate(scene, coupling=coupling)
            stats = result.statistics
            error = error_against(result.signals, twin, ["A.f_x", "A.f_y"])
            row = {"status": result.status, "error": error, "steps": result.steps}
            lines.append(f"| {joints} | {coupling} | {verdict(row)} | {error:.2e} | "
                         f"{stats['iterations']['mean_per_step']:.2f} | {stats['step_cuts']} "
                         f"| {stats['least_squares_steps']} |")
            print(lines[-1], flush=True)
    return lines + [""]


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "stability.md"))
    parser.add_argument("--long-steps", type=int, default=100_000,
                        help="steps of the undamped runs")
    args = parser.parse_args(argv)
    started = time.perf_counter()
    base = Testbed()
    free = Testbed(F0=0.0, x0=0.01, k0=1e4, c0=0.0)
    with tempfile.TemporaryDirectory() as work:
        folder = Path(work)
        sections = [
            *table("Joint stiffness (flexible joint k0, c0 = 14.14 N.s/m; H = 0.01 s, 0 to "
                   "5 s)", "k0 (N/m)",
                   [(f"{k:g}", replace(base, k0=k), 0.01, 5.0, {})
                    for k in (1e2, 1e4, 1e6, 1e8, 1e9)], folder),
            *table("Mass ratio across a fixed joint (m1 = 10 kg; H = 0.01 s, 0 to 5 s)",
                   "m2 / m1",
                   [(f"{r:g}", replace(base, joint="fixed", m2=10.0 * r), 0.01, 5.0, {})
                    for r in (1e-4, 1e-2, 1.0, 1e2, 1e4)], folder),
            *table("Macro step against the shortest period (undamped joint k0 = 1e4; 0 to "
                   "5 s)", "H (s)",
                   [(f"{f * free.highest_period():.3g}", replace(free, F0=10.0, x0=0.0),
                     f * free.highest_period(), 5.0, {})
                    for f in (0.01, 0.1, 1 / 3, 1.0, 3.0)], folder),
            *table(f"{args.long_steps:g} undamped steps (H = 1e-3 s; free vibration from "
                   "x0 = 0.01 m)", "joint",
                   [(joint, replace(free, joint=joint), 1e-3, args.long_steps * 1e-3, {})
                    for joint in ("flexible", "fixed")], folder,
                   extra=[("energy change at the end / E0", lambda r: f"{r['drift']:.2e}"),
                          ("twin's change / E0", lambda r: f"{r['twin_drift']:.2e}")]),
            *table("Zero and very large loads (H = 0.01 s, 0 to 5 s)", "load",
                   [("none, at rest", replace(base, F0=0.0), 0.01, 5.0, {}),
                    ("1e12 N, absolute tolerance 1e-12 m", replace(base, F0=1e12), 0.01,
                     5.0, {}),
                    ("1e12 N, relative tolerance 1e-12", replace(base, F0=1e12), 0.01, 5.0,
                     {"relative_tolerance": 1e-12})], folder),
            *four_bar_rows(),
        ]
    text = "\n".join([
        "# Stability at the extremes",
        "",
        f"Written by `python -m benchmarks.stability` on {time.strftime('%Y-%m-%d')} (Python "
        f"{platform.python_version()}, {machine()}, {time.perf_counter() - started:.0f}"
        " s). The testbed (examples/testbed.py): two SpringMass FMUs, m1 on a 100 N/m spring "
        "to ground glued to m2, which a 100 N/m spring ties to m3 under a 10 N load; 10 kg "
        "each unless said. Every run is compared with its monolithic twin (the same chain in "
        "one solver, same trapezoidal rule and step): error is the largest position "
        "difference over the run relative to the twin's peak. Iterative: tolerance 1e-12 m, "
        "linear predictor, at most 20 iterations and 4 step cuts. Explicit: one trial per "
        "step, the correction fed to the next step (docs/method.md). A run is *stable* when "
        "it completes with an error at most 1; *failed* runs name the step where dsim "
        "detected the divergence (docs/method.md, Divergence), with every earlier step kept. "
        "The explicit runs that complete with an error above the peak are the cases the "
        "divergence watch does not catch: runs of fewer than 60 steps, and the long undamped "
        "run, whose explicit coupling gains half its energy over 1e5 steps, a growth of a "
        "few parts per million per step, far slower than the watch's 3x per block.",
        "",
        *sections,
    ])
    Path(args.out).write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
