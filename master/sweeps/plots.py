"""The figures of a sweep, as PNG bytes: error against wall time with its Pareto front
(``sweep.png``), each KPI against each varied factor (``kpis.png``) and the scatter
matrix of factors and KPIs (``scatter.png``).  Every axis names its unit where the
FMUs declare one (``units``: factor or KPI -> unit, :func:`sweep_units`), the KPIs
stand grouped by unit, and legends stay outside the data."""
from __future__ import annotations

import io
import math

from dsim.master.reading.fmi_description import describe
from dsim.master.recording.results import read_units, save_figure
from dsim.master.sweeps.kpi import parse

#: the units of the master's settings a sweep may vary
SETTING_UNITS = {"step": "s", "output_interval": "s", "stop": "s"}


def sweep_units(plan, names, labels, points) -> dict[str, str]:
    """Factor or KPI -> unit: a varied model parameter's FMU unit (``plan``: the
    sweep's plan), a master setting's, and a KPI's from the columns it reduces (as the
    points' statistics JSONs say them; ``s`` for argmax and argmin); '' when unknown
    or when the columns a KPI pools have several units."""
    units = {}
    for name in names:
        units[name] = SETTING_UNITS.get(name, "")
        for spec in sorted(getattr(plan, "specs", ()), key=lambda s: -len(s.name)):
            if name.startswith(spec.name + "."):
                variable = describe(spec.path).by_name.get(name[len(spec.name) + 1:])
                units[name] = (variable.unit or "") if variable is not None else ""
                break
    columns = {}
    for point in points:
        if point.results is not None:
            columns = read_units(point.results)
            if columns:
                break
    for label in labels:
        try:
            kpi = parse(label)
        except Exception:  # a label read back from a table: no unit rather than no plot
            units[label] = ""
            continue
        if kpi.reduction in ("argmax", "argmin"):
            units[label] = "s"
            continue
        found = {columns.get(c, "") for c in kpi.columns(columns)}
        units[label] = found.pop() if len(found) == 1 else ""
    return units


def _with_unit(name: str, units: dict | None) -> str:
    unit = (units or {}).get(name)
    return f"{name} ({unit})" if unit else name


def sweep_title(scene: str, fixed: dict | None = None) -> str:
    """The figures' title: the scene and the settings every point shares."""
    shared = " ".join(f"{k}={v}" for k, v in (fixed or {}).items())
    return f"{scene} ({shared})" if shared else scene

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
    figure, axis = plt.subplots(figsize=(8.6, 4.6), layout="constrained")
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
    axis.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
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


def plot_kpis(points, factors, kpis: list[str], title: str,
              units: dict | None = None) -> bytes:
    """A panel per KPI (rows, grouped by unit) and varied factor (columns): the KPI of
    each completed point against the factor's value (log axis for a log range), each
    axis with its unit; failed points marked at the panel's foot, the legend below."""
    plt = _pyplot()
    order = {unit: k for k, unit in enumerate(dict.fromkeys(
        (units or {}).get(kpi, "") for kpi in kpis))}
    kpis = sorted(kpis, key=lambda kpi: order[(units or {}).get(kpi, "")])
    rows, columns = max(len(kpis), 1), max(len(factors), 1)
    figure, axes = plt.subplots(rows, columns, figsize=(3.2 * columns + 0.8, 2.6 * rows + 0.9),
                                squeeze=False, layout="constrained")
    failed = None
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
                failed = axis.scatter([_value(p, factor.name) for p in bad],
                                      [low] * len(bad), marker="x", color="C3")
            if factor.kind == "log":
                axis.set_xscale("log")
            axis.grid(True, alpha=0.3)
            if r == rows - 1:
                axis.set_xlabel(_with_unit(factor.name, units), fontsize=8)
            if c == 0:
                axis.set_ylabel(_with_unit(kpi, units), fontsize=8)
            axis.tick_params(which="both", labelsize=7)
    if failed is not None:  # one legend for the figure, outside every panel
        figure.legend([failed], ["no value (failed), drawn at the lowest value"],
                      loc="outside lower center", fontsize=7, frameon=False)
    figure.suptitle(f"{title}: each KPI against each varied factor", fontsize=9)
    return _png(figure)


def plot_scatter(points, factors, kpis: list[str], title: str,
                 units: dict | None = None) -> bytes:
    """The scatter matrix of the numeric factors and the KPIs (histograms on the
    diagonal); at most :data:`MATRIX_LIMIT` of them."""
    plt = _pyplot()
    every = [f.name for f in factors if f.numeric] + list(kpis)
    names = every[:MATRIX_LIMIT]
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
                axis.set_xlabel(("log10 " if x in logs else "") + _with_unit(x, units),
                                fontsize=7)
            if c == 0:
                axis.set_ylabel(("log10 " if y in logs else "") + _with_unit(y, units),
                                fontsize=7)
    left = (f"\n{len(names)} of {len(every)} factors and KPIs drawn (the first; a sweep "
            "with fewer --vary or --kpi draws the others)" if len(every) > len(names) else "")
    figure.suptitle(f"{title}: scatter matrix of {len(good)} completed points{left}",
                    fontsize=9)
    return _png(figure)
