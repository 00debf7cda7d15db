"""The statistics of a run (the JSON beside the CSV, ``RunResult.statistics``):
wall time per phase, iterations per step, flexibility refreshes, and per component
the doSteps, state saves and restores, and calls and seconds per FMI function."""
from __future__ import annotations

#: counter names of the FMI functions (FMU subsystems) and core methods (in-process)
DO_STEP = ("fmi2DoStep", "step", "fmi3DoStep", "fmiDoStep", "integrate")
SAVE = ("fmi2GetFMUstate", "get_state", "fmi3GetFMUState", "save continuous states")
RESTORE = ("fmi2SetFMUstate", "set_state", "fmi3SetFMUState", "restore continuous states")


def _count(functions: dict, names) -> int:
    return sum(functions.get(name, {}).get("calls", 0) for name in names)


def _components(plan, counts) -> dict:
    result = {}
    specs = {spec.name: spec for spec in plan.specs}
    for name, counters, place in counts.subsystems or ():
        functions = {f: {"calls": calls, "seconds": seconds}
                     for f, (calls, seconds) in sorted(counters.items())}
        result[name] = {"seconds": sum(f["seconds"] for f in functions.values()),
                        "do_steps": _count(functions, DO_STEP),
                        "state_saves": _count(functions, SAVE),
                        "state_restores": _count(functions, RESTORE),
                        "functions": functions}
        if name in specs:  # which FMI version and interface ran
            result[name]["fmi_version"] = specs[name].fmi_version
            result[name]["interface"] = specs[name].interface
        if place is not None:  # a worker process elsewhere: which node, which process
            result[name]["worker"] = dict(place)
    return result


def recorded_units(plan, columns=()) -> dict[str, str]:
    """Column of the results CSV -> its unit ('' where the FMU declares none; String
    columns have none); ``columns``: the run's numeric columns (default the plan's)."""
    units = plan.units or {}
    columns = tuple(columns) or tuple(plan.columns)
    if plan.selected is not None:
        columns = tuple(columns[i] for i in plan.selected)
    return {name: units.get(name, "") for name in ("time",) + columns
            + tuple(plan.text_columns)}


def recorded_display_units(plan, units: dict) -> dict[str, dict]:
    """Column of the results CSV (``units``: what :func:`recorded_units` gives) -> the
    display unit its FMU variable declares ({"unit", "factor", "offset"}: plots show
    value * factor + offset in it); only the columns that declare one."""
    display = plan.display_units or {}
    return {name: dict(display[name]) for name in units if name in display}


def run_statistics(plan, counts, wall_seconds: float, components: dict | None = None) -> dict:
    """The statistics of a run of ``plan`` from its
    :class:`~dsim.master.running.counts.RunCounts` (seconds, counts); ``components``:
    what is known of them, when they cannot be asked (an abandoned run whose workers
    may be stuck)."""
    scene, settings = plan.scene, plan.scene.master
    components = _components(plan, counts) if components is None else components
    # (an abandoned run knows only where its workers ran: no seconds, no counts)
    inside = sum(c.get("seconds", 0.0) for c in components.values())
    do_steps = sum(c.get("do_steps", 0) for c in components.values())
    # Newton iterations -> steps that took that many
    histogram = counts.iterations
    taken = sum(histogram.values())
    total = sum(iterations * count for iterations, count in histogram.items())
    steps = counts.steps
    phases = counts.phases
    coupling = counts.coupling
    units = recorded_units(plan, counts.columns)
    statistics = {
        "scene": scene.name,
        "file": str(scene.file),
        "status": counts.status,
        "message": counts.message or (str(counts.error) if counts.error else None),
        "start_time": scene.start_time,
        "stop_time": scene.stop_time,
        "time_reached": counts.time,
        # an FMU that ended the simulation itself: which, and the time it reached
        "ended_by": counts.ended_by,
        "coupling": plan.coupling,
        "backend": plan.backend,
        "master": dict(settings.__dict__),
        "steps": steps,
        "planned_steps": counts.planned_steps,
        "wall_seconds": wall_seconds,
        "setup_seconds": phases["setup"],
        "phases": phases,
        "seconds_in_fmus": inside,
        "seconds_in_master": wall_seconds - inside,
        "iterations": {
            "total": total if steps else 0,
            "mean_per_step": total / taken if steps and taken else 0.0,
            "max_per_step": max(histogram, default=0) if steps else 0,
            "histogram": {str(k): v for k, v in sorted(histogram.items()) if v},
        },
        "lambda_refreshes": coupling.get("lambda_refreshes", 0),
        "lambda_factorizations": coupling.get("lambda_factorizations", 0),
        "step_cuts": coupling.get("step_cuts", 0),
        "least_squares_factorizations": coupling.get("least_squares_factorizations", 0),
        "least_squares_steps": coupling.get("least_squares_steps", 0),
        "roundoff_steps": coupling.get("roundoff_steps", 0),
        # the algebraic loops' Newton (None without loops): solves, corrections,
        # Jacobians measured, damped corrections, residual evaluations
        "algebraic_loops": coupling.get("algebraic_loops"),
        "do_steps_per_step": do_steps / steps if steps else 0.0,
        # an error-controlled run (step auto): its steps and its largest estimate
        "step_control": counts.step_control,
        # a fixed-step run: how far each connected value moves within a step while the
        # FMU it feeds does not see it move, relative to its range (docs/method.md)
        "coupling_error": counts.coupling_error,
        "components": components,
        # every worker lost (killed, or gone with its node) and how the run went on
        "lost_workers": list(counts.lost_workers),
        "warnings": list(counts.warnings),
        # what repeats the run besides the scene and "master": the parameter sets
        # chosen, the values given on top (docs/parameters.md) and what was recorded
        "parameter_sets": list(scene.parameter_sets),
        "parameters": dict(scene.overrides),
        # the unit of each column of the results CSV (docs/results.md, "Units"), and
        # the display unit of those whose FMU declares one (plots show them in it)
        "units": units,
        "display_units": recorded_display_units(plan, units),
        # components stepped several times per macro step (--substeps)
        "substeps": {spec.name: spec.substeps for spec in plan.specs if spec.substeps > 1},
        # of those, the ones whose Real inputs were extrapolated over the substeps with
        # their slope (fmi2SetRealInputDerivatives: the FMU declares canInterpolateInputs);
        # the others' inputs were held
        "substeps_input_derivatives": [spec.name for spec in plan.specs
                                       if spec.input_derivatives],
        "recording": {"outputs": list(plan.outputs),
                      "output_interval": plan.output_interval,
                      "every_steps": plan.record_every},
    }
    if plan.input_table is not None:  # --input: the table and what each column fed
        statistics["inputs"] = plan.input_table
    if counts.scenario is not None:  # a run with a scenario: every change it applied
        scenario = plan.scenario
        statistics["scenario"] = {"file": scenario.file, "format": scenario.format,
                                  "end": scenario.end, "applied": list(counts.scenario)}
    return statistics
