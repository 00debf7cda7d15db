"""The Python API that the command line, sweeps, regression runs and the web front
end call: :func:`prepare` checks a scene and its settings into a plan,
:func:`simulate` runs one to the end and returns its :class:`~dsim.master.recording.results.RunResult`.
"""
from __future__ import annotations

from dataclasses import replace

from dsim.master.errors import InputError
from dsim.master.planning.inputs import with_inputs
from dsim.master.planning.parameters import require_mapping, with_parameters
from dsim.master.planning.plan import make_plan
from dsim.master.planning.scenario import resolve_scenario
from dsim.master.planning.solver import with_solver
from dsim.master.planning.load import load_scene
from dsim.master.recording.observers import (CsvRecorder, MatWriter, PlotWriter, ProgressBar,
                                             StatisticsWriter)
from dsim.master.recording.results import RunResult, statistics_path
from dsim.master.running.backends.base import BACKEND_OPTIONS
from dsim.master.running.collector import collector_paused
from dsim.master.running.backends import BACKENDS
from dsim.master.running.execution import Execution
from dsim.master.scene import Scene
from dsim.master.settings import resolve


def prepare(scene, *, load_libraries: bool = True, strict: bool = False, parameters=None,
            outputs=None, output_interval=None, solver=None, allow_outside=None,
            substeps=None, fmu_log: bool = False, scenario=None, inputs=None, **settings):
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
    ``inputs``: an input table feeding inputs of the scene's components over time (a
    .csv or .mat file's path, a pandas DataFrame or a numpy structured array: a
    ``time`` column, then one column per input named ``component.variable``;
    docs/inputs.md).
    Raises :class:`~dsim.master.errors.InputError` listing every problem."""
    with collector_paused():  # 10,000 components: millions of objects, few cycles
        plan = _prepare(scene, load_libraries, strict, parameters, outputs,
                        output_interval, solver, allow_outside, settings, substeps, inputs)
    if scenario is not None:
        plan = replace(plan, scenario=resolve_scenario(plan, scenario))
    if fmu_log:
        plan = replace(plan, specs=tuple(replace(s, fmu_log=True) for s in plan.specs))
    return plan


def _prepare(scene, load_libraries, strict, parameters, outputs, output_interval, solver,
             allow_outside, settings, substeps=None, inputs=None):
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
    if settings.get("step") is not None:  # said by dsim info and validate
        changes["step_from"] = "the step setting (--step)"
    return make_plan(replace(scene, **changes), options.get("backend", "in-process"),
                     {key: options.get(key) for key in BACKEND_OPTIONS}, load_libraries, strict,
                     outputs, output_interval, substeps)


def simulate(scene, *, out=None, statistics=None, plot=None, mat=None, progress: bool = False,
             observers=(), handle_signals: bool = True, force: bool = False,
             **settings) -> RunResult:
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
    """
    # a cluster's workers start while the scene is read and planned (Backend.ahead)
    backend = BACKENDS.get(settings.get("backend") or "")
    if backend is not None:
        backend.ahead(settings)
    try:
        return _simulate(scene, out, statistics, plot, mat, progress, observers,
                         handle_signals, force, settings)
    finally:
        if backend is not None:
            backend.release_ahead()  # a connection made ahead that no backend took


def _simulate(scene, out, statistics, plot, mat, progress, observers, handle_signals,
              force, settings) -> RunResult:
    plan = prepare(scene, **settings)
    watchers = []
    if out is not None:
        watchers.append(CsvRecorder(out, force=force))
        watchers.append(StatisticsWriter(statistics or statistics_path(out)))
    elif statistics is not None:
        watchers.append(StatisticsWriter(statistics))
    if plot is not None:
        watchers.append(PlotWriter(plot))
    if mat is not None:
        watchers.append(MatWriter(mat))
    if progress:
        watchers.append(ProgressBar())
    return Execution(plan, watchers + list(observers)).run(handle_signals)
