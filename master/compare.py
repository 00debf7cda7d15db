"""Compare a results CSV with a reference CSV: the regression check of a CI job.

Every chosen column must stay inside a tolerance band around the reference at every
time the two share: ``|result - reference| <= atol + rtol * max|reference|`` (the
reference interpolated linearly onto the result's times when the grids differ).
For each column: the largest difference, and the first and the worst time it
leaves the band.  A result that ends before the reference (a run that failed) does
not pass either.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from master.errors import InputError
from master.results import read_columns


@dataclass(frozen=True)
class ColumnDifference:
    """How one column of a run differs from the reference: the largest difference,
    the band's half-width (``allowed``), and where the result first and worst left
    it: (time s, result, reference), None when it never did."""

    column: str
    max_difference: float
    reference_peak: float
    allowed: float
    first: tuple[float, float, float] | None = None
    worst: tuple[float, float, float] | None = None

    @property
    def passed(self) -> bool:
        return self.first is None


@dataclass
class Comparison:
    """Every column's difference, and how far each run reaches (s)."""

    differences: list[ColumnDifference] = field(default_factory=list)
    result_end: float = 0.0
    reference_end: float = 0.0

    @property
    def short(self) -> bool:
        """Whether the result ends before the reference does."""
        span = max(abs(self.reference_end), 1.0)
        return self.result_end < self.reference_end - 1e-9 * span

    @property
    def passed(self) -> bool:
        return not self.short and all(d.passed for d in self.differences)

    @property
    def failed(self) -> list[ColumnDifference]:
        return [d for d in self.differences if not d.passed]


def _read(path) -> dict[str, np.ndarray]:
    columns = read_columns(path)  # InputError for anything that is not a whole results CSV
    if len(columns["time"]) == 0:
        raise InputError(f"{path}: not a dsim results CSV (no rows)")
    return columns


def _text_column(name: str, times, values, reference) -> ColumnDifference:
    """A column of String values: equal at every shared time, or the first place
    (time, -, -) where it is not; ``max_difference`` counts the differing rows."""
    count = min(len(values), len(reference))
    differ = [k for k in range(count) if values[k] != reference[k]]
    first = (float(times[differ[0]]), float("nan"), float("nan")) if differ else None
    return ColumnDifference(name, float(len(differ)), 0.0, 0.0, first, first)


def _column(name: str, times, values, reference, rtol: float, atol: float) -> ColumnDifference:
    peak = float(np.max(np.abs(reference))) if len(reference) else 0.0
    allowed = atol + rtol * peak
    with np.errstate(invalid="ignore"):
        gap = np.abs(values - reference)
    gap = np.where(np.isfinite(gap), gap, np.inf)
    outside = np.flatnonzero(gap > allowed)
    first = worst = None
    if len(outside):
        k, w = outside[0], outside[np.argmax(gap[outside])]
        first = (float(times[k]), float(values[k]), float(reference[k]))
        worst = (float(times[w]), float(values[w]), float(reference[w]))
    largest = float(np.max(gap)) if len(gap) else 0.0
    return ColumnDifference(name, largest, peak, allowed, first, worst)


def compare_files(result, reference, columns=None, rtol: float = 1e-6,
                  atol: float = 0.0) -> Comparison:
    """The comparison of the chosen (default: every common) column."""
    ours, theirs = _read(result), _read(reference)
    common = [c for c in list(ours)[1:] if c in theirs]
    chosen = list(columns) if columns else common
    missing = [c for c in chosen if c not in common]
    if missing or not chosen:
        raise InputError(f"{result}: columns not in both files: {', '.join(missing) or 'none'}")
    times, ref_times = ours["time"], theirs["time"]
    inside = (times >= ref_times[0] - 1e-12) & (times <= ref_times[-1] + 1e-12)
    same_grid = len(times) <= len(ref_times) and np.allclose(
        times, ref_times[:len(times)], rtol=1e-12, atol=1e-15)
    comparison = Comparison([], float(times[-1]), float(ref_times[-1]))
    for name in chosen:
        values, ref_values = ours[name], theirs[name]
        if values.dtype == object or ref_values.dtype == object:
            comparison.differences.append(_text_column(name, times, values, ref_values))
            continue
        if same_grid:
            ref_values, at = ref_values[:len(times)], times
        else:
            ref_values = np.interp(times[inside], ref_times, ref_values)
            values, at = values[inside], times[inside]
        comparison.differences.append(_column(name, at, values, ref_values, rtol, atol))
    return comparison
