"""``dsim sweep``: the speed-accuracy trade of one scene, measured.

A sweep runs a scene at every point of a grid of settings (macro step, tolerance,
coupling, predictor, refresh policy, parameter set: anything ``dsim.simulate``
takes) and measures each: the error against a reference (a results CSV the user
gives, else the monolithic twin's results a scene ships as ``resources/reference.csv``,
else the sweep's tightest run), wall
time, iterations and doSteps per step, and whether it stayed stable.  Each
finished point is a whole row of ``sweep.csv`` at once, so an interrupted sweep
keeps them; at the end (or the interrupt) it writes ``sweep.md`` (a table) and
``sweep.png`` (error against wall time, the Pareto front marked).
"""
from __future__ import annotations

import itertools
import json
import math
import shlex
import time as clock
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from master.errors import InputError
from master.output_files import OutputFile, write_whole
from master.settings import SETTINGS, convert

#: the reference named to measure against the sweep's tightest point even where the
#: scene ships its monolithic twin
TIGHTEST = "tightest"
#: the columns of sweep.csv, after the point's settings
MEASURES = ("status", "stable", "error", "wall_seconds", "iterations_per_step",
            "do_steps_per_fmu_step", "lambda_refreshes", "steps", "message")


@dataclass
class Point:
    """One configuration of a sweep and what it measured."""

    settings: dict
    status: str = ""
    stable: bool = False
    error: float = math.nan
    wall_seconds: float = math.nan
    iterations_per_step: float = math.nan
    do_steps_per_fmu_step: float = math.nan
    lambda_refreshes: int = 0
    steps: int = 0
    message: str = ""
    results: Path | None = None
    pareto: bool = False

    @property
    def label(self) -> str:
        return " ".join(f"{k}={v}" for k, v in self.settings.items())


@dataclass
class Sweep:
    """What to sweep: a grid (setting -> values) or explicit points, settings that
    hold for every point, the reference and the compared columns."""

    grid: dict = field(default_factory=dict)
    points: list = field(default_factory=list)
    fixed: dict = field(default_factory=dict)
    #: a results CSV, TIGHTEST, or None (the scene's twin where it ships one)
    reference: Path | str | None = None
    columns: list | None = None

    def configurations(self) -> list[dict]:
        """Every point's settings: the grid's product, then the explicit points."""
        keys = list(self.grid)
        product = [dict(zip(keys, values)) for values in
                   itertools.product(*(self.grid[k] for k in keys))] if keys else []
        return [{**p} for p in product + list(self.points)]


def read_sweep_file(path) -> Sweep:
    """A sweep file (JSON): ``{"grid": {"step": [...], ...}, "points": [{...}],
    "settings": {"stop": 1.0}, "reference": "twin.csv", "columns": [...]}``."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as error:
        raise InputError(f"{path}: cannot read the sweep file: {error}") from None
    unknown = set(data) - {"grid", "points", "settings", "reference", "columns"}
    if unknown:
        raise InputError(f"{path}: unknown keys {', '.join(sorted(unknown))} (known: grid, "
                         "points, settings, reference, columns)")
    reference = data.get("reference")
    if reference and reference != TIGHTEST:
        reference = path.parent / reference
    return Sweep(dict(data.get("grid", {})), list(data.get("points", [])),
                 dict(data.get("settings", {})), reference, data.get("columns"))


def check(sweep: Sweep) -> None:
    """Every swept name is a setting and every value valid for it (InputError listing
    every problem, before any point runs)."""
    problems = []
    pairs = [(name, value) for name, values in sweep.grid.items() for value in values]
    pairs += [pair for settings in [sweep.fixed] + sweep.points for pair in settings.items()]
    for name, value in pairs:
        if name not in SETTINGS:
            problems.append(f"sweep: unknown setting '{name}' (known: "
                            f"{', '.join(SETTINGS)})")
            continue
        _, problem = convert(SETTINGS[name], value, f"sweep: {name}")
        if problem:
            problems.append(problem)
    if not sweep.configurations():
        problems.append("sweep: no points (give at least one setting with values)")
    if problems:
        raise InputError(list(dict.fromkeys(problems)))


def tightest(configurations: list[dict]) -> int:
    """Index of the tightest point: iterative, the smallest step, the smallest
    tolerance (the default reference of a sweep)."""
    def key(k):
        settings = configurations[k]
        return (settings.get("coupling", "iterative") != "iterative",
                float(settings.get("step", 0.0) or 0.0),
                float(settings.get("tolerance", 0.0) or 0.0))
    return min(range(len(configurations)), key=key)


def error_against(columns: dict, reference: dict, chosen=None) -> float:
    """Largest difference over the compared columns, relative to each column's peak in
    the reference (the reference interpolated onto the point's times)."""
    names = chosen or [n for n in columns if n != "time" and n in reference
                       and columns[n].dtype != object]
    missing = [n for n in names if n not in columns or n not in reference]
    if missing:
        raise InputError(f"sweep: columns not in both the run and the reference: "
                         f"{', '.join(missing)}")
    times, rows, reference_rows = shared_times(columns["time"], reference["time"])
    worst = 0.0
    for name in names:
        if reference_rows is None:
            expected = np.interp(times, reference["time"], reference[name])
        else:
            expected = reference[name][reference_rows]
        peak = float(np.max(np.abs(reference[name]))) or 1.0
        with np.errstate(invalid="ignore"):
            gap = float(np.max(np.abs(columns[name][rows] - expected), initial=0.0))
        worst = max(worst, gap / peak if math.isfinite(gap) else math.inf)
    return worst


def shared_times(times, reference_times):
    """Where to compare a run with a reference: the run's times that are also the
    reference's (both grids multiples of a common step: no interpolation error, which
    at a step much coarser than the motion would swamp what is measured), else every
    run time inside the reference's span, the reference interpolated there.  Returns
    (times, the run's rows, the reference's rows or None)."""
    span = max(abs(float(reference_times[-1])), abs(float(times[-1])), 1.0)
    nearest = np.clip(np.searchsorted(reference_times, times), 1, len(reference_times) - 1)
    left = reference_times[nearest - 1]
    nearest = np.where(np.abs(times - left) <= np.abs(reference_times[nearest] - times),
                       nearest - 1, nearest)
    matched = np.abs(reference_times[nearest] - times) <= 1e-9 * span
    if np.count_nonzero(matched) > 1:
        rows = np.flatnonzero(matched)
        return times[rows], rows, nearest[rows]
    rows = np.flatnonzero((times >= reference_times[0] - 1e-12)
                          & (times <= reference_times[-1] + 1e-12))
    return times[rows], rows, None


def mark_pareto(points: list[Point]) -> None:
    """Mark the stable points no other stable point beats in both error and time."""
    stable = [p for p in points if p.stable and math.isfinite(p.error)]
    for p in stable:
        p.pareto = not any(q is not p and q.error <= p.error and q.wall_seconds <= p.wall_seconds
                           and (q.error < p.error or q.wall_seconds < p.wall_seconds)
                           for q in stable)


def cheapest(points: list[Point], target: float) -> Point | None:
    """The fastest stable point whose error is at most ``target``."""
    meeting = [p for p in points if p.stable and p.error <= target]
    return min(meeting, key=lambda p: p.wall_seconds) if meeting else None


def command_line(scene, point: Point, fixed: dict) -> str:
    """The ``dsim run`` command of a point."""
    words = ["dsim", "run", str(scene)]
    for key, value in {**fixed, **point.settings}.items():
        words += [SETTINGS[key].option, str(value)]
    return " ".join(shlex.quote(w) for w in words)


class SweepTable:
    """``sweep.csv``: one whole row per finished point, as it finishes."""

    def __init__(self, path: Path, names: list[str], inputs):
        self.names = names
        self.output = OutputFile(path, inputs)
        self.output.open()
        self.output.append((",".join(list(names) + list(MEASURES)) + "\n").encode())

    def add(self, point: Point) -> None:
        cells = [str(point.settings.get(n, "")) for n in self.names]
        cells += [point.status, str(point.stable).lower(), repr(point.error),
                  repr(point.wall_seconds), repr(point.iterations_per_step),
                  repr(point.do_steps_per_fmu_step), str(point.lambda_refreshes),
                  str(point.steps), json.dumps(point.message)]
        self.output.append((",".join(cells) + "\n").encode(), separator=b"\n")

    def close(self) -> None:
        self.output.commit()


def markdown(points: list[Point], names: list[str], reference: str) -> str:
    """The sweep's table, Pareto points marked."""
    lines = [f"Reference: {reference}. Error: the largest difference of any compared column "
             "over the run, relative to that column's peak in the reference.", "",
             "| " + " | ".join(names) + " | status | error | wall (s) | iterations per step "
             "| doSteps per FMU per step | Pareto |",
             "|" + "---|" * (len(names) + 6)]
    for p in points:
        lines.append("| " + " | ".join(str(p.settings.get(n, "")) for n in names)
                     + f" | {p.status}{'' if p.stable else ' (unstable)'} | {p.error:.2e} | "
                     f"{p.wall_seconds:.3f} | {p.iterations_per_step:.2f} | "
                     f"{p.do_steps_per_fmu_step:.2f} | {'yes' if p.pareto else ''} |")
    return "\n".join(lines) + "\n"


def plot_points(points: list[Point], title: str) -> bytes:
    """Error against wall time, log-log, the Pareto front joined; PNG bytes."""
    import io

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from master.results import save_figure

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
    image = io.BytesIO()
    save_figure(figure, image)
    return image.getvalue()


def run_sweep(scene, sweep: Sweep, out: Path, progress=None,
              bars: bool = False) -> tuple[list[Point], int | None]:
    """Run every point, writing ``out/sweep.csv`` as points finish, then
    ``out/sweep.md`` and ``out/sweep.png``; returns the points and the signal that
    interrupted the sweep, if one did (SIGINT or SIGTERM end the running points after
    their current step, and the sweep after them, with everything written).
    ``progress(done, total, point)`` is called as points finish; ``bars`` shows each
    point's progress bar on a terminal (points run one after the other).

    With the setting ``backend`` fixed to ``ray`` the points run side by side, one per
    Ray worker (each in-process inside its worker: master/sweep_ray.py), on a local
    Ray instance or the cluster at ``address``."""
    from master.api import prepare
    from master.results import read_columns

    check(sweep)
    configurations = sweep.configurations()
    names = list(dict.fromkeys(k for c in configurations for k in c))
    plan = prepare(scene, **sweep.fixed)  # bad input before any point runs
    reference_file = (None if sweep.reference == TIGHTEST
                      else sweep.reference or plan.scene.reference)
    reference_index = None if reference_file else tightest(configurations)
    if reference_index is not None:  # the tightest run first: the others compare with it
        configurations.insert(0, configurations.pop(reference_index))
    out = Path(out)
    table = SweepTable(out / "sweep.csv", names, plan.inputs)
    reference = read_columns(reference_file) if reference_file else None
    label = ("the scene's monolithic twin (resources/reference.csv)"
             if reference_file and not sweep.reference else
             str(reference_file) if reference_file else "the tightest point")
    points: dict[int, Point] = {}
    interrupted = None
    # measured in configuration order until there is a reference (the first point that
    # completes, unless the user gave one); in any order after that
    finished: dict[int, PointRun] = {}
    order = iter(range(len(configurations)))
    waiting = next(order)

    def measure(k: int, run) -> None:
        nonlocal reference, label, interrupted
        if reference is None and run.result is not None and run.result.ok:
            reference = run.result.signals
            label = f"the tightest point ({Point(configurations[k]).label})"
        point = measured(Point(configurations[k]), run, reference, sweep.columns)
        if point.status == "interrupted" and run.result.signal:
            interrupted = run.result.signal
        points[k] = point
        table.add(point)
        if progress:
            progress(len(points), len(configurations), point)

    def finish(k: int, run) -> None:
        nonlocal waiting
        finished[k] = run
        while reference is None and waiting in finished:
            measure(waiting, finished.pop(waiting))
            waiting = next(order, None)
        if reference is not None:
            for key in sorted(finished):
                measure(key, finished.pop(key))

    parallel = sweep.fixed.get("backend") == "ray"
    try:
        if parallel:
            from master.sweep_ray import run_points
            run_points(scene, configurations, sweep.fixed, out, plan.inputs, finish)
        else:
            for k, settings in enumerate(configurations):
                finish(k, run_point(scene, {**sweep.fixed, **settings},
                                    out / f"point_{k + 1:03d}.csv", bars))
                if interrupted:
                    break
        for k in sorted(finished):  # no point completed: nothing to compare with
            measure(k, finished.pop(k))
    finally:
        table.close()
        ordered = [points[k] for k in sorted(points)]
        mark_pareto(ordered)
        write_whole(out / "sweep.md", markdown(ordered, names, label).encode(), plan.inputs)
        if ordered:
            write_whole(out / "sweep.png", plot_points(ordered, plan.scene.name), plan.inputs)
    return [points[k] for k in sorted(points)], interrupted


@dataclass
class PointRun:
    """How one point ran: its :class:`~master.results.RunResult` (None for bad input),
    the problems of bad input, wall seconds and where its results are."""

    result: object = None
    problems: list = field(default_factory=list)
    wall_seconds: float = math.nan
    results: Path | None = None


def run_point(scene, settings: dict, results: Path, bars: bool = False) -> PointRun:
    """Run one point in this process, its results CSV (and statistics) at ``results``
    (``bars``: its progress bar on a terminal)."""
    from master.api import simulate

    start = clock.perf_counter()
    try:
        result = simulate(scene, out=results, progress=bars, **settings)
    except InputError as error:
        return PointRun(problems=list(error.problems))
    return PointRun(result, wall_seconds=clock.perf_counter() - start, results=results)


def measured(point: Point, run: PointRun, reference, columns) -> Point:
    """``point`` with what its run measured (the error against ``reference``, if any)."""
    if run.result is None:
        point.status, point.message = "bad input", "; ".join(run.problems)
        return point
    result = run.result
    point.wall_seconds = run.wall_seconds
    point.status, point.message = result.status, result.message
    stats = result.statistics
    if not stats:  # its worker died: nothing was measured
        return point
    point.steps = result.steps
    point.iterations_per_step = stats["iterations"]["mean_per_step"]
    point.do_steps_per_fmu_step = (stats["do_steps_per_step"]
                                   / max(len(stats["components"]), 1))
    point.lambda_refreshes = stats["lambda_refreshes"]
    point.results = run.results
    if reference is not None and result.steps:
        point.error = error_against(result.signals, reference, columns)
    point.stable = result.ok and point.error <= 1.0
    return point
