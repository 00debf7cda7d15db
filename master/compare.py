"""Compare a results CSV with a reference CSV: the regression check of a CI job.

A column passes when ``max |result - reference| <= atol + rtol * max |reference|``
over the common time span (the reference is interpolated linearly onto the
result's times when the two grids differ).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from master.errors import InputError
from master.results import read_csv


@dataclass(frozen=True)
class ColumnDifference:
    """How one column of a run differs from the reference."""

    column: str
    max_difference: float
    reference_peak: float
    allowed: float

    @property
    def passed(self) -> bool:
        return bool(self.max_difference <= self.allowed)


def _read(path) -> tuple[list[str], np.ndarray]:
    header, data = read_csv(path)  # InputError for anything that is not a whole results CSV
    if len(data) == 0:
        raise InputError(f"{path}: not a dsim results CSV (no rows)")
    return header, data


def compare_files(result, reference, columns=None, rtol: float = 1e-6,
                  atol: float = 0.0) -> list[ColumnDifference]:
    """Differences of the chosen (default: every common) column."""
    header, data = _read(result)
    ref_header, ref_data = _read(reference)
    common = [c for c in header[1:] if c in ref_header[1:]]
    chosen = list(columns) if columns else common
    missing = [c for c in chosen if c not in common]
    if missing or not chosen:
        raise InputError(f"{result}: columns not in both files: {', '.join(missing) or 'none'}")
    times, ref_times = data[:, 0], ref_data[:, 0]
    inside = (times >= ref_times[0] - 1e-12) & (times <= ref_times[-1] + 1e-12)
    same_grid = len(times) == len(ref_times) and np.allclose(times, ref_times, rtol=1e-12,
                                                              atol=1e-15)
    differences = []
    for column in chosen:
        values = data[:, header.index(column)]
        ref_values = ref_data[:, ref_header.index(column)]
        if not same_grid:
            ref_values = np.interp(times[inside], ref_times, ref_values)
            values = values[inside]
        peak = float(np.max(np.abs(ref_values)))
        difference = float(np.max(np.abs(values - ref_values)))
        if not np.isfinite(difference):
            difference = float("inf")
        differences.append(ColumnDifference(column, difference, peak, atol + rtol * peak))
    return differences
