"""``dsim sweep``: a scene run at every point of a design, each point measured.

A sweep runs a scene at every point of a grid of settings (macro step, tolerance,
coupling, predictor, refresh policy, parameter set: anything ``dsim.simulate``
takes) or of a design of experiments over settings and model parameters
(:mod:`dsim.master.sweeps.design`: full-factorial grids, Latin hypercube, Sobol', Halton, Saltelli,
Morris), and measures each: the error against a reference (a results CSV the user
gives, else the monolithic twin's results a scene ships as ``resources/reference.csv``,
else dsim's reference run: the strong coupling with an error-controlled step at a tenth
of the tightest point's tolerance, or, where that cannot run, the sweep's tightest
run; none by default where model parameters vary, since a twin at the nominal
parameters is no reference for other ones), the quantities of
interest asked for (:mod:`dsim.master.sweeps.kpi`), wall time, iterations and doSteps per step,
and whether it stayed stable.  Each finished point is a whole row of ``sweep.csv`` at
once, so an interrupted or killed sweep keeps them, and a rerun into the same folder
runs only the points missing (:mod:`dsim.master.sweeps.folder`).  At the end (or the
interrupt) it writes ``sweep.md`` (a table), ``sweep.png`` (error against wall time,
the Pareto front marked), and for KPIs ``kpis.png``, ``scatter.png`` and the
sensitivity indices (:mod:`dsim.master.sweeps.sensitivity`).
"""
from __future__ import annotations

import difflib
import json
import math
import shlex
import time as clock
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dsim.master.api import prepare, simulate
from dsim.master.errors import InputError
from dsim.master.recording.results import read_columns, statistics_path
from dsim.master.running.step_control import DEFAULT_TOLERANCE
from dsim.master.settings import SETTINGS, convert_setting, is_auto
from dsim.master.sweeps.design import SALIB, Design, Factor, parse_vary, split
from dsim.master.sweeps.folder import open_folder, spec, write_outputs
from dsim.master.sweeps.kpi import parse_all, unresolved
from dsim.master.sweeps.plots import plot_points  # noqa: F401  (its place before the split)
from dsim.master.sweeps.point import PointRun, ended, keep_files, keywords, run_in_worker
from dsim.master.running.backends.ray import run_points
from dsim.master.sweeps.table import MEASURES, Point, SweepTable, markdown  # noqa: F401

#: the reference named to measure against the sweep's tightest point even where the
#: scene ships its monolithic twin
TIGHTEST = "tightest"
#: the error tolerance of the reference run as a share of the tightest point's (of
#: DEFAULT_TOLERANCE where that point steps at a fixed step)
REFERENCE_SHARE = 0.1
#: the reference run's results in the sweep's folder (under a temporary name while it
#: runs: the file is there only when the run completed)
REFERENCE_FILE, REFERENCE_RUNNING = "reference.csv", "reference.running.csv"
#: the keys of a sweep file
FILE_KEYS = ("grid", "points", "settings", "reference", "columns", "vary", "design",
             "samples", "seed", "kpis")


@dataclass
class Sweep:
    """What to sweep: a grid (setting -> values), factors to vary (``vary``: settings or
    model parameters, :class:`~dsim.master.sweeps.design.Factor`) by a design (``design``: grid,
    lhs, sobol, halton, saltelli, morris; ``samples`` and ``seed`` of a sampled one) or
    explicit points, settings that hold for every point, the KPIs (``kpis``: ``--kpi``
    texts), the reference and the compared columns."""

    grid: dict = field(default_factory=dict)
    points: list = field(default_factory=list)
    fixed: dict = field(default_factory=dict)
    #: a results CSV, TIGHTEST, or None (the scene's twin where it ships one)
    reference: Path | str | None = None
    columns: list | None = None
    vary: list = field(default_factory=list)
    design: str = "grid"
    samples: int | None = None
    seed: int | None = None
    kpis: list = field(default_factory=list)
    #: folders whose files the scene may name besides its own (``--allow-outside``:
    #: every point's run trusts them; docs/security.md)
    allow_outside: tuple = ()
    #: a scenario every point's run takes (``--scenario``: a path, or the
    #: :class:`~dsim.master.reading.scenario_files.Scenario` read from one), or None
    scenario: object = None
    #: when the scenario's events take effect (``--events``: point or exact)
    events: str = "point"
    #: an input table every point's run takes (``--input``: a path, or the
    #: :class:`~dsim.master.reading.input_tables.Table` read from one), or None
    inputs: object = None
    #: the checkpoint every point's run starts from (``--from``: a path, or the
    #: :class:`~dsim.master.reading.checkpoint_files.Checkpoint` read from one), or None
    start_from: object = None

    def plan(self) -> Design:
        """The design: the grid's settings as lists, then the varied factors."""
        factors = [Factor(name, "list", tuple(values)) for name, values in self.grid.items()]
        return Design(factors + list(self.vary), self.design, self.samples, self.seed)

    def configurations(self) -> list[dict]:
        """Every point's settings and parameters: the design's points, then the
        explicit points."""
        return [{**p} for p in self.plan().configurations() + list(self.points)]

    @property
    def varies_parameters(self) -> bool:
        """Whether any point sets a model parameter (a dotted name)."""
        names = [*self.fixed, *self.grid, *(f.name for f in self.vary),
                 *(name for point in self.points for name in point)]
        return any("." in name for name in names)


def read_sweep_file(path) -> Sweep:
    """A sweep file (JSON): ``{"grid": {"step": [...], ...}, "points": [{...}],
    "settings": {"stop": 1.0}, "reference": "twin.csv", "columns": [...],
    "vary": ["left.k=1e3:1e5:log"], "design": "lhs", "samples": 64, "seed": 1,
    "kpis": ["max(right.x[2])"]}``."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as error:
        raise InputError(f"{path}: cannot read the sweep file: {error}") from None
    if not isinstance(data, dict):
        raise InputError(f"{path}: a sweep file is a JSON object (keys {', '.join(FILE_KEYS)})")
    unknown = set(data) - set(FILE_KEYS)
    if unknown:
        raise InputError(f"{path}: unknown keys {', '.join(sorted(unknown))} (known: "
                         f"{', '.join(FILE_KEYS)})")
    return sweep_of(data, path.parent)


def sweep_of(data: dict, folder: Path | None = None) -> Sweep:
    """The :class:`Sweep` of a sweep file's object (keys :data:`FILE_KEYS`, not checked
    here), its reference path taken relative to ``folder`` where one is given."""
    reference = data.get("reference")
    if reference and reference != TIGHTEST:
        reference = folder / reference if folder is not None else Path(reference)
    design = str(data.get("design", "grid"))
    vary = [parse_vary(str(v), design != "grid") for v in data.get("vary", [])]
    return Sweep(dict(data.get("grid", {})), list(data.get("points", [])),
                 dict(data.get("settings", {})), reference, data.get("columns"), vary,
                 design, data.get("samples"), data.get("seed"), list(data.get("kpis", [])))


def check(sweep: Sweep) -> None:
    """Every swept name is a setting or a dotted model parameter, every setting's value
    valid for it, the design and the KPIs well formed (InputError listing every
    problem, before any point runs; parameter values are checked by the run's own
    checks against the FMUs, also before any point runs)."""
    problems = []
    pairs = [(name, None) for name in sweep.grid]  # their values: the design's check
    pairs += [pair for settings in [sweep.fixed] + sweep.points for pair in settings.items()]
    for name, value in pairs:
        if "." in name:
            continue
        if name not in SETTINGS:
            problems.append(f"sweep: unknown setting '{name}' (known: "
                            f"{', '.join(SETTINGS)}; a model parameter is "
                            "COMPONENT.VARIABLE)")
            continue
        _, problem = convert_setting(name, value, f"sweep: {name}") if value is not None \
            else (None, None)
        if problem:
            problems.append(problem)
    unknown = {name for name in sweep.grid if name not in SETTINGS and "." not in name}
    for problem_source in (Design([f for f in sweep.plan().factors if f.name not in unknown],
                                  sweep.design, sweep.samples, sweep.seed).check,
                           lambda: parse_all(sweep.kpis)):
        try:
            problem_source()
        except InputError as error:
            problems += error.problems
    if not problems and not sweep.configurations():
        problems.append("sweep: no points (give at least one setting with values, or "
                        "--vary NAME=SPEC)")
    if problems:
        raise InputError(list(dict.fromkeys(problems)))


#: how close each coupling comes, best first (a sweep's tightest point is of the first)
COUPLING_RANK = {"strong": 0, "iterative": 1}


def tightest(configurations: list[dict]) -> int:
    """Index of the tightest point (the default reference of a sweep): the strong
    coupling before the iterative one before the others (which exchange connections
    once per step), an error-controlled step (step auto) at the smallest error
    tolerance before any fixed step, then the smallest step and tolerance."""
    def key(k):
        settings = configurations[k]
        step = settings.get("step", 0.0) or 0.0
        auto = is_auto("step", step)
        return (COUPLING_RANK.get(settings.get("coupling", "iterative"), 2),
                not auto,
                float(settings.get("error_tolerance") or DEFAULT_TOLERANCE) if auto else 0.0,
                0.0 if auto else float(step),
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


def command_line(scene, point: Point, fixed: dict, allow_outside=(), scenario=None,
                 inputs=None, start_from=None, events: str = "point") -> str:
    """The ``dsim run`` command of a point (``allow_outside``: the sweep's trusted
    folders; ``scenario``: its scenario, its events taking effect as ``events`` says;
    ``inputs``: its input table; ``start_from``: the checkpoint its run starts from)."""
    words = ["dsim", "run", str(scene)]
    settings, parameters = split({**fixed, **point.settings})
    for key, value in settings.items():
        words += [SETTINGS[key].option, str(value)]
    for key, value in parameters.items():
        words += ["--set", f"{key}={value}"]
    for folder in allow_outside:
        words += ["--allow-outside", str(folder)]
    if scenario is not None:
        words += ["--scenario", str(getattr(scenario, "file", scenario))]
        if events != "point":
            words += ["--events", events]
    if inputs is not None:
        words += ["--input", str(getattr(inputs, "file", None) or getattr(inputs, "source",
                                                                            inputs))]
    if start_from is not None:
        words += ["--from", str(getattr(start_from, "folder", start_from))]
    return " ".join(shlex.quote(w) for w in words)


def trusted(sweep: Sweep) -> dict:
    """The keywords of ``dsim.simulate``/``prepare`` every point's run shares besides its
    settings: the folders the sweep's scene may name files in (``allow_outside``) and
    its scenario, its input table and the checkpoint its points start from ({} when it
    has none of them)."""
    shared = {"allow_outside": list(sweep.allow_outside)} if sweep.allow_outside else {}
    if sweep.scenario is not None:
        shared["scenario"] = sweep.scenario
        if sweep.events != "point":
            shared["events"] = sweep.events
    if sweep.inputs is not None:
        shared["inputs"] = sweep.inputs
    if sweep.start_from is not None:
        shared["start_from"] = sweep.start_from
    return shared


def run_point(scene, settings: dict, results: Path, bars: bool = False,
              where: dict | None = None) -> PointRun:
    """Run one point (settings and dotted model parameters) in this process, its
    results CSV (and statistics) at ``results`` (``bars``: its progress bar on a
    terminal; ``where``: :func:`trusted`'s keywords)."""
    start = clock.perf_counter()
    try:
        result = simulate(scene, out=results, progress=bars, **keywords(settings),
                          **(where or {}))
    except InputError as error:
        return PointRun(problems=list(error.problems))
    return PointRun(result, wall_seconds=clock.perf_counter() - start, results=results)


def measured(point: Point, run: PointRun, reference, columns, kpis=()) -> Point:
    """``point`` with what its run measured: the error against ``reference`` (if any)
    and the value of each of ``kpis`` (:class:`~dsim.master.sweeps.kpi.Kpi`; nan unless the run
    completed, and where the KPI has none, said in the message)."""
    point.kpis = {k.label: math.nan for k in kpis}
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
    point.stable = result.ok and (point.error <= 1.0 if reference is not None else True)
    if result.ok:
        notes = []
        for kpi in kpis:
            try:
                point.kpis[kpi.label] = kpi.value(result.signals)
            except ValueError as error:
                notes.append(str(error))
        point.message = "; ".join([point.message] * bool(point.message) + notes)
    return point


def check_parameters(scene, sweep: Sweep, configurations: list[dict]) -> None:
    """Every value a varied model parameter takes at the ends of its range (or in its
    list) checked against the FMUs, with every other quantity at the first point's
    values: InputError listing every problem, before any point runs."""
    if not configurations:
        return
    base = {**sweep.fixed, **configurations[0]}
    trials = []
    for factor in sweep.plan().factors:
        if factor.is_parameter:
            values = factor.values if factor.kind == "list" else (factor.low, factor.high)
            trials += [{**base, factor.name: v} for v in values]
    trials += [{**sweep.fixed, **p} for p in sweep.points if any("." in k for k in p)]
    problems = []
    for trial in trials:
        try:
            prepare(scene, load_libraries=False, **keywords(trial), **trusted(sweep))
        except InputError as error:
            problems += error.problems
    if problems:
        raise InputError(list(dict.fromkeys(problems)))


def recorded_columns(plan) -> list[str]:
    """The columns a run of ``plan`` records: its outputs and joint forces (those its
    ``outputs`` choose), then its String outputs (``time`` first)."""
    layout, _ = plan.assemble()
    numbers = list(plan.columns) + list(layout.labels)
    if plan.selected is not None:
        numbers = [numbers[i] for i in plan.selected]
    return ["time"] + numbers + list(plan.text_columns)


def unrecorded_columns(sweep: Sweep, names) -> list[str]:
    """One problem per KPI of ``sweep`` that matches none of the recorded columns
    ``names`` (or whose ``final`` matches several), and per compared column
    (``columns``) not among them, each naming the closest: what ``dsim sweep`` and
    ``dsim serve``'s sweep form refuse before the first point."""
    names = list(names)
    problems = unresolved(parse_all(sweep.kpis), names)
    for column in sweep.columns or ():
        if column not in names:
            close = difflib.get_close_matches(column, names[:50000], n=3, cutoff=0.4)
            problems.append(f"--columns: the scene records no column '{column}'"
                            + (f" (closest: {', '.join(close)})" if close else ""))
    return problems


def check_columns(plan, sweep: Sweep) -> None:
    """Every KPI's columns and every compared column among those a run of ``plan``
    records (:func:`unrecorded_columns`): InputError before any point runs (a
    misspelled column would otherwise be found only in each point's row)."""
    problems = unrecorded_columns(sweep, recorded_columns(plan))
    if problems:
        raise InputError(problems)


def _reference_choice(sweep: Sweep, plan) -> tuple[Path | None, bool]:
    """The results file the points are measured against, and whether it is instead the
    sweep's tightest point: the sweep's own reference, else the twin the scene ships
    (at nominal parameters only), else the tightest point (not for SALib's designs,
    whose points keep their order)."""
    reference_file, use_tightest = None, False
    if sweep.reference == TIGHTEST:
        use_tightest = True
    elif sweep.reference is not None:
        reference_file = Path(sweep.reference)
    elif not sweep.varies_parameters:  # a twin at nominal parameters: no reference else
        reference_file = plan.scene.reference
        use_tightest = reference_file is None
    return reference_file, use_tightest and sweep.design not in SALIB


def _reference(sweep: Sweep, reference_file, use_tightest: bool, points: dict):
    """The reference's columns (None until the tightest point has run) and how the
    tables name it; a resumed sweep's tightest point is its first completed one."""
    reference = read_columns(reference_file) if reference_file else None
    label = ("the scene's monolithic twin (resources/reference.csv)"
             if reference_file and not sweep.reference else
             str(reference_file) if reference_file else "the tightest point")
    if use_tightest:  # resumed: the first completed point in order was the reference
        first = next((points[k] for k in sorted(points) if points[k].status == "completed"),
                     None)
        if first is not None and first.results is not None:
            reference = read_columns(first.results)
            label = f"the tightest point ({Point(first.settings).label})"
    return reference, label


def reference_settings(configuration: dict, fixed: dict) -> dict | None:
    """The reference run's settings beside the tightest point's ``configuration`` (with
    ``fixed``, the settings of every point): the most accurate run dsim can make of the
    scene, the strong coupling with an error-controlled step (step auto) at
    :data:`REFERENCE_SHARE` of the point's error tolerance (of DEFAULT_TOLERANCE where it
    steps at a fixed step, recording a row at each of its steps); None where the point
    is such a run already."""
    settings = {**fixed, **configuration}
    step = settings.get("step")
    auto = step is not None and is_auto("step", step)
    if auto and settings.get("coupling") == "strong":
        return None
    tolerance = float(settings.get("error_tolerance") or DEFAULT_TOLERANCE) if auto else \
        DEFAULT_TOLERANCE
    chosen = {"coupling": "strong", "step": "auto",
              "error_tolerance": tolerance * REFERENCE_SHARE}
    chosen.update((k, v) for k, v in configuration.items() if k not in chosen)
    if step is not None and not auto and "output_interval" not in settings:
        chosen["output_interval"] = step
    return chosen


def _reference_run(scene, sweep: Sweep, chosen: dict, out: Path, bars: bool):
    """The reference run of ``chosen`` settings (:func:`reference_settings`), kept in
    ``out`` (a rerun of the sweep reads it back): its columns, or None with why not,
    and the signal that interrupted it, if one did."""
    kept = out / REFERENCE_FILE
    if kept.is_file():
        return read_columns(kept), "", None
    running = out / REFERENCE_RUNNING
    for stale in (running, statistics_path(running)):  # a killed rerun's
        stale.unlink(missing_ok=True)
    run = run_point(scene, {**sweep.fixed, **chosen}, running, bars, trusted(sweep))
    if run.result is None:
        return None, "; ".join(run.problems), None
    if not run.result.ok:
        return None, run.result.message, run.result.signal
    statistics_path(running).replace(statistics_path(kept))
    running.replace(kept)
    return read_columns(kept), "", None


def run_sweep(scene, sweep: Sweep, out: Path, progress=None, bars: bool = False,
              resumed=None, said=None) -> tuple[list[Point], int | None]:
    """Run every point not already finished in ``out``, writing ``out/sweep.csv`` as
    points finish, then ``out/sweep.md``, ``sweep.png`` and the KPIs' figures and
    sensitivity (:func:`dsim.master.sweeps.folder.write_outputs`); returns every point of the
    folder and the signal that interrupted the sweep, if one did (SIGINT or SIGTERM
    end the running points after their current step, and the sweep after them, with
    everything written).  ``progress(done, total, point)`` is called as points finish;
    ``resumed(finished, total)`` once, before any point runs, when the folder already
    held finished points of this sweep; ``said(line)`` with what the sweep measures
    against where it chose it itself; ``bars`` shows each point's progress bar on a
    terminal (points run one after the other).

    With the setting ``backend`` fixed to ``ray`` the points run side by side, one per
    Ray worker (each in-process inside its worker: master/running/backends/ray/points.py), on a local
    Ray instance or the cluster at ``address``."""

    check(sweep)
    kpis = parse_all(sweep.kpis)
    labels = [k.label for k in kpis]
    configurations = sweep.configurations()
    names = list(dict.fromkeys(k for c in configurations for k in c))
    # bad input before any point runs
    plan = prepare(scene, **keywords(sweep.fixed), **trusted(sweep))
    check_parameters(scene, sweep, configurations)
    check_columns(plan, sweep)
    reference_file, use_tightest = _reference_choice(sweep, plan)
    chosen = None
    if use_tightest:  # the tightest run first: the others compare with it
        configurations.insert(0, configurations.pop(tightest(configurations)))
        if sweep.reference is None:  # not asked for the tightest point: dsim's best run
            chosen = reference_settings(configurations[0], sweep.fixed)
    out = Path(out)
    configurations, points = open_folder(out, spec(scene, sweep, kpis), configurations,
                                         plan.inputs)
    total = len(configurations)
    if points and resumed:
        resumed(len(points), total)
    table = SweepTable(out / "sweep.csv", names, plan.inputs, labels)
    for k in sorted(points):
        table.add(points[k])
    interrupted = None
    if chosen is not None:
        columns, why, interrupted = _reference_run(scene, sweep, chosen, out, bars)
        if columns is not None:
            use_tightest = False
        elif said and not interrupted:
            said(f"the reference run ({Point(chosen).label}) did not complete: {why}; "
                 "measuring against the tightest point instead")
    reference, label = _reference(sweep, reference_file, use_tightest, points)
    if chosen is not None and not use_tightest:
        reference = columns
        label = f"dsim's reference run ({Point(chosen).label}, {REFERENCE_FILE})"
    if said and (chosen is not None or use_tightest) and not interrupted:
        said(f"measured against {label}")
    measuring = reference_file is not None or use_tightest or reference is not None
    todo = [] if interrupted else [k for k in range(total) if k not in points]
    # measured in configuration order until there is a reference (the first point that
    # completes, where it is the tightest); in any order after that
    finished: dict[int, PointRun] = {}
    order = iter(todo)
    waiting = next(order, None)

    def measure(k: int, run) -> None:
        nonlocal reference, label, interrupted
        if measuring and reference is None and run.result is not None and run.result.ok:
            reference = run.result.signals
            label = f"the tightest point ({Point(configurations[k]).label})"
        point = measured(Point(dict(configurations[k]), index=k + 1), run,
                         reference if measuring else None, sweep.columns, kpis)
        if point.status == "interrupted" and run.result.signal:
            interrupted = run.result.signal
        points[k] = point
        table.add(point)
        if progress:
            progress(len(points), total, point)

    def finish(k: int, run) -> None:
        nonlocal waiting
        finished[k] = run
        while measuring and reference is None and waiting in finished:
            measure(waiting, finished.pop(waiting))
            waiting = next(order, None)
        if reference is not None or not measuring:
            for key in sorted(finished):
                measure(key, finished.pop(key))

    parallel = sweep.fixed.get("backend") == "ray"
    try:
        if parallel:
            # (the trusted folders travel with the settings: each point's run takes them)
            run_points(scene, [(k, configurations[k]) for k in todo],
                       {**sweep.fixed, **trusted(sweep)},
                       lambda k, run, files: finish(k, keep_files(
                           run, files, out / f"point_{k + 1:03d}.csv", plan.inputs)),
                       run_in_worker, ended)
        else:
            for k in todo:
                finish(k, run_point(scene, {**sweep.fixed, **configurations[k]},
                                    out / f"point_{k + 1:03d}.csv", bars, trusted(sweep)))
                if interrupted:
                    break
        for k in sorted(finished):  # no point completed: nothing to compare with
            measure(k, finished.pop(k))
    finally:
        table.close()
        ordered = [points[k] for k in sorted(points)]
        mark_pareto(ordered)
        write_outputs(out, ordered, sweep, names, labels, label, plan.scene.name,
                      plan.inputs, total, plan=plan)
    return ordered, interrupted
