"""The figures of a sweep, as PNG bytes: error against wall time with its Pareto front
(``sweep.png``), each KPI against each varied factor (``kpis.png``) and the scatter
matrix of factors and KPIs (``scatter.png``)."""
from __future__ import annotations

import io
import math
from dsim.master.recording.results import save_figure

#: most factors plus KPIs drawn in a scatter matrix (beyond it a figure is unreadable)
MATRIX_LIMIT = 8


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _png(figure) -> bytes:
    image = io.BytesIO()
    save_figure(figure, image)
    return image.getvalue()


def plot_points(points, title: str) -> bytes:
    """Error against wall time, log-log, the Pareto front joined; PNG bytes."""
    plt = _pyplot()
    figure, axis = plt.subplots(figsize=(7, 4.6))
    stable = [p for p in points if p.stable and p.error > 0 and math.isfinite(p.error)]
    exact = [p for p in points if p.stable and p.error == 0]
    floor = min([p.error for p in stable], default=1e-16) / 10
    axis.scatter([p.wall_seconds for p in stable], [p.error for p in stable], color="C0",
                 label="stable point")
    axis.scatter([p.wall_seconds for p in exact], [floor] * len(exact), color="C2",
                 marker="*", s=90, label="the reference itself")
    unstable = [p for p in points if not p.stable and math.isfinite(p.wall_seconds)]
    if unstable:
        axis.scatter([p.wall_seconds for p in unstable],
                     [max(floor, 1.0)] * len(unstable), color="C3", marker="x",
                     label="unstable / failed (drawn at 1)")
    front = sorted((p for p in stable if p.pareto), key=lambda p: p.wall_seconds)
    if front:
        axis.plot([p.wall_seconds for p in front], [p.error for p in front], "C1-",
                  label="Pareto front")
    for p in front:  # the front's points named by their values, the rest in sweep.md
        axis.annotate(" ".join(str(v) for v in p.settings.values()),
                      (p.wall_seconds, p.error), fontsize=7, xytext=(4, 4),
                      textcoords="offset points")
    axis.set_xscale("log")
    axis.set_yscale("log")
    axis.set_xlabel("wall time (s)")
    axis.set_ylabel("error / peak")
    axis.grid(True, which="both", alpha=0.3)
    axis.legend(fontsize=8, loc="lower left")
    axis.set_title(f"{title}: error against wall time ("
                   + ", ".join(dict.fromkeys(k for p in points for k in p.settings)) + ")",
                   fontsize=9)
    return _png(figure)


def _value(point, name: str) -> float:
    value = point.kpis[name] if name in point.kpis else point.settings.get(name)
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def plot_kpis(points, factors, kpis: list[str], title: str) -> bytes:
    """A panel per KPI (rows) and varied factor (columns): the KPI of each completed
    point against the factor's value (log axis for a log range); failed points marked
    at the panel's foot."""
    plt = _pyplot()
    rows, columns = max(len(kpis), 1), max(len(factors), 1)
    figure, axes = plt.subplots(rows, columns, figsize=(3.2 * columns + 0.6, 2.6 * rows + 0.6),
                                squeeze=False)
    for r, kpi in enumerate(kpis):
        for c, factor in enumerate(factors):
            axis = axes[r][c]
            good = [p for p in points if math.isfinite(_value(p, kpi))
                    and math.isfinite(_value(p, factor.name))]
            axis.scatter([_value(p, factor.name) for p in good], [_value(p, kpi) for p in good],
                         s=14, color="C0")
            bad = [p for p in points if not math.isfinite(_value(p, kpi))
                   and math.isfinite(_value(p, factor.name))]
            if bad and good:
                low = min(_value(p, kpi) for p in good)
                axis.scatter([_value(p, factor.name) for p in bad], [low] * len(bad),
                             marker="x", color="C3", label="no value (failed)")
                axis.legend(fontsize=7)
            if factor.kind == "log":
                axis.set_xscale("log")
            axis.grid(True, alpha=0.3)
            if r == rows - 1:
                axis.set_xlabel(factor.name, fontsize=8)
            if c == 0:
                axis.set_ylabel(kpi, fontsize=8)
            axis.tick_params(labelsize=7)
    figure.suptitle(f"{title}: each KPI against each varied factor", fontsize=9)
    return _png(figure)


def plot_scatter(points, factors, kpis: list[str], title: str) -> bytes:
    """The scatter matrix of the numeric factors and the KPIs (histograms on the
    diagonal); at most :data:`MATRIX_LIMIT` of them."""
    plt = _pyplot()
    names = ([f.name for f in factors if f.numeric] + list(kpis))[:MATRIX_LIMIT]
    logs = {f.name for f in factors if f.kind == "log"}
    good = [p for p in points if all(math.isfinite(_value(p, n)) for n in names)]
    size = len(names)
    figure, axes = plt.subplots(size, size, figsize=(1.9 * size + 0.8, 1.9 * size + 0.8),
                                squeeze=False)
    for r, y in enumerate(names):
        for c, x in enumerate(names):
            axis = axes[r][c]
            xs = [_value(p, x) for p in good]
            if x in logs:
                xs = [math.log10(v) for v in xs]
            if r == c:
                axis.hist(xs, bins=min(12, max(3, len(xs) // 4)), color="C0", alpha=0.7)
            else:
                ys = [_value(p, y) for p in good]
                ys = [math.log10(v) for v in ys] if y in logs else ys
                axis.scatter(xs, ys, s=6, color="C0")
            axis.tick_params(labelsize=6)
            if r == size - 1:
                axis.set_xlabel(("log10 " if x in logs else "") + x, fontsize=7)
            if c == 0:
                axis.set_ylabel(("log10 " if y in logs else "") + y, fontsize=7)
    figure.suptitle(f"{title}: scatter matrix of {len(good)} completed points", fontsize=9)
    return _png(figure)
