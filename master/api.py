"""The Python API that the command line, sweeps, regression runs and the web front
end call: :func:`prepare` checks a scene and its settings into a plan,
:func:`simulate` runs one to the end and returns its :class:`~dsim.master.recording.results.RunResult`.
"""
from __future__ import annotations

from dataclasses import replace

from dsim.master.errors import InputError
from dsim.master.planning.checkpoints import (changed_parameters, check_files,
                                              checked_every, checkpoint_problems,
                                              manifest_of_run, request_of,
                                              resumed_settings)
from dsim.master.planning.inputs import with_inputs
from dsim.master.planning.parameters import require_mapping, with_parameters
from dsim.master.planning.plan import make_plan
from dsim.master.planning.scenario import resolve_scenario
from dsim.master.planning.solver import with_solver
from dsim.master.planning.load import load_scene
from dsim.master.recording.observers import (CsvRecorder, MatWriter, PlotWriter, ProgressBar,
                                             StatisticsWriter)
from dsim.master.reading.checkpoint_files import find_checkpoint
from dsim.master.recording.checkpoints import CheckpointFolder, checkpoints_beside
from dsim.master.recording.results import RunResult, statistics_path
from dsim.master.running.backends.base import BACKEND_OPTIONS, RUN_OPTIONS
from dsim.master.running.collector import collector_paused
from dsim.master.running.backends import BACKENDS
from dsim.master.running.checkpointing import Checkpointer
from dsim.master.running.execution import Execution
from dsim.master.scene import Scene
from dsim.master.settings import resolve


def prepare(scene, *, load_libraries: bool = True, strict: bool = False, parameters=None,
            outputs=None, output_interval=None, solver=None, allow_outside=None,
            substeps=None, fmu_log: bool = False, scenario=None, events: str = "point",
            inputs=None, start_time=None, start_from=None, **settings):
    """The checked :class:`~dsim.master.planning.plan.Plan` of ``scene`` (an .ssp archive, a scene
    folder, an .ssd file, or a :class:`~dsim.master.scene.Scene`) with ``settings``
    overriding the scene's ``glue:Master`` annotation (keywords as the command-line
    options: stop, step, tolerance, relative_tolerance, max_iterations,
    refresh_after, perturbation, predictor, refresh, convergence, coupling, start,
    backend, address, call_timeout, parameter_set, ssd; ``dsim.master.settings.SETTINGS``
    holds them all).  ``load_libraries=False`` checks each FMU's
    library as bytes without loading it (no code of the FMU runs: what ``dsim
    validate`` and ``dsim serve``'s uploads do).  ``strict``: refuse what would
    otherwise be a warning (a rule the files break that does not change the results).
    ``parameters``: start values of the components' variables and joint law
    coefficients for this run, on top of every binding and the parameter set: a
    mapping of full names (``"left.k_ground[1]"``, ``"sub.inner.m"``, ``"j1.k0"``) to
    Python values or text read by the variable's type (docs/parameters.md).
    ``outputs``: glob patterns of the columns to record (default: every one);
    ``output_interval``: record every this many seconds, a whole multiple of the
    macro step (default: every step; docs/results.md).  ``solver``: the integrator
    settings of the Model Exchange components, over the SSD's annotations: a mapping
    of ``method``, ``rtol``, ``atol``, ``max_step`` (every component) or
    ``COMPONENT.NAME`` (one) to values (docs/third_party.md).  ``allow_outside``: a
    folder (or several) whose files the scene may name besides its own, for scenes
    whose FMUs sit beside them and that the user trusts (docs/security.md).
    ``substeps``: communication steps per macro step of components exchanged once per
    step, their inputs held, or extrapolated where the FMU can interpolate inputs
    (``{"controller": 10}``; ``"auto"``: each from its FMU's DefaultExperiment
    stepSize), over the scene's ``glue:Substeps`` annotations (docs/third_party.md).
    ``fmu_log``: every log category of every FMU on and each message printed to stderr
    (default: only the warning and error categories an FMU declares;
    docs/third_party.md).
    ``scenario``: events at times of the run (a scenario file's path, libcosim's JSON or
    YAML or ECOS's XML, or a :class:`~dsim.master.reading.scenario_files.Scenario`
    read from one), resolved against the scene's variables (docs/scenarios.md).
    ``events``: ``"point"`` (default: each event at the first communication point at or
    after its time, as libcosim) or ``"exact"`` (a step an event falls inside is cut
    at its time; every FMU must take steps of any size).
    ``inputs``: an input table feeding inputs of the scene's components over time (a
    .csv or .mat file's path, a pandas DataFrame or a numpy structured array: a
    ``time`` column, then one column per input named ``component.variable``;
    docs/inputs.md).
    ``start_from``: a checkpoint (its folder, or a checkpoint folder: its last one) a
    new run starts from, at its time and from its saved states, with the scene and
    settings of the checkpoint's run and these on top (``scene`` may be None: the
    checkpoint's; docs/checkpoints.md).
    Raises :class:`~dsim.master.errors.InputError` listing every problem."""
    if start_from is not None:
        return _prepare_from(scene, start_from, dict(
            settings, parameters=parameters, outputs=outputs, output_interval=output_interval,
            solver=solver, allow_outside=allow_outside, substeps=substeps, fmu_log=fmu_log,
            scenario=scenario, events=events, inputs=inputs, strict=strict,
            load_libraries=load_libraries))
    with collector_paused():  # 10,000 components: millions of objects, few cycles
        plan = _prepare(scene, load_libraries, strict, parameters, outputs,
                        output_interval, solver, allow_outside, settings, substeps, inputs,
                        start_time)
    if scenario is not None:
        plan = replace(plan, scenario=resolve_scenario(plan, scenario, events))
    elif events != "point":
        raise InputError("--events chooses when a scenario's events take effect: give "
                         "--scenario with it")
    if fmu_log:
        plan = replace(plan, specs=tuple(replace(s, fmu_log=True) for s in plan.specs))
    return plan


def _prepare(scene, load_libraries, strict, parameters, outputs, output_interval, solver,
             allow_outside, settings, substeps=None, inputs=None, start_time=None):
    """:func:`prepare`'s work."""
    parameters = require_mapping(parameters)
    chosen = settings.get("parameter_set")
    if not isinstance(scene, Scene):  # the plan reports the reader's problems with its own
        scene = load_scene(scene, [chosen] if chosen else (), strict=False,
                           ssd=settings.get("ssd"), allow_outside=allow_outside)
    elif chosen or settings.get("ssd"):
        raise InputError("settings parameter_set and ssd: give the scene's file, not a "
                         "loaded scene")
    scene = with_parameters(scene, parameters)
    scene = with_solver(scene, solver)
    if inputs is not None:  # a table component and its connections (docs/inputs.md)
        scene = with_inputs(scene, inputs)
    try:
        master, options = resolve(scene.master, settings)
    except InputError as error:
        refused = InputError(list(scene.problems) + error.problems)
        refused.warnings = list(scene.warnings)
        raise refused from None
    changes = {"master": master}
    if "stop" in options:  # the user said when to stop: no default assumed
        changes.update(stop_time=options["stop"], experiment=True)
    if start_time is not None:  # a run started from a checkpoint: its time
        changes["start_time"] = float(start_time)
    if settings.get("step") is not None:  # said by dsim info and validate
        changes["step_from"] = "the step setting (--step)"
    return make_plan(replace(scene, **changes), options.get("backend", "in-process"),
                     {key: options.get(key) for key in (*BACKEND_OPTIONS, *RUN_OPTIONS)},
                     load_libraries, strict,
                     outputs, output_interval, substeps)


def simulate(scene=None, *, out=None, statistics=None, plot=None, mat=None,
             progress: bool = False, observers=(), handle_signals: bool = True,
             force: bool = False, checkpoint_every=None, checkpoint_keep: int | None = None,
             checkpoints=None, resume=None, start_from=None, **settings) -> RunResult:
    """Run ``scene`` to its stop time and return the :class:`~dsim.master.recording.results.RunResult`,
    also when the run fails or is interrupted (``result.status``).

    ``out``: results CSV to write (its statistics JSON goes beside it, or to
    ``statistics``); without it the signals are kept in memory.  ``plot``: a PNG of
    the signals.  ``mat``: a MATLAB .mat file of them.  ``progress``: a progress bar on a terminal.  ``observers``: more
    :class:`~dsim.master.recording.observers.Observer` objects.  ``handle_signals``: SIGINT and
    SIGTERM end the run after the current step (main thread only); a second one ends
    the process at once, files kept (:mod:`dsim.master.running.interrupts`).  ``force``: run
    even when the CSV would not fit the free disk space (else refused before the
    run, as bad input).  ``parameters``, ``outputs``, ``output_interval`` and the other
    keywords are as :func:`prepare` takes them.  Raises InputError for bad input, before
    anything runs.

    Checkpoints (docs/checkpoints.md): ``checkpoint_every``: seconds of simulated time
    between two checkpoints of the whole simulation's state, written to ``checkpoints``
    (a folder; default ``NAME.checkpoints`` beside ``out``), the last
    ``checkpoint_keep`` kept.  ``resume``: a checkpoint folder (its last whole
    checkpoint) or one checkpoint: the run that wrote it goes on from there, with its
    own scene, settings and files (only where it runs may change: ``backend`` and its
    options), its results continued to the same bytes as a run never stopped.
    ``start_from``: a checkpoint a new run starts from (its time the start time), with
    the scene and settings of the checkpoint's run and what is given here on top
    (tunable parameters, a scenario, a stop time, other files).
    """
    # a cluster's workers start while the scene is read and planned (Backend.ahead)
    backend = BACKENDS.get(settings.get("backend") or "")
    if backend is not None:
        backend.ahead(settings)
    try:
        return _simulate(scene, out, statistics, plot, mat, progress, observers,
                         handle_signals, force, settings, checkpoint_every,
                         checkpoint_keep, checkpoints, resume, start_from)
    finally:
        if backend is not None:
            backend.release_ahead()  # a connection made ahead that no backend took


def _simulate(scene, out, statistics, plot, mat, progress, observers, handle_signals,
              force, settings, every=None, keep=None, folder=None, resume=None,
              start_from=None) -> RunResult:
    if resume is not None or start_from is not None:
        return _from_checkpoint(scene, out, statistics, plot, mat, progress, observers,
                                handle_signals, force, settings, every, keep, folder,
                                resume, start_from)
    plan = prepare(scene, **settings)
    checkpointer = None
    if every is not None:
        request = request_of(scene, settings, {"out": out, "statistics": statistics,
                                               "plot": plot, "mat": mat, "force": force})
        checkpointer = _checkpointer(plan, settings, every, keep, folder, out, request)
    return _run(plan, out, statistics, plot, mat, progress, observers, handle_signals,
                force, checkpointer)


def _checkpointer(plan, settings, every, keep, folder, out, request):
    """The checkpoints of a run of ``plan``; InputError when its FMUs cannot serialize
    their state or it has nowhere to write them."""
    every = checked_every(every)
    problems = checkpoint_problems(plan)
    if problems:
        raise InputError([f"checkpoints: {p}" for p in problems])
    if folder is None and out is None:
        raise InputError("checkpoints: give a results file (out) or a checkpoint folder "
                         "(checkpoints) to write them beside")
    keep = 2 if keep is None else keep
    if not isinstance(keep, int) or isinstance(keep, bool) or keep < 1:
        raise InputError(f"checkpoint_keep: {keep!r}: give a whole number from 1")
    folder = checkpoints_beside(out) if folder is None else folder
    inputs = [plan.scene.file] + [spec.path for spec in plan.specs]
    return Checkpointer(CheckpointFolder(folder, keep, inputs), every,
                        {**manifest_of_run(plan, request, settings, every), "keep": keep})


def _from_checkpoint(scene, out, statistics, plot, mat, progress, observers,
                     handle_signals, force, settings, every, keep, folder, resume,
                     start_from) -> RunResult:
    """A run resumed from a checkpoint (``resume``), or a new run started from one
    (``start_from``)."""
    if resume is not None and start_from is not None:
        raise InputError("give resume or start_from, not both")
    found = find_checkpoint(resume if resume is not None else start_from)
    where = f"checkpoint {found.folder}"
    manifest = found.manifest
    if resume is not None:
        if scene is not None:
            raise InputError(f"{where}: a resumed run reads its scene from the "
                             "checkpoint; give no scene")
        scene, settings, outputs = resumed_settings(manifest, settings, where)
        plan = prepare(scene, **settings)
        check_files(manifest, plan, settings, where)
        out, statistics, plot, mat = (outputs.get(k) for k in ("out", "statistics", "plot",
                                                               "mat"))
        force = bool(outputs.get("force"))
        continuing = (manifest.get("results") or {}).get("csv")
        if out is not None and continuing is None:
            raise InputError(f"{where}: it records no results file to go on from")
        every = manifest.get("every") if every is None else every
        keep = manifest.get("keep") if keep is None else keep
        checkpointer = _checkpointer(plan, settings, every, keep, folder or (
            found.folder.parent if found.folder.name.startswith("step-") else None),
            out, manifest.get("request"))
        return _run(plan, out, statistics, plot, mat, progress, observers, handle_signals,
                    force, checkpointer, found, continuing=continuing)
    plan = prepare(scene, start_from=found, **settings)
    checkpointer = None
    if every is not None:
        merged = _merged(manifest, settings)
        request = request_of(plan.scene.file if scene is None else scene,
                             {**merged, "start_time": found.time},
                             {"out": out, "statistics": statistics, "plot": plot,
                              "mat": mat, "force": force})
        checkpointer = _checkpointer(plan, merged, every, keep, folder, out, request)
    return _run(plan, out, statistics, plot, mat, progress, observers, handle_signals,
                force, checkpointer)


def _merged(manifest: dict, given: dict) -> dict:
    """The settings of a checkpoint's run with ``given`` on top (the parameters merged;
    what is not given, None, is the checkpoint run's)."""
    request = manifest.get("request") or {}
    settings = dict(request.get("settings") or {})
    if given.get("parameters"):
        settings["parameters"] = {**(settings.get("parameters") or {}),
                                  **given["parameters"]}
    settings.update({k: v for k, v in given.items() if k != "parameters" and v is not None})
    settings.pop("start_time", None)
    return settings


def _prepare_from(scene, start_from, given: dict):
    """:func:`prepare` of a new run from a checkpoint (``start_from``: a path or a
    :class:`~dsim.master.reading.checkpoint_files.Checkpoint`)."""
    found = find_checkpoint(start_from)
    where = f"checkpoint {found.folder}"
    manifest = found.manifest
    if scene is None:
        scene = (manifest.get("request") or {}).get("scene")
        if scene is None:
            raise InputError(f"{where}: its run was given a loaded scene: give the scene")
    settings = _merged(manifest, given)
    plan = prepare(scene, start_time=found.time, **settings)
    check_files(manifest, plan, settings, where, fresh=True)
    if plan.scene.stop_time <= found.time:
        raise InputError(f"{where}: it is at t = {found.time:g} s, at or after the stop "
                         f"time {plan.scene.stop_time:g} s: give a later stop time (--stop)")
    return replace(plan, start_from=found,
                   start_values=tuple(changed_parameters(manifest, plan, where)))


def _run(plan, out, statistics, plot, mat, progress, observers, handle_signals, force,
         checkpointer=None, resume=None, continuing=None) -> RunResult:
    watchers = []
    if out is not None:
        recorder = CsvRecorder(out, force=force, digest=checkpointer is not None,
                               continuing=continuing)
        if checkpointer is not None:
            checkpointer.results = recorder
        watchers.append(recorder)
        watchers.append(StatisticsWriter(statistics or statistics_path(out)))
    elif statistics is not None:
        watchers.append(StatisticsWriter(statistics))
    if plot is not None:
        watchers.append(PlotWriter(plot))
    if mat is not None:
        watchers.append(MatWriter(mat))
    if progress:
        watchers.append(ProgressBar())
    return Execution(plan, watchers + list(observers), checkpoints=checkpointer,
                     resume=resume).run(handle_signals)
