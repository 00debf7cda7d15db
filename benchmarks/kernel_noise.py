"""How far each column of a scene moves when only the OpenBLAS kernels change: per
kernel, the largest difference from the run with the default kernel, next to the
spread ``dsim regress --update`` stores as the band's floor (dsim.master.checks.kernel_study).

    python -m benchmarks.kernel_noise [SCENE ...] [--out docs/kernel_noise.md]

Default scenes: the three four bars (a singular parallelogram: coupler.theta and
coupler.omega are zero in exact arithmetic, pure round-off).
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from dsim.master.api import simulate
from dsim.master.recording.output_files import write_whole
from dsim.master.recording.results import read_columns
from dsim.master.checks.compare import NOISE_FACTOR
from dsim.master.checks.kernel_study import study

ROOT = Path(__file__).resolve().parent.parent
SCENES = ("four_bar_singular_fixed", "four_bar_singular_penalized",
          "four_bar_singular_flexible")


def measure(scene: str, folder: Path) -> list[str]:
    """The markdown table of one scene: a row per column, a column per kernel."""
    spec = json.loads((ROOT / "regression" / "baselines" / f"{scene}.json").read_text())
    settings = spec["settings"]
    baseline = folder / f"{scene}.csv"
    simulate(ROOT / "build" / "ssp" / f"{scene}.ssp", out=baseline, **settings)
    start = time.perf_counter()
    measured = study(ROOT / "build" / "ssp" / f"{scene}.ssp", settings, baseline,
                     keep=folder / "kernels")
    seconds = time.perf_counter() - start
    if measured.skipped:
        return [f"## {scene}", "", measured.skipped, ""]
    default = read_columns(baseline)
    runs = {r.kernel: read_columns(r.csv) for r in measured.runs if r.csv is not None}
    said = ", ".join(f"{k} {v}" for k, v in settings.items())
    lines = [f"## {scene} ({said}; study {seconds:.1f} s)", "",
             "| column | peak | " + " | ".join(f"{k} ({measured.kernels[k]})" for k in runs)
             + f" | spread | floor ({NOISE_FACTOR:g} x) |",
             "|---" * (len(runs) + 4) + "|"]
    for name in list(default)[1:]:
        peak = float(np.max(np.abs(default[name])))
        cells = [f"{float(np.max(np.abs(run[name] - default[name]))):.2e}"
                 for run in runs.values()]
        noise = measured.noise.get(name, 0.0)
        lines.append(f"| {name} | {peak:.3g} | " + " | ".join(cells)
                     + f" | {noise:.2e} | {NOISE_FACTOR * noise:.2e} |")
    if measured.failed:
        lines.append("")
        lines += [f"- failed under {k}: {v}" for k, v in measured.failed.items()]
    return lines + [""]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="*", default=list(SCENES))
    parser.add_argument("--out", help="write the tables to this markdown file too")
    args = parser.parse_args(argv)
    lines = ["# Round-off between OpenBLAS kernels", ""]
    with tempfile.TemporaryDirectory(prefix="dsim-kernel-noise-") as temp:
        for scene in args.scenes:
            lines += measure(scene, Path(temp) / scene)
    text = "\n".join(lines)
    print(text)
    if args.out:
        write_whole(Path(args.out), (text + "\n").encode())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
