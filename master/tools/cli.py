"""``dsim``: run, inspect and build glued co-simulations (a thin layer over the
Python API of :mod:`dsim.master.api`).

Exit codes: 0 success, 1 the simulation failed, 2 bad input or usage,
128 + signal when interrupted (SIGINT: 130, SIGTERM: 143).
"""
from __future__ import annotations

import argparse
import functools
import sys
from importlib.metadata import entry_points
from pathlib import Path

from dsim.master import __version__
from dsim.master.api import simulate
from dsim.master.checks.compare import band_origin, compare_files
from dsim.master.checks.kernel_study import choose_kernels
from dsim.master.checks.regress import (KernelChoice, find_cases, junit_xml, read_noise, run_cases,
                                        summary_lines)
from dsim.master.checks.validate import validate
from dsim.master.errors import InputError, SimulationError
from dsim.master.planning.parameters import JOINT_COEFFICIENTS
from dsim.master.planning.scenario import EVENT_MODES
from dsim.master.reading.parameter_input import given_parameters
from dsim.master.reading.input_tables import read_table
from dsim.master.reading.scenario_files import read_scenario
from dsim.master.reading.checkpoint_files import find_checkpoint
from dsim.master.recording.checkpoints import checkpoints_beside
from dsim.master.recording.results import statistics_path
from dsim.master.recording.observers import ProgressBar
from dsim.master.running.backends import log_lines
from dsim.master.running.timeline import span_note
from dsim.master.settings import SETTINGS, choices
from dsim.master.sweeps.design import DESIGNS, parse_vary
from dsim.master.sweeps.folder import read_sensitivity
from dsim.master.running.backends.ray import HeadLost
from dsim.master.sweeps.sensitivity import (SPANS_ZERO, SPANS_ZERO_TEXT, Index,
                                            cautions, ranking_text)
from dsim.master.sweeps.sweep import (Sweep, TIGHTEST, cheapest, command_line, read_sweep_file,
                                      run_sweep)
from dsim.master.sweeps.table import STATES, count_states, state
from dsim.master.tools import supervised
from dsim.master.tools.info import scene_info
from dsim.master.tools.plot import overlay_files
from dsim.master.tools.process_exit import end_process


def _work_line(data: dict, components: int) -> str:
    """The summary's line of what each step took, only what applies: Newton iterations
    and Lambda (the interface flexibility or the iterated connections' Jacobian)
    refreshes for a coupling that iterates, not the causal one; the algebraic loops'
    corrections where the scene has loops; the doSteps per FMU."""
    parts = []
    if data["coupling"] != "causal":
        parts += [f"{data['iterations']['mean_per_step']:.2f} per step "
                  f"(max {data['iterations']['max_per_step']})",
                  f"Lambda refreshes {data['lambda_refreshes']}"]
    loops = data.get("algebraic_loops")
    if loops:
        parts.append(f"algebraic loops {loops['corrections']} corrections "
                     f"({loops['jacobians']} Jacobians)")
    parts.append(f"doSteps per FMU per step {data['do_steps_per_step'] / components:.2f}")
    label = "steps" if data["coupling"] == "causal" else "iterations"
    return f"{label:<12}" + ", ".join(parts)


def _summary(result, plot: Path | None) -> str:
    data = result.statistics
    components = max(len(data["components"]), 1)
    uneven = span_note(data["start_time"], data["stop_time"], data["master"]["step"])
    lines = [
        f"scene       {data['scene']}  ({data['file']}), {data['coupling']} coupling, "
        f"{data['backend']} backend",
        f"time        {data['start_time']:g} .. {data['stop_time']:g} s, "
        f"step {data['master']['step']:g} s, {data['steps']} steps"
        + (f" ({uneven.split(': ', 1)[1]})" if uneven else "")
        + (f" (ended by {data['ended_by']['component']} at t = "
           f"{data['ended_by']['time']:g} s; the last row at {data['time_reached']:g} s)"
           if data.get("ended_by") else ""),
        _work_line(data, components),
        f"wall time   {data['wall_seconds']:.3f} s "
        f"({data['seconds_in_fmus']:.3f} s inside FMUs)",
    ]
    held = data.get("coupling_error")
    if held and held["connection"]:
        lines.insert(2, f"coupling    error estimate: a connected value off by up to "
                     f"{100 * held['largest']:.2g} % of its range within a step "
                     f"({held['connection']}; statistics: coupling_error)")
    control = data.get("step_control")
    if control and control["accepted_steps"]:
        lines.insert(2, f"step auto   E {control['error_tolerance']:g}: "
                     f"{control['accepted_steps']} steps accepted, "
                     f"{control['rejected_steps']} taken again; "
                     f"h {control['smallest_step']:.3g} .. {control['largest_step']:.3g} s "
                     f"(mean {control['mean_step']:.3g}); largest estimate "
                     f"{control['largest_estimate']:.3g} E"
                     + (f" at t = {control['largest_estimate_time']:.6g} s "
                        f"({control['largest_estimate_quantity']})"
                        if control["largest_estimate_quantity"] else ""))
    signals = result.signals
    names = [n for n in signals if n != "time"]
    if names and len(signals["time"]):
        width = max(len(n) for n in names)
        units = data.get("units") or {}
        lines.append(f"{'column':<{width}}  {'final':>13}  {'max |value|':>13}  unit")
        for name in names[:12]:
            lines.append(f"{name:<{width}}  {signals[name][-1]:>13.6g}  "
                         f"{abs(signals[name]).max():>13.6g}  {units.get(name) or '-'}")
        if len(names) > 12:
            lines.append(f"... {len(names) - 12} more columns in the CSV")
    for kind in ("csv", "statistics", "plot", "mat"):
        if kind in result.files:
            lines.append(f"{'results' if kind == 'csv' else kind:<11} {result.files[kind]}")
    return "\n".join(lines)


def _cmd_run(args) -> int:
    if args.resume is not None or args.start_from is not None:
        return _cmd_run_checkpoint(args)
    if args.scene is None:
        raise InputError("dsim run: give a scene (or --resume FOLDER, --from CHECKPOINT)")
    out = Path(args.out or f"{Path(args.scene).stem}.csv")
    settings = {keyword: getattr(args, keyword) for keyword in SETTINGS}
    if args.isolate:
        if settings["backend"] not in (None, "isolated"):
            raise InputError(f"--isolate runs every FMU in its own local worker process (the "
                             f"isolated backend): it cannot be combined with --backend "
                             f"{settings['backend']}")
        settings["backend"] = "isolated"
    progress = ProgressBar(Path(args.scene).stem)
    _report(args.scene, out, args)
    result = simulate(args.scene, out=out, plot=args.plot, mat=args.mat, observers=[progress],
                      force=args.force, strict=args.strict, **_checkpoint_choices(args),
                      **_run_choices(args), **settings)
    return _said(result, args, progress)


def _report(scene, out: Path, args, checkpoints=None) -> None:
    """Tell a supervising process (master/tools/supervisor.py) where the run's files
    are, so that it can finish them if this process dies."""
    if checkpoints is None and args.checkpoint_every is not None:
        checkpoints = args.checkpoints or checkpoints_beside(out)
    supervised.report(csv=Path(out).resolve(), statistics=statistics_path(out).resolve(),
                      checkpoints=None if checkpoints is None else Path(checkpoints).resolve(),
                      scene=scene)


def _checkpoint_choices(args) -> dict:
    """``--checkpoint-every``, ``--checkpoint-keep`` and ``--checkpoints``."""
    return {"checkpoint_every": args.checkpoint_every, "checkpoint_keep": args.checkpoint_keep,
            "checkpoints": args.checkpoints}


def _cmd_run_checkpoint(args) -> int:
    """``dsim run --resume FOLDER`` (the same run goes on) or ``dsim run [SCENE] --from
    CHECKPOINT`` (a new run from a saved state): docs/checkpoints.md."""
    settings = {keyword: getattr(args, keyword) for keyword in SETTINGS}
    if args.resume is not None:
        given = [name for name, value in (("--out", args.out), ("--plot", args.plot),
                                          ("--mat", args.mat), ("--from", args.start_from))
                 if value is not None]
        if given:
            raise InputError(f"--resume goes on writing the run's own files: "
                             f"{', '.join(given)} cannot be given with it")
        progress = ProgressBar(Path(args.resume).name)
        found = find_checkpoint(args.resume)
        outputs = (found.manifest.get("request") or {}).get("outputs") or {}
        if outputs.get("out"):
            _report(found.manifest.get("scene"), Path(outputs["out"]), args,
                    checkpoints=found.folder.parent)
        result = simulate(args.scene, observers=[progress], resume=found,
                          checkpoint_keep=args.checkpoint_keep,
                          **{k: v for k, v in settings.items() if v is not None})
        return _said(result, args, progress)
    found = find_checkpoint(args.start_from)
    scene = args.scene or (found.manifest.get("request") or {}).get("scene") or "scene"
    out = Path(args.out or f"{Path(scene).stem}_from_{found.time:g}s.csv")
    choices = {k: v for k, v in _run_choices(args).items() if v not in (None, {}, [], False)}
    progress = ProgressBar(Path(scene).stem)
    _report(scene, out, args)
    result = simulate(args.scene, out=out, plot=args.plot, mat=args.mat, observers=[progress],
                      force=args.force, start_from=found, **_checkpoint_choices(args),
                      **choices, **{k: v for k, v in settings.items() if v is not None})
    return _said(result, args, progress)


def _said(result, args, progress) -> int:
    """What the command line says of a run's ``result``; its exit code."""
    if result.status != "completed":
        label = "simulation failed" if result.status == "failed" else "interrupted"
        print(f"dsim: {label}: {result.message}", file=sys.stderr)
        if "csv" in result.files:
            print(f"dsim: the {result.steps} converged steps are in {result.files['csv']}, "
                  f"statistics in {result.files.get('statistics', 'nowhere')}", file=sys.stderr)
    if result.status == "failed" or (result.statistics or {}).get("lost_workers"):
        for line in log_lines():  # a lost node's post-mortem, a raylet's worker notices
            print(line, file=sys.stderr)
    for warning in result.warnings[len(progress.shown):]:  # those said at the end
        print(f"dsim: warning: {warning}", file=sys.stderr)
    if result.status == "completed" and not args.quiet:
        print(_summary(result, args.plot))
    return result.exit_code


def _cmd_info(args) -> int:
    print("\n".join(scene_info(args.scene, ssd=args.ssd, every=args.all,
                                allow_outside=args.allow_outside, scenario=args.scenario,
                                inputs=args.input, events=args.events)))
    return 0


def _cmd_validate(args) -> int:
    settings = {keyword: getattr(args, keyword) for keyword in SETTINGS}
    found = validate(args.scene, strict=args.strict, **_run_choices(args), **settings)
    for problem in found.errors:
        print(f"dsim: error: {problem}", file=sys.stderr)
    for warning in found.warnings:
        print(f"dsim: warning: {warning}", file=sys.stderr)
    if found.ok:
        print(found.summary)
    return 0 if found.ok else 2


def comparison_lines(comparison) -> list[str]:
    """The table of a comparison: per column the largest difference, the band and
    what set it (rtol, or a floor: ulps, kernel noise), the reference's peak, and the
    first and worst time outside the band."""
    width = max(len(d.column) for d in comparison.differences)
    lines = [f"{'column':<{width}}  {'max |diff|':>11}  {'allowed':>11}  {'band':>5}  "
             f"{'ref peak':>11}  verdict"]
    for d in comparison.differences:
        verdict = "ok" if d.passed else (
            f"DIFFERS from t = {d.first[0]:.6g} s (worst at t = {d.worst[0]:.6g} s: "
            f"{d.worst[1]:.6g} against {d.worst[2]:.6g})")
        lines.append(f"{d.column:<{width}}  {d.max_difference:>11.3e}  {d.allowed:>11.3e}  "
                     f"{d.source:>5}  {d.reference_peak:>11.3e}  {verdict}")
    return lines


def _cmd_plot(args) -> int:
    files = [Path(a) for a in args.items if a.lower().endswith(".csv")]
    patterns = [a for a in args.items if not a.lower().endswith(".csv")]
    done = overlay_files(files, patterns, args.out, args.title or "")
    print(f"plot        {done.out} ({len(done.drawn)} signals of {done.results} results"
          + (f"; {len(done.names) - len(done.drawn)} more not drawn"
             if len(done.names) > len(done.drawn) else "") + ")")
    return 0


def _cmd_compare(args) -> int:

    columns = args.columns.split(",") if args.columns else None
    noise = read_noise(args.noise) if args.noise else None
    comparison = compare_files(args.result, args.reference, columns, args.rtol, args.atol,
                               noise)
    print("\n".join(comparison_lines(comparison)))
    floors = [f"{d.column}: {band_origin(d)}" for d in comparison.differences
              if d.source != "rtol"]
    if floors:
        print("bands set by a floor (round-off, not rtol): " + "; ".join(floors))
    if comparison.short:
        print(f"dsim: {args.result} ends at t = {comparison.result_end:g} s, before the "
              f"reference ({comparison.reference_end:g} s)", file=sys.stderr)
    failed = comparison.failed
    if failed:
        print(f"dsim: {len(failed)} of {len(comparison.differences)} columns differ from "
              f"{args.reference}", file=sys.stderr)
    return 0 if comparison.passed else 1


def _sweep_of(args):
    """The sweep the options say: a sweep file's, then the settings swept
    (``--tolerance 1e-6,1e-8``), the design and its samples and seed, what varies, the
    KPIs, the reference and the columns compared."""

    sweep = read_sweep_file(args.sweep) if args.sweep else Sweep()
    for keyword in SETTINGS:
        text = getattr(args, keyword, None)
        if text is not None:
            values = [v.strip() for v in text.split(",") if v.strip()]
            if len(values) == 1 and keyword not in sweep.grid:
                sweep.fixed[keyword] = values[0]
            else:
                sweep.grid[keyword] = values
    if args.design:
        sweep.design = args.design
    if args.samples is not None:
        sweep.samples = args.samples
    if args.seed is not None:
        sweep.seed = args.seed
    if sweep.design != "grid" and sweep.seed is None:
        sweep.seed = 0  # a sampled design is reproducible without being asked
    if args.vary:
        if sweep.design not in DESIGNS:
            raise InputError(f"--design {sweep.design}: not one of {', '.join(DESIGNS)}")
        problems, vary = [], []
        for text in args.vary:
            try:
                vary.append(parse_vary(text, sweep.design != "grid"))
            except InputError as error:
                problems += error.problems
        if problems:
            raise InputError(problems)
        given = {f.name for f in vary}
        sweep.vary = [f for f in sweep.vary if f.name not in given] + vary
    if args.kpi:
        sweep.kpis = list(dict.fromkeys(list(sweep.kpis) + args.kpi))
    if args.reference:
        sweep.reference = args.reference if args.reference == TIGHTEST else Path(args.reference)
    if args.columns:
        sweep.columns = args.columns.split(",")
    sweep.allow_outside = tuple(args.allow_outside or ())
    if args.scenario:  # read once: each point's run (here or in a Ray worker) takes it
        sweep.scenario = read_scenario(args.scenario)
    sweep.events = args.events
    if args.input:  # read once, as the scenario
        sweep.inputs = read_table(args.input)
    if args.start_from:  # read and checked once, as the scenario
        sweep.start_from = find_checkpoint(args.start_from)
    return sweep


def _cmd_sweep(args) -> int:
    sweep = _sweep_of(args)
    out = Path(args.out or f"{Path(args.scene).stem}_sweep")

    def progress(done, total, point):
        kpis = "".join(f", {k} {v:.4g}" for k, v in point.kpis.items())
        error = f", error {point.error:.2e}" if point.error == point.error else ""
        print(f"point {done}/{total}: {point.label}: {point.status}"
              f"{error}{kpis}, {point.wall_seconds:.2f} s", file=sys.stderr)

    def resumed(finished, total):
        print(f"resume      {finished} of {total} points already finished in {out}: "
              f"running the other {total - finished}", file=sys.stderr)

    try:
        points, interrupted = run_sweep(
            args.scene, sweep, out, progress, bars=True, resumed=resumed,
            said=lambda line: print(f"reference   {line}", file=sys.stderr))
    except HeadLost as lost:  # the table and files are written: say what was lost
        print(f"dsim: sweep failed: {lost} in {out}", file=sys.stderr)
        for line in log_lines():
            print(line, file=sys.stderr)
        return 1
    _print_sweep_summary(args, sweep, out, points)
    if any(state(p) in ("failed", "lost") for p in points):
        for line in log_lines():  # what Ray said of a lost node or worker
            print(line, file=sys.stderr)
    if interrupted:
        kept = [p for p in points if p.finished]
        print(f"dsim: interrupted: {len(kept)} finished point{'s' * (len(kept) != 1)} "
              f"kept in {out} ({count_states(points)}); run the same command again to run "
              "the others", file=sys.stderr)
        return 128 + interrupted
    return 0


def _print_sweep_summary(args, sweep, out: Path, points) -> None:
    """What a sweep wrote, its failed points, Pareto front, rankings and the cheapest
    point within ``--target-error``."""
    written = [out / name for name in ("sweep.csv", "sweep.md", "sweep.png", "kpis.png",
                                       "scatter.png", "sensitivity.md")
               if (out / name).is_file()]
    print(f"sweep       {len(points)} points ({count_states(points)}): "
          f"{', '.join(str(w) for w in written)}")
    for word in ("unstable", "failed", "refused", "interrupted", "lost"):
        these = [p for p in points if state(p) == word]
        if these:
            print(f"{word:<11} point{'s' * (len(these) > 1)} "
                  f"{', '.join(str(p.index) for p in these[:12])}"
                  f"{' ...' if len(these) > 12 else ''}: {STATES[word]}")
    front = sorted((p for p in points if p.pareto), key=lambda p: p.wall_seconds)
    for point in front:
        print(f"pareto      {point.label}: error {point.error:.2e}, {point.wall_seconds:.2f} s")
    _print_rankings(out)
    if args.target_error is not None:
        best = cheapest(points, args.target_error)
        if best is None:
            print(f"target      no measured point has an error of at most "
                  f"{args.target_error:g}")
        else:
            print(f"target      the cheapest point with an error of at most "
                  f"{args.target_error:g}: {best.label} (error {best.error:.2e}, "
                  f"{best.wall_seconds:.2f} s)")
            line = command_line(args.scene, best, sweep.fixed, sweep.allow_outside,
                                sweep.scenario, sweep.inputs, sweep.start_from,
                                sweep.events)
            print(f"run it      {line}")


def _print_rankings(out: Path) -> None:
    """The factors of each KPI ranked by the sweep's sensitivity table."""

    rows = read_sensitivity(out)
    indices = [Index(r["kpi"], r["factor"], r["method"], r["measure"], float(r["value"]),
                     float(r.get("confidence") or "nan"), r.get("note", "")) for r in rows]
    for kpi in dict.fromkeys(i.kpi for i in indices):
        order = ranking_text(indices, kpi)
        if order:
            print(f"ranking     {kpi}: {order}")
            if SPANS_ZERO in order:
                print(f"            {SPANS_ZERO}: {SPANS_ZERO_TEXT}")
        for note in cautions(indices, kpi):
            print(f"caution     {kpi}: {note}")


def _cmd_regress(args) -> int:

    if (args.kernels or args.no_kernel_study) and not args.update:
        raise InputError("--kernels and --no-kernel-study choose the kernel study of "
                         "--update: give --update too")
    if args.kernels and args.no_kernel_study:
        raise InputError("--kernels and --no-kernel-study contradict each other: give one")
    kernels = KernelChoice(not args.no_kernel_study, choose_kernels(
        [k.strip() for k in args.kernels.split(",") if k.strip()]) if args.kernels else None)
    cases, without = find_cases(args.folder, args.baselines, args.scene or (), args.update,
                                args.allow_outside)
    if not cases:
        raise InputError(f"{args.folder}: no scene has a baseline in "
                         f"{args.baselines or Path(args.folder) / 'baselines'} "
                         "(write them with --update)")

    def progress(outcome):
        verdict = outcome.status + (f": {outcome.message}" if outcome.message else "")
        print(f"{outcome.case.name}: {verdict}", file=sys.stderr)

    outcomes = run_cases(cases, args.results, args.update, args.rtol, args.atol, progress,
                         kernels)
    print("\n".join(summary_lines(outcomes)))
    if without:
        print(f"without a baseline (not run): {', '.join(without)}")
    if args.junit:
        junit_xml(outcomes, args.junit)
    bad = [o for o in outcomes if o.status not in ("passed", "updated")]
    if bad:
        print(f"dsim: {len(bad)} of {len(outcomes)} scenes did not pass: "
              f"{', '.join(o.case.name for o in bad)}", file=sys.stderr)
    return 1 if bad else 0


def _run_choices(args) -> dict:
    """The keywords of :func:`dsim.master.api.prepare` that ``--set``, ``--set-file``,
    ``--outputs`` and ``--output-interval`` give."""
    solver = {}
    for text in args.solver or ():
        name, sep, value = text.partition("=")
        if not sep:
            raise InputError(f"--solver {text}: give NAME=VALUE (rtol=1e-10, "
                             "m.method=cvode)")
        solver[name.strip()] = value.strip()
    substeps = {}
    for text in args.substeps or ():
        name, sep, value = text.partition("=")
        if text.strip().lower() == "auto":
            name, value = "*", "auto"
        elif not sep:
            raise InputError(f"--substeps {text}: give COMPONENT=N (controller=10) or auto")
        substeps[name.strip()] = value.strip()
    return {"parameters": given_parameters(args.set_file, args.set),
            "outputs": args.outputs, "output_interval": args.output_interval,
            "solver": solver, "allow_outside": args.allow_outside,
            "substeps": substeps or None, "fmu_log": args.fmu_log,
            "scenario": args.scenario, "events": args.events, "inputs": args.input}


def _add_allow_outside(parser) -> None:
    """``--allow-outside DIR`` (run, validate, sweep, regress): folders the scene may name
    files in besides its own (docs/security.md)."""
    parser.add_argument("--allow-outside", action="append", metavar="DIR",
                        help="let the scene name files (FMUs, parameter sets) in DIR too, "
                        "outside its own folder: only for files you trust "
                        "(docs/security.md); again for more")


def _add_events(parser) -> None:
    """``--events`` (run, sweep, info): when a scenario's events take effect."""
    parser.add_argument("--events", choices=EVENT_MODES, default="point",
                        help="when a scenario's events take effect: point (default: at the "
                        "first communication point at or after each event's time, as "
                        "libcosim) or exact (the step an event falls inside is cut at its "
                        "time; every FMU must take steps of any size)")


def _add_run_choices(run_parser) -> None:
    """Options that choose a run's model parameters and what it records (run,
    validate): docs/parameters.md, docs/results.md."""
    run_parser.add_argument("--set", action="append", metavar="NAME=VALUE",
                            help="a start value for this run, on top of the scene's "
                            "bindings and --parameter-set: COMPONENT.VARIABLE=VALUE "
                            "(nested components by their dotted path) or JOINT.k0=VALUE "
                            f"({' '.join(JOINT_COEFFICIENTS)}: those of the joint's law); "
                            "again for more (`dsim info --all` lists what can be set)")
    run_parser.add_argument("--substeps", action="append", metavar="COMPONENT=N",
                            help="N communication steps of a component per macro step, "
                            "its inputs held over them, or extrapolated where its FMU "
                            "can interpolate inputs (a component exchanged once per "
                            "step); auto: each from its FMU's DefaultExperiment stepSize; "
                            "again for more; over the scene's glue:Substeps")
    run_parser.add_argument("--fmu-log", action="store_true",
                            help="every log category of every FMU on, each message printed "
                            "to stderr as it comes (default: only the categories of "
                            "warnings and errors an FMU declares, its last messages kept "
                            "for the error messages)")
    run_parser.add_argument("--scenario", metavar="FILE",
                            help="events at times of the run: override, bias or reset an "
                            "input, a tunable parameter, an output or a joint's law "
                            "coefficient (JOINT.k0) (libcosim's .json or "
                            ".yml scenario, or ECOS's .xml; docs/scenarios.md); each takes "
                            "effect at the first communication point at or after its time")
    _add_events(run_parser)
    run_parser.add_argument("--input", metavar="FILE",
                            help="inputs over time from a table (.csv or .mat): a time column, "
                            "then one column per input named COMPONENT.VARIABLE; Reals "
                            "interpolated linearly, discrete values held, a time on two "
                            "rows a jump, the first and last values held outside "
                            "(docs/inputs.md)")
    _add_allow_outside(run_parser)
    run_parser.add_argument("--set-file", action="append", metavar="FILE",
                            help="start values from a file: an SSP parameter set (.ssv), "
                            "name,value rows (.csv) or a JSON object (.json); --set wins "
                            "over it")
    run_parser.add_argument("--solver", action="append", metavar="NAME=VALUE",
                            help="the integrator of the Model Exchange components: "
                            "method (DOP853 RK45 RK23 Radau BDF LSODA cvode), rtol, atol or "
                            "max_step, for every one (rtol=1e-10) or one (m.method=cvode); "
                            "again for more; over the SSD's solver annotations")
    run_parser.add_argument("--outputs", action="append", metavar="PATTERN",
                            help="record only the columns matching this glob (right.x*, "
                            "'j1.*'); again for more (default: every recorded column)")
    run_parser.add_argument("--output-interval", metavar="DT",
                            help="record a row every DT seconds, a whole multiple of the "
                            "macro step, and the last step (default: every step)")


def _add_settings(run_parser) -> None:
    """One option per setting of :mod:`dsim.master.settings` (checked there, not here)."""
    for keyword, setting in SETTINGS.items():
        names = [setting.option] + (["--tol"] if keyword == "tolerance" else [])
        text = setting.help
        if setting.rule == "choice":
            text += f" ({', '.join(choices(keyword))})"
        run_parser.add_argument(*names, dest=keyword, metavar=keyword.upper()
                                if setting.rule != "choice" else "NAME", help=text)


#: what --strict does (run and validate)
STRICT_HELP = ("refuse (exit 2) what is otherwise a warning: a rule the files break that "
               "does not change what the run computes")


def _add_run(commands) -> None:
    """``dsim run``: its settings, run choices and output files."""
    run_parser = commands.add_parser("run", help="run a scene (.ssp, folder or .ssd)")
    run_parser.add_argument("scene", nargs="?")
    _add_settings(run_parser)
    _add_run_choices(run_parser)
    run_parser.add_argument("--out", help="results CSV (default: SCENE.csv here); the "
                            "statistics JSON goes beside it")
    run_parser.add_argument("--plot", help="write a PNG plot of the results")
    run_parser.add_argument("--mat", help="write the results as a MATLAB .mat file too")
    run_parser.add_argument("--quiet", action="store_true", help="no summary")
    run_parser.add_argument("--force", action="store_true", help="run even when the "
                            "results CSV would not fit the free disk space")
    run_parser.add_argument("--isolate", action="store_true",
                            help="run every FMU in its own worker process on this machine "
                            "(--backend isolated; needs dsim[ray]): an FMU that crashes ends "
                            "the run with a message, never dsim")
    run_parser.add_argument("--strict", action="store_true", help=STRICT_HELP)
    run_parser.add_argument("--checkpoint-every", type=float, metavar="T",
                            help="write the whole simulation's state every T seconds of "
                            "simulated time (and when interrupted) to a folder beside the "
                            "results (docs/checkpoints.md)")
    run_parser.add_argument("--checkpoint-keep", type=int, metavar="N",
                            help="checkpoints kept, the last ones (default 2; a resumed "
                            "run: as many as its run kept)")
    run_parser.add_argument("--checkpoints", metavar="DIR",
                            help="the checkpoint folder (default: RESULTS.checkpoints "
                            "beside the results CSV)")
    run_parser.add_argument("--resume", metavar="FOLDER",
                            help="go on from the last whole checkpoint in FOLDER (or from "
                            "the checkpoint FOLDER): the same run, its own scene, settings "
                            "and files; the results are the bytes of a run never stopped")
    run_parser.add_argument("--no-supervisor", action="store_true",
                            help="step the run in the dsim process itself, with no small "
                            "process beside it to finish its files if it is killed "
                            "(docs/results.md)")
    run_parser.add_argument("--from", dest="start_from", metavar="CHECKPOINT",
                            help="a new run starting from a checkpoint's state and time, "
                            "with its run's scene and settings and what is given here on "
                            "top (--set of tunable parameters, --scenario, --stop, --out)")
    run_parser.set_defaults(handler=_cmd_run)


def _add_validate(commands) -> None:
    """``dsim validate``: the run's checks, nothing run."""
    validate_parser = commands.add_parser(
        "validate", help="every check of dsim run, without running: one line per finding, "
        "exit 2 when the scene cannot run")
    validate_parser.add_argument("scene")
    _add_settings(validate_parser)
    _add_run_choices(validate_parser)
    validate_parser.add_argument("--strict", action="store_true", help=STRICT_HELP)
    validate_parser.set_defaults(handler=_cmd_validate)


def _add_plot(commands) -> None:
    """``dsim plot``: signals of results CSVs, overlaid."""
    plot_parser = commands.add_parser(
        "plot", help="a PNG of chosen signals of one or more results CSVs, overlaid")
    plot_parser.add_argument("items", nargs="+", metavar="RESULT.csv|SIGNAL",
                             help="results CSVs and signal names (glob patterns: 'j1.*')")
    plot_parser.add_argument("--out", help="the PNG (default: the first CSV's name .png)")
    plot_parser.add_argument("--title", help="a title")
    plot_parser.set_defaults(handler=_cmd_plot)


def _add_sweep(commands) -> None:
    """``dsim sweep``: grids and designs of experiments (docs/doe.md)."""
    sweep_parser = commands.add_parser(
        "sweep", help="run a scene at every point of a grid of settings or a design of "
        "experiments over settings and model parameters; measure error, KPIs, wall time, "
        "iterations and sensitivity (a rerun into the same --out finishes only the missing "
        "points)")
    sweep_parser.add_argument("scene")
    for keyword, setting in SETTINGS.items():
        sweep_parser.add_argument(setting.option, dest=keyword, metavar="V1,V2",
                                  help=f"{setting.help} (comma-separated values to sweep)")
    sweep_parser.add_argument("--sweep", help="a sweep file (JSON: grid, points, settings, "
                              "reference, columns, vary, design, samples, seed, kpis)")
    sweep_parser.add_argument("--reference", help="results CSV to measure the error against, "
                              "or 'tightest' (default: the monolithic twin the scene ships as "
                              "resources/reference.csv, else dsim's reference run: strong "
                              "coupling, --step auto at a tenth of the tightest point's "
                              "tolerance, kept as OUT/reference.csv; no error where model "
                              "parameters vary)")
    sweep_parser.add_argument("--columns", help="comma-separated columns to compare "
                              "(default: every common column)")
    sweep_parser.add_argument("--out", help="folder for sweep.csv, sweep.md, the plots, the "
                              "sensitivity and each point's results (default: SCENE_sweep); "
                              "the same sweep into the same folder runs only the points "
                              "missing there")
    sweep_parser.add_argument("--vary", action="append", metavar="NAME=SPEC",
                              help="vary a setting or a model parameter (COMPONENT.VARIABLE): "
                              "a list a,b,c, a range lo:hi:N or lo:hi:log:N on a grid, lo:hi "
                              "or lo:hi:log for a sampled design (repeatable)")
    sweep_parser.add_argument("--design", help="grid (the full factorial, default), lhs, "
                              "sobol, halton (scipy.stats.qmc), saltelli (Sobol' indices) or "
                              "morris (elementary effects)")
    sweep_parser.add_argument("--samples", type=int, help="points of a sampled design (sobol "
                              "and saltelli: a power of 2; saltelli runs N (d + 2) points, "
                              "morris N (d + 1))")
    sweep_parser.add_argument("--seed", type=int, help="seed of a sampled design (default 0: "
                              "the same points every time)")
    sweep_parser.add_argument("--kpi", action="append", metavar="REDUCTION(COLUMN)",
                              help="a quantity of interest per point: max, min, maxabs, mean, "
                              "rms, final, argmax, argmin of a column or a glob of columns "
                              "(repeatable; docs/doe.md)")
    sweep_parser.add_argument("--target-error", type=float, help="name the cheapest measured "
                              "point whose error is at most this, and its command line")
    sweep_parser.add_argument("--scenario", metavar="FILE",
                              help="the same scenario's events in every point's run (and "
                              "the reference run): docs/scenarios.md")
    _add_events(sweep_parser)
    sweep_parser.add_argument("--input", metavar="FILE",
                              help="the same input table (.csv or .mat) in every point's run "
                              "(and the reference run): docs/inputs.md")
    sweep_parser.add_argument("--from", dest="start_from", metavar="CHECKPOINT",
                              help="every point's run (and the reference run) starts from "
                              "this checkpoint's state and time: run to a steady state "
                              "once, then vary (docs/checkpoints.md)")
    _add_allow_outside(sweep_parser)
    sweep_parser.set_defaults(handler=_cmd_sweep)


def _add_regress(commands) -> None:
    """``dsim regress``: scenes against stored baselines (docs/ci.md)."""
    regress_parser = commands.add_parser(
        "regress", help="run every scene of a folder that has a stored baseline and compare "
        "(exit 1 on any regression)")
    regress_parser.add_argument("folder", help="scenes: NAME.ssp archives or NAME/ folders")
    regress_parser.add_argument("--baselines", help="NAME.csv and NAME.json per scene "
                                "(default: FOLDER/baselines)")
    regress_parser.add_argument("--results", help="keep each run's CSV and statistics here")
    regress_parser.add_argument("--junit", help="write a JUnit XML report")
    regress_parser.add_argument("--update", action="store_true",
                                help="store each run as the new baseline instead of comparing "
                                "(scenes without one get one), and measure in each JSON how "
                                "far every column moves between OpenBLAS kernels (the "
                                "bands' floor)")
    regress_parser.add_argument("--no-kernel-study", action="store_true",
                                help="with --update: do not run the scenes under other "
                                "OpenBLAS kernels (the stored noise is kept)")
    regress_parser.add_argument("--kernels", metavar="K1,K2", help="with --update: the "
                                "OpenBLAS kernels of the study (default: every one this CPU "
                                "runs; Prescott, Nehalem, Sandybridge, Haswell, Zen, "
                                "SkylakeX)")
    regress_parser.add_argument("--scene", action="append", help="only this scene (again "
                                "for more)")
    regress_parser.add_argument("--rtol", type=float, help="override every case's rtol")
    regress_parser.add_argument("--atol", type=float, help="override every case's atol")
    _add_allow_outside(regress_parser)
    regress_parser.set_defaults(handler=_cmd_regress)


def _add_info(commands) -> None:
    """``dsim info``: what a scene is made of."""
    info_parser = commands.add_parser("info", help="a one-screen summary of a scene: FMU "
                                      "files, components, ports, joints, connections, what "
                                      "can be set (counted), master settings")
    info_parser.add_argument("scene")
    info_parser.add_argument("--ssd", help=SETTINGS["ssd"].help)
    info_parser.add_argument("--allow-outside", action="append", metavar="DIR",
                             help="let the scene name files in DIR too (docs/security.md)")
    info_parser.add_argument("--scenario", metavar="FILE",
                             help="list the events of a scenario file (docs/scenarios.md): "
                             "when each takes effect, its target and action, all checked "
                             "against the scene")
    _add_events(info_parser)
    info_parser.add_argument("--input", metavar="FILE",
                             help="summarise an input table (.csv or .mat: its columns, "
                             "their ranges and its time span), checked against the scene "
                             "(docs/inputs.md)")
    info_parser.add_argument("--all", action="store_true", help="every component in full, "
                             "with the table of every variable a run may set (name, type, "
                             "unit, start, the scene's value, limits, description)")
    info_parser.set_defaults(handler=_cmd_info)


def _add_compare(commands) -> None:
    """``dsim compare``: one results CSV against a reference."""
    compare_parser = commands.add_parser(
        "compare", help="compare a results CSV with a reference CSV (exit 1 if it differs)")
    compare_parser.add_argument("result")
    compare_parser.add_argument("reference")
    compare_parser.add_argument("--columns", help="comma-separated columns (default: common)")
    compare_parser.add_argument("--rtol", type=float, default=1e-6,
                                help="allowed difference relative to the reference's peak")
    compare_parser.add_argument("--atol", type=float, default=0.0, help="absolute allowance")
    compare_parser.add_argument("--noise", metavar="BASELINE.json", help="a baseline JSON of "
                                "dsim regress: its measured kernel noise is the floor of "
                                "the bands")
    compare_parser.set_defaults(handler=_cmd_compare)


class _CommandParser(argparse.ArgumentParser):
    """A subcommand's parser: an option it does not know is its error, said with its
    own usage (argparse would hand it up to the top-level parser, whose usage names
    no option of the subcommand)."""

    def parse_known_args(self, args=None, namespace=None):
        namespace, extras = super().parse_known_args(args, namespace)
        if extras:
            self.error(f"unrecognized arguments: {' '.join(extras)}")
        return namespace, extras


@functools.lru_cache(maxsize=1)
def parser() -> argparse.ArgumentParser:
    """The command-line parser, made once per process (parsing leaves it as it was; making
    it takes about 30 ms, half of it finding the other packages' commands)."""
    main_parser = argparse.ArgumentParser(
        prog="dsim", description="Co-simulation master: glues the FMUs of an SSP file (FMI 1.0 "
        "co-simulation, FMI 2.0 and 3.0 co-simulation and Model Exchange) with the T-T gluing "
        "algorithm.")
    main_parser.add_argument("--version", action="version", version=f"dsim {__version__}")
    commands = main_parser.add_subparsers(dest="command", required=True,
                                          parser_class=_CommandParser)
    _add_run(commands)
    _add_validate(commands)
    _add_plot(commands)
    _add_sweep(commands)
    _add_regress(commands)
    _add_info(commands)
    _add_compare(commands)
    # commands of other packages (build_fmus: `dsim build-fmus`), so that the master
    # imports none of them
    for entry in entry_points(group="dsim.commands"):
        entry.load()(commands)
    return main_parser


class _Terminated(BaseException):
    """SIGTERM outside a run (while a scene is read): unwinds like Ctrl-C, so that the
    folders unpacked so far are removed (a run installs its own handler meanwhile)."""


def _on_sigterm(number, frame) -> None:
    raise _Terminated


def main(argv=None) -> int:
    """Entry point of the ``dsim`` console script."""
    import signal
    import threading

    args = parser().parse_args(argv)
    in_main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _on_sigterm) if in_main else None
    try:
        return args.handler(args)
    except _Terminated:
        print("dsim: interrupted by SIGTERM", file=sys.stderr)
        return 128 + signal.SIGTERM
    except InputError as error:
        for problem in error.problems:
            print(f"dsim: error: {problem}", file=sys.stderr)
        return 2
    except SimulationError as error:
        print(f"dsim: simulation failed: {error}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("dsim: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # output piped into `head` and friends: not an error
        import os
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def console() -> None:
    """The ``dsim`` console script and ``python -m dsim.master.tools.cli``: :func:`main`, then the
    process ends without the native libraries' exit handlers (:mod:`dsim.master.tools.process_exit`;
    main itself returns, for callers in this process such as the tests)."""
    end_process(main())


if __name__ == "__main__":
    console()
