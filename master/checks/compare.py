"""Compare a results CSV with a reference CSV: the regression check of a CI job.

Every chosen column must stay inside a tolerance band around the reference at every
time the two share (the reference interpolated linearly onto the result's times
when the grids differ).  For each column: the largest difference, and the first and
the worst time it leaves the band.  A result that ends before the reference (a run
that failed) does not pass either.

The band's half-width (:func:`band`) is ``atol + rtol * max|reference|``, but never
less than a floor that round-off cannot cross: the last bits of a solve differ
between CPUs and numpy releases (OpenBLAS picks its kernels by CPU), and a column
that is zero in exact arithmetic is pure round-off, its own peak no scale at all::

    allowed = max(atol + rtol * peak, ULPS * eps * scale, NOISE_FACTOR * noise)

``scale`` is the largest peak among the columns of the same quantity (see
:func:`quantity`) and ``noise`` the column's spread between OpenBLAS kernels, as
measured by :mod:`dsim.master.checks.kernel_study` and stored in a baseline's JSON.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dsim.master.errors import InputError
from dsim.master.recording.results import read_columns

#: A few units in the last place of the column's scale: what reordered sums and
#: fused multiply-adds move a well-conditioned result by.  16 is far below any rtol
#: a user sets (16 eps = 3.6e-15) and far above the 1-2 ulps such changes give.
ULPS = 16
#: The measured spread between kernels is a sample: the kernels this CPU can run,
#: this numpy.  Other CPUs' kernels (AVX-512) and other releases land elsewhere in
#: the same round-off cloud.  Measured (docs/ci.md): an AVX-512 machine's difference
#: from the shipped baselines was 0.62 x the spread of the Prescott, Nehalem,
#: Sandybridge and Haswell kernels on an AVX2 machine for the penalized four bar's
#: coupler.omega, 0.58 x for the fixed one's coupler.theta; the baselines made
#: elsewhere differ from that machine's runs by at most 1.45 x (four_post_fixed,
#: mount_fr.f_z).  10 leaves a margin of 7 over the worst seen, and stays orders of
#: magnitude below a change of the dynamics.
NOISE_FACTOR = 10.0
EPS = float(np.finfo(float).eps)


def quantity(column: str) -> str:
    """The quantity a column measures, without the component or joint it belongs to
    and without a node index: ``coupler.theta`` -> ``theta``, ``right.x[2]`` -> ``x``."""
    return column.rsplit(".", 1)[-1].split("[", 1)[0]


def band(peak: float, rtol: float, atol: float, scale: float | None = None,
         noise: float | None = None) -> tuple[float, str]:
    """The half-width of a column's band and what set it: ``"rtol"`` (atol + rtol *
    peak), ``"ulps"`` (ULPS * eps * scale; scale defaults to the peak) or
    ``"noise"`` (NOISE_FACTOR * the spread measured between BLAS kernels)."""
    tolerance = atol + rtol * peak
    ulps = ULPS * EPS * max(peak, scale or 0.0)
    measured = NOISE_FACTOR * noise if noise else 0.0
    allowed, source = max((tolerance, "rtol"), (ulps, "ulps"), (measured, "noise"),
                          key=lambda pair: pair[0])
    return allowed, source


def band_origin(difference: "ColumnDifference") -> str:
    """Where a column's band came from, in words (for reports)."""
    if difference.source == "ulps":
        return f"floor: {ULPS} ulps of {difference.scale:.3g}"
    if difference.source == "noise":
        return (f"floor: {NOISE_FACTOR:g} x {difference.noise:.3g} measured between "
                "BLAS kernels")
    return "rtol"


@dataclass(frozen=True)
class ColumnDifference:
    """How one column of a run differs from the reference: the largest difference,
    the band's half-width (``allowed``) and what set it (``source``: rtol, ulps or
    noise, with the ``scale`` and ``noise`` the floors used), and where the result
    first and worst left it: (time s, result, reference), None when it never did."""

    column: str
    max_difference: float
    reference_peak: float
    allowed: float
    first: tuple[float, float, float] | None = None
    worst: tuple[float, float, float] | None = None
    source: str = "rtol"
    scale: float = 0.0
    noise: float = 0.0

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


def _peak(values) -> float:
    return float(np.max(np.abs(values))) if len(values) else 0.0


def _column(name: str, times, values, reference, rtol: float, atol: float,
            scale: float, noise: float) -> ColumnDifference:
    peak = _peak(reference)
    allowed, source = band(peak, rtol, atol, scale, noise)
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
    return ColumnDifference(name, largest, peak, allowed, first, worst, source,
                            max(peak, scale), noise)


def quantity_scales(columns: dict) -> dict[str, float]:
    """Per quantity (:func:`quantity`), the largest peak of its numeric columns: the
    size of what a column is computed from, when its own peak is only round-off."""
    scales: dict[str, float] = {}
    for name, values in list(columns.items())[1:]:
        if values.dtype != object:
            scales[quantity(name)] = max(scales.get(quantity(name), 0.0), _peak(values))
    return scales


def compare_files(result, reference, columns=None, rtol: float = 1e-6,
                  atol: float = 0.0, noise: dict | None = None) -> Comparison:
    """The comparison of the chosen (default: every common) column; ``noise``: per
    column, the spread measured between BLAS kernels (a baseline JSON's)."""
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
    scales, noise = quantity_scales(theirs), noise or {}
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
        comparison.differences.append(_column(name, at, values, ref_values, rtol, atol,
                                              scales[quantity(name)],
                                              float(noise.get(name, 0.0))))
    return comparison
