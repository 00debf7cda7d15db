"""Results as the pages show them: signals for charts (thinned to what a chart can
draw), the ``dsim compare`` verdict of runs against a baseline, a sweep's points
read back from its ``sweep.csv``, and the .mat and PNG files made on request
from a run's CSV with dsim's own writers."""
from __future__ import annotations

import io
import math
import threading
from pathlib import Path

import numpy as np

from dsim import (InputError, Point, compare_files, mark_pareto, mat_bytes, plot_overlay,
                  plot_signals, read_columns, read_table, read_units)

#: most points per curve sent to a browser chart
MAX_POINTS = 4000
#: matplotlib's pyplot is not thread-safe: one figure at a time
_PLOT_LOCK = threading.Lock()


def _finite(values) -> list:
    return [float(v) if math.isfinite(v) else None for v in np.asarray(values, float)]


def thin(count: int, most: int = MAX_POINTS) -> slice:
    """Every n-th row so that at most about ``most`` remain (the last row kept by the
    caller where it matters)."""
    return slice(None, None, max(1, math.ceil(count / most)))


def signals(csv_path: Path, wanted=None) -> dict:
    """``{"time": [...], "columns": {name: [...]}}`` of the numeric columns of a
    results CSV (``wanted``: those only), thinned for a chart."""
    columns = read_columns(csv_path)
    names = [n for n in columns if n != "time" and columns[n].dtype != object
             and (not wanted or n in wanted)]
    rows = thin(len(columns["time"]))
    return {"time": _finite(columns["time"][rows]),
            "columns": {n: _finite(columns[n][rows]) for n in names}}


def overlay(results: dict, column: str) -> dict:
    """One column of several runs (``results``: label -> CSV path), for one chart:
    ``{"column": ..., "series": [{"label", "time", "values"}]}``; runs without the
    column or without a readable CSV are left out."""
    series = []
    for label, path in results.items():
        try:
            columns = read_columns(path)
        except InputError:
            continue
        if column in columns and columns[column].dtype != object:
            rows = thin(len(columns["time"]))
            series.append({"label": label, "time": _finite(columns["time"][rows]),
                           "values": _finite(columns[column][rows])})
    return {"column": column, "series": series}


def verdict(result_csv: Path, baseline_csv: Path, rtol: float, atol: float) -> dict:
    """``dsim compare RESULT BASELINE``: per column the largest difference, the band
    and the first and worst time it leaves the band; ``error`` when it cannot."""
    try:
        comparison = compare_files(result_csv, baseline_csv, rtol=rtol, atol=atol)
    except InputError as error:
        return {"error": "; ".join(error.problems)}
    return {"passed": comparison.passed, "short": comparison.short,
            "result_end": comparison.result_end, "reference_end": comparison.reference_end,
            "columns": [{"column": d.column, "passed": d.passed,
                         "max_difference": d.max_difference, "allowed": d.allowed,
                         "reference_peak": d.reference_peak, "first": d.first,
                         "worst": d.worst} for d in comparison.differences]}


def sweep_points(folder: Path) -> tuple[list[str], list[Point]]:
    """The varied names and every finished point of a sweep's ``sweep.csv`` (its
    temporary file while the sweep runs), Pareto front marked."""
    names, _, points = sweep_table(folder)
    return names, points


def sweep_table(folder: Path) -> tuple[list[str], list[str], list[Point]]:
    """(varied names, KPI labels, points) of a sweep's folder, Pareto front marked; read
    by dsim's own reader (:func:`dsim.read_table`), which the writer's
    quoting matches."""
    path = folder / "sweep.csv"
    if not path.exists():
        path = folder / ".sweep.csv.partial"
    names, kpis, points = read_table(path)
    mark_pareto(points)
    return names, kpis, points


def png(csv_path: Path, title: str) -> bytes:
    """dsim's plot of a run's signals (``dsim run --plot``)."""
    image = io.BytesIO()
    with _PLOT_LOCK:
        plot_signals(read_columns(csv_path), image, title, units=read_units(csv_path))
    return image.getvalue()


def overlay_png(results: dict, names: list[str], title: str) -> bytes:
    """dsim's overlay plot of several runs (``dsim plot``)."""
    image = io.BytesIO()
    with _PLOT_LOCK:
        plot_overlay({label: read_columns(path) for label, path in results.items()},
                     names, image, title,
                     {k: v for path in results.values() for k, v in read_units(path).items()})
    return image.getvalue()


def mat(csv_path: Path) -> bytes:
    """A run's signals as a MATLAB .mat file (``dsim run --mat``)."""
    return mat_bytes(read_columns(csv_path), read_units(csv_path))
