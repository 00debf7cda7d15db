"""`dsim sweep` on the shipped scenes: error against each scene's monolithic twin
(resources/reference.csv, at a tenth of the scene's step) against wall time, over
macro step, tolerance, predictor and coupling; the cheapest point per error level.

    python -m benchmarks.sweeps [--out docs/sweeps.md]

Writes docs/sweeps.md and docs/sweep_<scene>.png (each sweep's error-against-time
plot with its Pareto front); the points' results go to results/sweeps/.
"""
from __future__ import annotations

import argparse
import platform
import shutil
import time
from pathlib import Path

from benchmarks import machine
from dsim.master.sweeps.sweep import Sweep, cheapest, command_line, markdown, run_sweep

ROOT = Path(__file__).resolve().parent.parent
OUT_DIR = ROOT / "results" / "sweeps"

#: scene -> its sweep: a grid of iterative points and the explicit baseline's points
SWEEPS = {
    "spring_mass_nonlinear": Sweep(
        grid={"step": [0.0025, 0.005, 0.01, 0.02], "tolerance": [1e-4, 1e-6, 1e-10],
              "predictor": ["linear", "quadratic"]},
        points=[{"step": step, "coupling": "explicit", "predictor": predictor}
                for step in (0.005, 0.01) for predictor in ("constant", "quadratic")],
        fixed={"stop": 10.0}),
    "four_bar_singular_flexible": Sweep(
        grid={"step": [0.001, 0.0025, 0.005, 0.01], "tolerance": [1e-6, 1e-8]},
        points=[{"step": step, "coupling": "explicit"} for step in (0.001, 0.01)],
        fixed={"stop": 2.0}),
    "frame_split": Sweep(
        grid={"step": [2.5e-5, 5e-5, 1e-4, 2e-4], "tolerance": [1e-10, 1e-12]},
        points=[{"step": 1e-4, "coupling": "explicit"}],
        fixed={"stop": 0.05}),
}
#: error levels (relative to the reference's peak) the summary names a point for
TARGETS = (1e-2, 1e-3, 1e-4, 1e-5)


def summary(scene: str, points, fixed: dict) -> list[str]:
    """Markdown rows: per target error, the cheapest point that meets it."""
    rows = []
    for target in TARGETS:
        best = cheapest(points, target)
        if best is None:
            rows.append(f"| {scene} | {target:g} | no point | | |")
        else:
            rows.append(f"| {scene} | {target:g} | {best.label} | {best.wall_seconds:.2f} | "
                        f"`{command_line(f'{scene}.ssp', best, fixed)}` |")
    return rows


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "sweeps.md"))
    args = parser.parse_args(argv)
    out = Path(args.out)
    sections, cheapest_rows = [], []
    for scene, sweep in SWEEPS.items():
        folder = OUT_DIR / scene
        shutil.rmtree(folder, ignore_errors=True)
        points, _ = run_sweep(ROOT / "build" / "ssp" / f"{scene}.ssp", sweep, folder)
        shutil.copyfile(folder / "sweep.png", out.parent / f"sweep_{scene}.png")
        names = list(dict.fromkeys(k for p in points for k in p.settings))
        sections += [f"## {scene} (stop {sweep.fixed['stop']:g} s)", "",
                     markdown(points, names, "the scene's monolithic twin"),
                     f"![{scene}](sweep_{scene}.png)", ""]
        cheapest_rows += summary(scene, points, sweep.fixed)
    text = "\n".join([
        "# Sweeps of the shipped scenes",
        "",
        f"Written by `python -m benchmarks.sweeps` on {time.strftime('%Y-%m-%d')} (Python "
        f"{platform.python_version()}, {machine()}, one process, points run one "
        "after the other). Each point is one `dsim sweep` run; its error is against the "
        "monolithic twin the scene ships (at a tenth of the scene's step), so it holds the "
        "time discretization's error as well as the gluing's. Wall times are of a shared "
        "machine: compare them within one table.",
        "",
        "## The cheapest point per error level",
        "",
        "| scene | error at most | cheapest point | wall (s) | command |",
        "|---|---|---|---|---|",
        *cheapest_rows,
        "",
        *sections,
    ])
    out.write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
