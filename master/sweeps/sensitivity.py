"""Global sensitivity of each KPI to each varied factor, by what the design supports.

* Every design with more points than factors: **standardized regression coefficients**
  (SRC), the least-squares slope of the KPI on each factor scaled by their standard
  deviations, with the fit's R^2.  For a KPI close to linear in the factors (R^2 near 1)
  SRC^2 is the factor's share of the KPI's variance (its first-order Sobol' index) and
  the sign says which way it moves it; a low R^2 says the ranking needs another method.
  Each SRC has a 95 % confidence half-width from the fit's standard errors (Student's
  t on n - d - 1 degrees of freedom).  Where the sample's factors are correlated
  (|r| above :data:`CORRELATED`, as a small Latin hypercube's often are) the factors
  share the variance they explain: their SRC^2 no longer add up to R^2, and the table
  says so instead of calling them variance shares.  A few lines of numpy (lstsq): no
  library computes it on given samples for us.
* ``grid`` (full factorial): the **main-effect index** of each factor, the variance of
  the KPI's mean at each of the factor's levels over the KPI's variance: on a balanced
  full-factorial grid this is the first-order Sobol' index of that grid (an analysis of
  variance; numpy, since SALib analyses no general full-factorial grid).
* ``lhs``, ``sobol``, ``halton``: SALib's **RBD-FAST** first-order indices, which SALib
  computes from given samples (Latin hypercube recommended), with a bootstrap
  confidence interval; few points make it noisy (the interval says how much).
* ``saltelli``: SALib's **Sobol'** first-order and total indices (S1, ST).
* ``morris``: SALib's **Morris** elementary effects (mu*, sigma): the KPI's change per
  step over the factor's whole range taken as 1 (SALib's scaled effects), in the
  KPI's unit, so factors of different units compare directly.

Factors on a log range are analysed in log10 of their value (the coordinate the design
is uniform in).  Points without a KPI value (failed runs) are left out of SRC, the
main effects and RBD-FAST, and stop Sobol' and Morris, whose estimators need every
point of their design; the table says so.  An index whose confidence interval spans
zero is marked as not distinguishable from zero (:attr:`Index.spans_zero`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dsim.master.sweeps.design import Design, MORRIS_LEVELS

#: RBD-FAST harmonics: SALib's default of 10 needs far more points than a sweep has;
#: 4 keeps its bias correction meaningful from about 30 points on
RBD_HARMONICS = 4
#: fewest points RBD-FAST is asked about: its bootstrap draws subsamples, and below
#: this its bias correction divides by about zero
RBD_LEAST = 32
#: bootstrap resamples of SALib's confidence intervals, and their seed
RESAMPLES = 200
SEED = 0
#: the largest correlation between two factors in a sample under which SRC^2 still
#: reads as each factor's variance share: above it (|r| > 0.3, which a 16-point Latin
#: hypercube reaches by chance) the shares overlap, and the output says so
CORRELATED = 0.3
#: the confidence level of the SRCs' intervals (SALib's bootstrap intervals are 95 % too)
CONFIDENCE = 0.95
#: what a mark of an index whose interval spans zero means
SPANS_ZERO = "~0"
SPANS_ZERO_TEXT = ("its 95 % confidence interval spans zero: not distinguishable from "
                   "zero on these points")


@dataclass
class Index:
    """One sensitivity index: ``kpi`` to ``factor`` by ``method`` (``measure`` names it:
    SRC, R2, main_effect, S1, ST, mu_star, sigma), with a confidence half-width where the
    method gives one and a note (why it is missing)."""

    kpi: str
    factor: str
    method: str
    measure: str
    value: float
    confidence: float = math.nan
    note: str = ""

    @property
    def spans_zero(self) -> bool:
        """Whether the index's confidence interval holds zero (it is then not
        distinguishable from zero)."""
        return (bool(self.factor) and math.isfinite(self.value)
                and math.isfinite(self.confidence) and abs(self.value) <= self.confidence)


def coordinates(design: Design, configurations: list[dict]) -> np.ndarray:
    """(points, factors): each point's factors as analysed (log10 on log ranges)."""
    return np.array([[f.coordinate(c[f.name]) for f in design.factors]
                     for c in configurations], dtype=float).reshape(len(configurations),
                                                                    len(design.factors))


def src(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, float]:
    """Standardized regression coefficients of ``y`` on the columns of ``x`` and R^2."""
    coefficients, _, r2 = src_with_intervals(x, y)
    return coefficients, r2


def src_with_intervals(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                float]:
    """Standardized regression coefficients of ``y`` on the columns of ``x``, their 95 %
    confidence half-widths (the least-squares standard errors times Student's t on
    n - d - 1 degrees of freedom; nan without any) and R^2."""
    from scipy.stats import t as student  # scipy.stats is slow to import: only here

    scale_x = x.std(axis=0)
    scale_y = y.std()
    usable = scale_x > 0
    coefficients = np.full(x.shape[1], math.nan)
    halves = np.full(x.shape[1], math.nan)
    if scale_y == 0 or not usable.any():
        return coefficients, halves, math.nan
    z = (x[:, usable] - x[:, usable].mean(axis=0)) / scale_x[usable]
    w = (y - y.mean()) / scale_y
    beta, *_ = np.linalg.lstsq(z, w, rcond=None)
    coefficients[usable] = beta
    residual = w - z @ beta
    freedom = len(w) - z.shape[1] - 1
    gram = z.T @ z
    if freedom > 0 and np.linalg.matrix_rank(gram) == gram.shape[0]:
        variance = residual @ residual / freedom
        errors = np.sqrt(np.maximum(np.diag(np.linalg.inv(gram)) * variance, 0.0))
        halves[usable] = errors * student.ppf(0.5 + CONFIDENCE / 2, freedom)
    return coefficients, halves, float(1 - residual @ residual / (w @ w))


def correlation(x: np.ndarray, names: list[str]) -> tuple[float, str, str]:
    """The largest correlation (Pearson's r, by size) between two columns of ``x`` and
    the names of those two; (0, "", "") with fewer than two varying columns."""
    varying = [j for j in range(x.shape[1]) if np.ptp(x[:, j]) > 0]
    if len(varying) < 2:
        return 0.0, "", ""
    r = np.corrcoef(x[:, varying], rowvar=False)
    np.fill_diagonal(r, 0.0)
    i, j = np.unravel_index(np.argmax(np.abs(r)), r.shape)
    return float(r[i, j]), names[varying[i]], names[varying[j]]


def main_effects(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Per column of ``x``: Var over its levels of mean(y | level) / Var(y)."""
    total = y.var()
    effects = np.full(x.shape[1], math.nan)
    if total == 0:
        return effects
    for j in range(x.shape[1]):
        levels, groups = np.unique(x[:, j], return_inverse=True)
        if len(levels) < 2:
            continue
        means = np.bincount(groups, weights=y) / np.bincount(groups)
        counts = np.bincount(groups)
        effects[j] = float(np.sum(counts * (means - y.mean()) ** 2) / len(y) / total)
    return effects


def analyse(design: Design, configurations: list[dict], kpis: dict) -> list[Index]:
    """Every index the design supports for each KPI (``kpis``: label -> values per
    point, in the order of ``configurations``)."""
    numeric = [f.numeric for f in design.factors]
    if not design.factors or not all(numeric):
        words = [f.name for f in design.factors if not f.numeric]
        note = (f"factors {', '.join(words)} are not numbers" if words else "nothing varied")
        return [Index(k, "", "none", "", math.nan, note=note) for k in kpis]
    x = coordinates(design, configurations)
    names = [f.name for f in design.factors]
    indices: list[Index] = []
    for label, values in kpis.items():
        y = np.asarray(values, dtype=float)
        keep = np.isfinite(y)
        missing = int(len(y) - keep.sum())
        note = f"{missing} of {len(y)} points without a value left out" if missing else ""
        if keep.any() and np.ptp(y[keep]) == 0:
            indices.append(Index(label, "", "none", "", math.nan,
                                 note=f"the KPI is the same ({y[keep][0]:.6g}) at every point"))
            continue
        if keep.sum() > len(names) + 1:
            coefficients, halves, r2 = src_with_intervals(x[keep], y[keep])
            indices += [Index(label, n, "regression", "SRC", float(c), float(h), note=note)
                        for n, c, h in zip(names, coefficients, halves)]
            indices.append(Index(label, "", "regression", "R2", r2, note=note))
            r, a, b = correlation(x[keep], names)
            if abs(r) > CORRELATED:
                shares = float(np.nansum(coefficients ** 2))
                indices.append(Index(label, "", "regression", "correlation", r, note=(
                    f"factors {a} and {b} are correlated at r = {r:.3f} in this sample "
                    f"(above {CORRELATED:g}): they share the variance they explain, so "
                    f"SRC^2 is not a variance share here (the SRC^2 add up to "
                    f"{shares:.2f} against R^2 = {r2:.3f}) and the ranking is uncertain; "
                    "more points, or a design whose factors are uncorrelated (sobol, "
                    "saltelli), separate them")))
        else:
            indices.append(Index(label, "", "regression", "SRC", math.nan,
                                 note=f"{int(keep.sum())} points with a value: SRC needs "
                                      f"more than {len(names) + 1}"))
        indices += _by_design(design, names, x, y, keep, label, note)
    return indices


def _by_design(design, names, x, y, keep, label, note) -> list[Index]:
    """The indices of the design's own method."""
    if design.kind == "grid":
        if missing_any(keep):
            note = (note + "; " if note else "") + "a grid with holes is unbalanced"
        return [Index(label, n, "main effect (ANOVA)", "main_effect", float(e), note=note)
                for n, e in zip(names, main_effects(x[keep], y[keep]))]
    if design.kind in ("lhs", "sobol", "halton"):
        if keep.sum() < RBD_LEAST:
            return [Index(label, "", "RBD-FAST", "S1", math.nan,
                          note=f"{int(keep.sum())} points: RBD-FAST needs {RBD_LEAST}")]
        import warnings

        from SALib.analyze import rbd_fast
        with warnings.catch_warnings():  # a factor with no harmonic content: nan, said
            warnings.simplefilter("ignore", RuntimeWarning)
            try:
                found = rbd_fast.analyze(design.salib_problem(), x[keep], y[keep],
                                         M=RBD_HARMONICS, num_resamples=RESAMPLES, seed=SEED)
            except (ZeroDivisionError, ValueError, FloatingPointError) as error:
                return [Index(label, "", "RBD-FAST", "S1", math.nan,
                              note=f"RBD-FAST failed on these points: {error}")]
        return [Index(label, n, "RBD-FAST", "S1", float(s), float(c), note)
                for n, s, c in zip(names, found["S1"], found["S1_conf"])]
    if missing_any(keep):
        return [Index(label, "", design.kind, "", math.nan,
                      note=f"{note}: {design.kind} needs every point of its design")]
    if design.kind == "saltelli":
        from SALib.analyze import sobol
        found = sobol.analyze(design.salib_problem(), y, calc_second_order=False,
                              num_resamples=RESAMPLES, seed=SEED)
        return ([Index(label, n, "Sobol'", "S1", float(s), float(c)) for n, s, c in
                 zip(names, found["S1"], found["S1_conf"])]
                + [Index(label, n, "Sobol'", "ST", float(s), float(c)) for n, s, c in
                   zip(names, found["ST"], found["ST_conf"])])
    from SALib.analyze import morris
    found = morris.analyze(design.salib_problem(), x, y, num_levels=MORRIS_LEVELS,
                           num_resamples=RESAMPLES, seed=SEED)
    return ([Index(label, n, "Morris", "mu_star", float(s), float(c)) for n, s, c in
             zip(names, found["mu_star"], found["mu_star_conf"])]
            + [Index(label, n, "Morris", "sigma", float(s)) for n, s in
               zip(names, found["sigma"])])


def missing_any(keep: np.ndarray) -> bool:
    return not bool(np.all(keep))


def ranked(indices: list[Index], kpi: str) -> list[Index]:
    """The indices :func:`ranking` orders ``kpi``'s factors by, largest first."""
    for method, measure in (("main effect (ANOVA)", "main_effect"), ("Sobol'", "S1"),
                            ("Morris", "mu_star"), ("regression", "SRC"), ("RBD-FAST", "S1")):
        chosen = [i for i in indices if i.kpi == kpi and (i.method, i.measure) ==
                  (method, measure) and i.factor and math.isfinite(i.value)]
        if chosen:
            return sorted(chosen, key=lambda i: -abs(i.value))
    return []


def ranking(indices: list[Index], kpi: str) -> list[str]:
    """The factors by the size of their effect on ``kpi``, largest first, by the first
    measure present of: main effect, Sobol' S1, Morris mu*, |SRC|, RBD-FAST S1 (last:
    noisy on the few dozen points of a sweep)."""
    return [i.factor for i in ranked(indices, kpi)]


def ranking_text(indices: list[Index], kpi: str) -> str:
    """``a > b > c ~0``: :func:`ranking`, each factor whose index is not
    distinguishable from zero marked ``~0`` (empty when nothing ranks)."""
    return " > ".join(i.factor + (f" {SPANS_ZERO}" if i.spans_zero else "")
                      for i in ranked(indices, kpi))


def cautions(indices: list[Index], kpi: str) -> list[str]:
    """What the reader of ``kpi``'s indices must know before trusting them: factors
    correlated in the sample."""
    return [i.note for i in indices if i.kpi == kpi and i.measure == "correlation"]


def csv_text(indices: list[Index]) -> str:
    """The indices as ``sensitivity.csv``."""
    import csv
    import io

    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(["kpi", "factor", "method", "measure", "value", "confidence", "note"])
    for i in indices:
        note = "; ".join([i.note] * bool(i.note) + [SPANS_ZERO_TEXT] * i.spans_zero)
        writer.writerow([i.kpi, i.factor, i.method, i.measure, repr(i.value),
                         repr(i.confidence), note])
    return text.getvalue()


def markdown(indices: list[Index]) -> str:
    """The indices as a table per KPI: factors down, measures across."""
    lines = []
    for kpi in dict.fromkeys(i.kpi for i in indices):
        mine = [i for i in indices if i.kpi == kpi]
        measures = list(dict.fromkeys(f"{i.method}: {i.measure}" for i in mine if i.factor))
        lines += [f"### {kpi}", ""]
        r2 = [i for i in mine if i.measure == "R2"]
        correlated = cautions(indices, kpi)
        if r2 and math.isfinite(r2[0].value):
            lines.append(f"Linear fit R^2 = {r2[0].value:.3f}" + (
                "." if correlated else
                " (SRC^2 is a factor's variance share where R^2 is close to 1)."))
        lines += [f"- **Caution**: {note}" for note in correlated]
        lines += [f"- {i.method}: {i.note}" for i in mine if i.note and not i.factor
                  and i.measure != "correlation"]
        if measures:
            lines += ["", "| factor | " + " | ".join(measures) + " |",
                      "|---|" + "---|" * len(measures)]
            for factor in dict.fromkeys(i.factor for i in mine if i.factor):
                cells = []
                for m in measures:
                    found = [i for i in mine if i.factor == factor
                             and f"{i.method}: {i.measure}" == m]
                    cells.append(_value(found[0]) if found else "")
                lines.append(f"| {factor} | " + " | ".join(cells) + " |")
            if any(i.spans_zero for i in mine):
                lines.append(f"\n{SPANS_ZERO}: {SPANS_ZERO_TEXT}.")
            order = ranking_text(indices, kpi)
            if order:
                lines.append(f"\nRanking: {order}")
        lines.append("")
    return "\n".join(lines)


def _value(index: Index) -> str:
    text = f"{index.value:.3f}" if math.isfinite(index.value) else "n/a"
    if math.isfinite(index.confidence):
        text += f" ± {index.confidence:.3f}"
    if index.spans_zero:
        text += f" {SPANS_ZERO}"
    return text
