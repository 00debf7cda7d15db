"""Results of a run: the CSV written as the run goes, the statistics JSON beside
it, and a PNG plot of a results CSV (DESIGN.md, "Results contract")."""
from __future__ import annotations

import csv
import json
from collections import Counter
from pathlib import Path

import numpy as np


class CsvRecorder:
    """``time``, recorded outputs, joint forces: one row per macro step, flushed
    at once so that a failed run keeps every converged step."""

    def __init__(self, path: Path, columns: list[str]):
        path.parent.mkdir(parents=True, exist_ok=True)
        self.file = open(path, "w", newline="")
        self.writer = csv.writer(self.file)
        self.writer.writerow(["time"] + list(columns))
        self.rows = 0

    def write(self, time: float, outputs: list[list[float]], forces) -> None:
        row = [repr(float(time))]
        for values in outputs:
            row += [repr(float(v)) for v in values]
        row += [repr(float(f)) for f in forces]
        self.writer.writerow(row)
        self.file.flush()
        self.rows += 1

    def close(self) -> None:
        self.file.close()


class RunStatistics:
    """Counters of one run, written as JSON: wall time, steps, iterations per
    step, Lambda refreshes, FMI calls and seconds per component and function."""

    def __init__(self, scene, times):
        self.scene = scene
        self.planned_steps = len(times) - 1
        self.iterations: list[int] = []
        self.refreshes = 0
        self.failure: str | None = None
        self.setup_seconds = 0.0
        self.data: dict = {}

    def add_step(self, report) -> None:
        self.iterations.append(report.iterations)
        self.refreshes += report.refreshed

    def finish(self, wall_time: float, gluing, subsystems) -> None:
        per_component = {}
        inside = 0.0
        do_steps = 0
        for subsystem in subsystems:
            functions = {name: {"calls": calls, "seconds": seconds}
                         for name, (calls, seconds) in sorted(subsystem.counters.items())}
            seconds = sum(f["seconds"] for f in functions.values())
            inside += seconds
            do_steps += functions.get("fmi2DoStep", {}).get("calls", 0)
            per_component[subsystem.name] = {"seconds": seconds, "functions": functions}
        iterations = np.array(self.iterations or [0])
        steps = len(self.iterations)
        self.data = {
            "scene": self.scene.name,
            "file": str(self.scene.file),
            "status": "failed" if self.failure else "ok",
            "failure": self.failure,
            "start_time": self.scene.start_time,
            "stop_time": self.scene.stop_time,
            "master": self.scene.master.__dict__,
            "steps": steps,
            "planned_steps": self.planned_steps,
            "wall_seconds": wall_time,
            "setup_seconds": self.setup_seconds,
            "seconds_in_fmus": inside,
            "seconds_in_master": wall_time - inside,
            "iterations": {
                "total": int(iterations.sum()) if steps else 0,
                "mean_per_step": float(iterations.mean()) if steps else 0.0,
                "max_per_step": int(iterations.max()) if steps else 0,
                "histogram": {str(k): v for k, v in sorted(Counter(self.iterations).items())},
            },
            "lambda_refreshes": gluing.refreshes,
            "do_steps_per_step": do_steps / steps if steps else 0.0,
            "components": per_component,
        }

    def write(self, path: Path) -> None:
        path.write_text(json.dumps(self.data, indent=2))


def read_csv(path) -> tuple[list[str], np.ndarray]:
    """Column names and the data of a results CSV (rows x columns)."""
    with open(path, newline="") as file:
        reader = csv.reader(file)
        header = next(reader)
        rows = [[float(v) for v in row] for row in reader]
    return header, np.array(rows).reshape(-1, len(header))


def plot_results(csv_path, png_path, title: str = "", max_curves: int = 8) -> None:
    """Two panels over time: recorded outputs, and joint forces (``*.f_*``)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    header, data = read_csv(csv_path)
    time = data[:, 0]
    forces = [i for i, n in enumerate(header) if ".f_" in n and i > 0]
    outputs = [i for i in range(1, len(header)) if i not in forces]
    panels = [(outputs, "recorded outputs"), (forces, "joint forces (N, N.m)")]
    panels = [(columns, label) for columns, label in panels if columns]
    figure, axes = plt.subplots(len(panels), 1, sharex=True, squeeze=False,
                                figsize=(8, 3 * len(panels)))
    for axis, (columns, label) in zip(axes[:, 0], panels):
        for i in columns[:max_curves]:
            axis.plot(time, data[:, i], label=header[i])
        axis.set_ylabel(label)
        axis.grid(True, alpha=0.3)
        axis.legend(fontsize=8, loc="best")
    axes[-1, 0].set_xlabel("time (s)")
    if title:
        axes[0, 0].set_title(title)
    save_figure(figure, png_path)


def save_figure(figure, png_path) -> None:
    """Lay out, write as PNG (creating the folder) and release a matplotlib figure."""
    import matplotlib.pyplot as plt

    figure.tight_layout()
    Path(png_path).parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(png_path, dpi=110)
    plt.close(figure)
