"""``dsim``: run, inspect and build glued co-simulations.

Exit codes: 0 success, 1 the simulation failed, 2 bad input or usage.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from master.errors import InputError, SimulationError


class ProgressBar:
    """A rich progress bar on a terminal; silent elsewhere (CI logs, pipes)."""

    def __init__(self, label: str):
        self.label = label
        self.progress = None

    def start(self, times):
        if not sys.stderr.isatty():
            return
        from rich.progress import (BarColumn, Progress, TextColumn, TimeElapsedColumn,
                                   TimeRemainingColumn)
        self.progress = Progress(TextColumn("{task.description}"), BarColumn(),
                                 TextColumn("t = {task.fields[t]:.4g} s"),
                                 TextColumn("it/step {task.fields[it]:.2f}"),
                                 TimeElapsedColumn(), TimeRemainingColumn(), transient=True)
        self.progress.start()
        self.total_iterations = 0
        self.task = self.progress.add_task(self.label, total=len(times) - 1, t=times[0], it=0.0)

    def step(self, index, time, report):
        if self.progress:
            self.total_iterations += report.iterations
            self.progress.update(self.task, completed=index, t=time,
                                 it=self.total_iterations / index)

    def finish(self):
        if self.progress:
            self.progress.stop()


def _summary(statistics, out: Path, plot: Path | None) -> str:
    from master.results import read_csv

    data = statistics.data
    header, values = read_csv(out)
    lines = [
        f"scene       {data['scene']}  ({data['file']}), "
        f"{data['master']['coupling']} coupling",
        f"time        {data['start_time']:g} .. {data['stop_time']:g} s, "
        f"step {data['master']['step']:g} s, {data['steps']} steps",
        f"iterations  {data['iterations']['mean_per_step']:.2f} per step "
        f"(max {data['iterations']['max_per_step']}), "
        f"Lambda refreshes {data['lambda_refreshes']}, "
        f"doSteps per FMU per step {data['do_steps_per_step'] / max(len(data['components']), 1):.2f}",
        f"wall time   {data['wall_seconds']:.3f} s "
        f"({data['seconds_in_fmus']:.3f} s inside FMUs)",
    ]
    if len(values):
        width = max(len(n) for n in header[1:]) if len(header) > 1 else 0
        lines.append(f"{'column':<{width}}  {'final':>13}  {'max |value|':>13}")
        for i, name in enumerate(header[1:13], start=1):
            lines.append(f"{name:<{width}}  {values[-1, i]:>13.6g}  "
                         f"{abs(values[:, i]).max():>13.6g}")
        if len(header) > 13:
            lines.append(f"... {len(header) - 13} more columns in the CSV")
    lines.append(f"results     {out}")
    lines.append(f"statistics  {out.with_suffix('.stats.json')}")
    if plot:
        lines.append(f"plot        {plot}")
    return "\n".join(lines)


def _cmd_run(args) -> int:
    from master.results import plot_results
    from master.run import run

    out = Path(args.out or f"{Path(args.scene).stem}.csv")
    overrides = dict(stop=args.stop, step=args.step, tolerance=args.tol,
                     max_iterations=args.max_iterations, predictor=args.predictor,
                     refresh=args.refresh, coupling=args.coupling)
    try:
        statistics = run(args.scene, out, observers=[ProgressBar(Path(args.scene).stem)],
                         **overrides)
    except SimulationError as error:
        print(f"dsim: simulation failed: {error}", file=sys.stderr)
        print(f"dsim: the converged steps are in {out}, statistics in "
              f"{out.with_suffix('.stats.json')}", file=sys.stderr)
        return 1
    if args.plot:
        plot_results(out, args.plot, title=statistics.data["scene"])
    if not args.quiet:
        print(_summary(statistics, out, Path(args.plot) if args.plot else None))
    return 0


def _cmd_info(args) -> int:
    from master.fmu import can_save_state
    from master.ports import model_description
    from master.run import plan

    checked = plan(__import__("master.ssp", fromlist=["load_scene"]).load_scene(args.scene))
    scene = checked.scene
    print(f"scene {scene.name}: {scene.start_time:g} .. {scene.stop_time:g} s")
    m = scene.master
    print(f"master: step {m.step:g} s, tolerance {m.tolerance:g} (relative "
          f"{m.relative_tolerance:g}), maxIterations {m.max_iterations}, predictor "
          f"{m.predictor}, refreshAfter {m.refresh_after}, perturbation {m.perturbation:g}")
    ports = checked.ports
    print(f"components ({len(scene.components)}):")
    for component in scene.components:
        description = model_description(component.source)
        cs = description.coSimulation
        flags = [f"state {'yes' if can_save_state(component.source) else 'NO'}",
                 f"serialize {'yes' if cs.canSerializeFMUstate else 'no'}",
                 f"variable step {'yes' if cs.canHandleVariableCommunicationStepSize else 'no'}"]
        port_text = ", ".join(f"{p}({' '.join(sorted(d))})" for p, d in sorted(
            ports[component.path].items()))
        print(f"  {component.path}: {component.source.name} "
              f"[{description.modelName}, FMI {description.fmiVersion}; {', '.join(flags)}]")
        print(f"      ports: {port_text or 'none'}")
        print(f"      records: {', '.join(checked.records[component.path])}")
    print(f"joints ({len(scene.joints)}):")
    for joint in scene.joints:
        law = ""
        if joint.kind == "flexible":
            law = f" k0={joint.k0} k1={joint.k1} c0={joint.c0} c1={joint.c1}"
        print(f"  {joint.name}: {'.'.join(joint.a)} -> {'.'.join(joint.b)} dofs "
              f"{' '.join(joint.dofs)}, {joint.kind}, {joint.measure}{law}")
    print(f"causal connections: {len(scene.connections)}")
    return 0


def _cmd_compare(args) -> int:
    from master.compare import compare_files

    columns = args.columns.split(",") if args.columns else None
    differences = compare_files(args.result, args.reference, columns, args.rtol, args.atol)
    width = max(len(d.column) for d in differences)
    print(f"{'column':<{width}}  {'max |diff|':>11}  {'allowed':>11}  {'ref peak':>11}")
    for d in differences:
        print(f"{d.column:<{width}}  {d.max_difference:>11.3e}  {d.allowed:>11.3e}  "
              f"{d.reference_peak:>11.3e}  {'ok' if d.passed else 'DIFFERS'}")
    failed = [d.column for d in differences if not d.passed]
    if failed:
        print(f"dsim: {len(failed)} of {len(differences)} columns differ from {args.reference}",
              file=sys.stderr)
        return 1
    return 0


def _cmd_build(args) -> int:
    from build_fmus.build import build_fmus, pack_scenes

    build_fmus(force=args.force)
    pack_scenes(force=args.force)
    return 0


def parser() -> argparse.ArgumentParser:
    """The command-line parser."""
    main_parser = argparse.ArgumentParser(
        prog="dsim", description="Co-simulation master: glues FMI 2.0 FMUs of an SSP file "
        "with the T-T gluing algorithm.")
    commands = main_parser.add_subparsers(dest="command", required=True)
    run_parser = commands.add_parser("run", help="run a scene (.ssp, folder or .ssd)")
    run_parser.add_argument("scene")
    run_parser.add_argument("--stop", type=float, help="stop time, s")
    run_parser.add_argument("--step", type=float, help="macro step H, s")
    run_parser.add_argument("--tol", type=float, help="absolute interface tolerance")
    run_parser.add_argument("--max-iterations", type=int, help="Newton iterations per step")
    run_parser.add_argument("--predictor", choices=["none", "constant", "linear", "quadratic"])
    run_parser.add_argument("--refresh", choices=["adaptive", "iterations"],
                            help="when to re-measure the interface flexibility")
    run_parser.add_argument("--coupling", choices=["iterative", "explicit"],
                            help="explicit: one trial per step, no iteration (a baseline)")
    run_parser.add_argument("--out", help="results CSV (default: SCENE.csv here)")
    run_parser.add_argument("--plot", help="write a PNG plot of the results")
    run_parser.add_argument("--quiet", action="store_true", help="no summary")
    run_parser.set_defaults(handler=_cmd_run)
    info_parser = commands.add_parser("info", help="components, capabilities, ports, "
                                      "joints and master settings of a scene")
    info_parser.add_argument("scene")
    info_parser.set_defaults(handler=_cmd_info)
    compare_parser = commands.add_parser(
        "compare", help="compare a results CSV with a reference CSV (exit 1 if it differs)")
    compare_parser.add_argument("result")
    compare_parser.add_argument("reference")
    compare_parser.add_argument("--columns", help="comma-separated columns (default: common)")
    compare_parser.add_argument("--rtol", type=float, default=1e-6,
                                help="allowed difference relative to the reference's peak")
    compare_parser.add_argument("--atol", type=float, default=0.0, help="absolute allowance")
    compare_parser.set_defaults(handler=_cmd_compare)
    build_parser = commands.add_parser("build-fmus", help="build FMUs and pack scenes")
    build_parser.add_argument("--force", action="store_true")
    build_parser.set_defaults(handler=_cmd_build)
    return main_parser


def main(argv=None) -> int:
    """Entry point of the ``dsim`` console script."""
    args = parser().parse_args(argv)
    try:
        return args.handler(args)
    except InputError as error:
        for problem in error.problems:
            print(f"dsim: error: {problem}", file=sys.stderr)
        return 2
    except SimulationError as error:
        print(f"dsim: simulation failed: {error}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("dsim: interrupted; the converged steps are kept", file=sys.stderr)
        return 130
    except BrokenPipeError:  # output piped into `head` and friends: not an error
        import os
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())
