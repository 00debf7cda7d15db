"""The execution of a checked plan: a coupling, a backend and observers.

:class:`Execution` is for callers that step, watch and stop a run themselves
(a sweep, a web server); :func:`dsim.master.api.simulate` runs one to the end.  The
flow: observers start (files opened and locked), the backend instantiates the
subsystems, the start forces are set in initialization mode, then every macro
step is one template step of the coupling, its outputs checked for non-finite
values and handed to the observers; whatever the ending, the subsystems are
released, the statistics made, and the observers finish with the
:class:`~dsim.master.recording.results.RunResult`.

Time is ``start + n * step`` (no drift); the last step is shortened to land on
the stop time exactly (never past it, also in the FMUs' own sum ``t + h``:
:mod:`dsim.master.running.timeline`), and every other step is given to the FMUs as exactly
``step``, so that nothing that depends on the step size (the interface
flexibility, the gluing matrix's factor) is rebuilt for round-off.
"""
from __future__ import annotations

import math
import signal
import threading
import time as clock
from collections import defaultdict
from contextlib import nullcontext
from dataclasses import replace

import numpy as np

from dsim.master.errors import InputError, SimulationError, Terminated
from dsim.master.recording.observers import (CsvRecorder, MemoryRecorder, Observer, RunInfo,
                                             StepRecord)
from dsim.master.recording.output_files import OutputError
from dsim.master.recording.results import RunResult
from dsim.master.recording.statistics import run_statistics
from dsim.master.running.backends import BACKENDS
from dsim.master.running.checkpointing import resume_run
from dsim.master.running.couplings import COUPLINGS
from dsim.master.running.couplings.base import StepReport
from dsim.master.running.collector import collector_paused
from dsim.master.running.counts import RunCounts
from dsim.master.running.coupling_error import CouplingErrorWatch
from dsim.master.running.interrupts import SignalWatch, end_lost
from dsim.master.running.scenario import ScenarioRun
from dsim.master.running.start import check_start, start_forces
from dsim.master.running.step_control import StepController
from dsim.master.running.timeline import size_to, step_count


#: cut steps (and least-squares steps) named one by one in the warnings
CUTS_SAID = 5
#: makes a StepRecord from a tuple of its fields, as its own _make does, without the
#: Python-level __new__ a NamedTuple has (a third of a microsecond, every step)
_record = tuple.__new__


class Execution:
    """One run of a :class:`~dsim.master.planning.plan.Plan` with ``observers`` (and, unless one of
    them records the signals or ``keep_signals`` is False, a memory recorder for the
    result's signals).

    Use :meth:`run` to go to the end, or :meth:`start`, then :meth:`step` until it
    returns False, then :meth:`finish`.  :meth:`stop` (from an observer, another
    thread or a signal handler) ends the run after the current step, as
    interrupted.  Bad input found while starting (up to the end of the FMUs'
    initialization) raises InputError; a failure after it, at the start time (its
    outputs, its algebraic loops) or during the run, ends it as failed, and
    :meth:`finish` returns the result.
    """

    def __init__(self, plan, observers=(), keep_signals: bool = True, checkpoints=None,
                 resume=None):
        self.plan = plan
        self.scene = plan.scene
        self.settings = plan.scene.master
        self.observers = list(observers)
        if keep_signals and not any(isinstance(o, (CsvRecorder, MemoryRecorder))
                                    for o in self.observers):
            self.observers.insert(0, MemoryRecorder())  # the result's signals
        self.status = "created"
        self.index = 0
        self.time = self.scene.start_time
        self.warnings: list[str] = []
        self.planned_steps = step_count(self.scene.start_time, self.scene.stop_time,
                                        self.settings.step)
        self.backend = None
        self.coupling = None
        self.layout = None
        self.error: Exception | None = None
        self.signal: int | None = None
        self._stop_requested: str | None = None
        self._told = -math.inf  # when the observers last heard of the set-up's progress
        #: the component that ended the simulation itself and the time it reached
        #: (:class:`~dsim.master.errors.Terminated`), or None
        self.ended_by: dict | None = None
        #: Newton iterations -> how many steps took that many
        self._iterations: dict[int, int] = defaultdict(int)
        self._refreshes = 0
        #: every subsystem has left initialization mode: what fails from then on is a
        #: failure of the run (exit 1), not bad input
        self._initialized = False
        self._phases = {"setup": 0.0, "steps": 0.0, "observers": 0.0, "finish": 0.0}
        self._wall_start = None
        self._columns: tuple[str, ...] = ()
        self._held = None
        #: how a macro step is taken (:meth:`_glued_advance`, or
        #: :meth:`_kernel_advance` where the coupling's kernel takes whole steps)
        self._advance = self._glued_advance
        #: the error-controlled steps (``step="auto"``:
        #: :mod:`dsim.master.running.step_control`), or None: one step per macro step
        self.controller = None
        self._said_notes: list[str] = []
        #: a fixed-step run's estimate of its coupling error (None: no connection)
        self._watch: CouplingErrorWatch | None = None
        #: the process is the run's: it may end it when the Ray head is lost (:meth:`run`)
        self._end_when_lost = False
        #: the scenario's state (:mod:`dsim.master.running.scenario`), or None: the step
        #: loop is then the same as without the option (no work added)
        self.scenario = None
        #: writes the run's checkpoints (:class:`~dsim.master.running.checkpointing.
        #: Checkpointer`), or None
        self.checkpoints = checkpoints
        #: the checkpoint this run goes on from (a
        #: :class:`~dsim.master.reading.checkpoint_files.Checkpoint`), or None; ``fresh``:
        #: a new run from its state (the plan's ``start_from``), not the same run resumed
        self._fresh = resume is None and plan.start_from is not None
        self.resumed_from = plan.start_from if self._fresh else resume

    # --- time --------------------------------------------------------------------
    def step_time(self, index: int) -> float:
        """Communication point ``index`` (s): start + index * step, the last one the
        stop time."""
        if index >= self.planned_steps:
            return self.scene.stop_time
        return self.scene.start_time + index * self.settings.step

    def _step_size(self, index: int) -> float:
        """Size handed to the FMUs for the step from point ``index``: ``step``, except
        for the last one, which ends at the stop time and never past it."""
        if index + 1 < self.planned_steps:
            return self.settings.step
        return size_to(self.step_time(index), self.step_time(index + 1), self.settings.step)

    # --- observers ---------------------------------------------------------------
    def _notify(self, hook: str, *args) -> None:
        start = clock.perf_counter()
        try:
            for observer in self.observers:
                method = getattr(observer, hook, None)  # an observer made before a hook
                if method is not None:
                    method(*args)
        finally:
            self._phases["observers"] += clock.perf_counter() - start

    #: seconds between two set-up progress notices (the last is always passed on)
    PREPARING_EVERY = 0.2

    def _instantiated(self, done: int, total: int, what: str = "FMUs instantiated") -> None:
        """The backend's progress: ``done`` of ``total`` FMUs instantiated (or ``what``
        else it does, ``total`` 0), passed to the observers a few times a second."""
        now = clock.perf_counter()
        if done < total and now - self._told < self.PREPARING_EVERY:
            return
        self._told = now
        self._notify("preparing", what, done, total)

    def warn(self, message: str) -> None:
        """Record a warning and pass it to the observers."""
        self.warnings.append(message)
        self._notify("warned", message)

    # --- start -------------------------------------------------------------------
    def start(self) -> None:
        """Open the observers, instantiate and initialise the subsystems, set the
        start forces and record the start time (raises InputError on bad input)."""
        if self.status != "created":
            raise RuntimeError(f"the execution is {self.status}, it can start only once")
        self._wall_start = clock.perf_counter()
        if self.plan.scenario is not None:  # its transfer carries the modified inputs
            self.scenario = ScenarioRun(self.plan.scenario, self.plan.transfer)
            self.plan = replace(self.plan, transfer=self.scenario.transfer)
        # (an observer whose stepped is the base class's does nothing there: not called)
        self._stepped = [observer.stepped for observer in self.observers
                         if getattr(observer.stepped, "__func__", None) is not Observer.stepped]
        plan = self.plan
        self._texts: list[str] = []
        self._text_reads = any(spec.text_reads for spec in plan.specs)
        layout, joints = plan.assemble()
        self._columns = tuple(plan.columns) + tuple(layout.labels)
        self._record_all = np.array_equal(plan.record_index, np.arange(sum(
            len(spec.reads) for spec in plan.specs)))
        self._selected = plan.selected
        self._record_every = plan.record_every
        self._held = None  # the last converged step, when it is not on the output grid
        shown = self._columns if self._selected is None else tuple(
            self._columns[i] for i in self._selected)
        info = RunInfo(self.scene.name, self.scene.file, shown, self.scene.start_time,
                       self.scene.stop_time, self.settings.step, self.planned_steps,
                       plan.coupling, plan.backend, tuple(plan.inputs), plan.text_columns,
                       plan.record_every, units={c: (plan.units or {}).get(c, "")
                                                 for c in ("time",) + shown})
        started = []
        try:
            for observer in self.observers:
                observer.started(info)
                started.append(observer)
            if self.checkpoints is not None:
                self.checkpoints.open(self.scene.start_time)
            self.backend = BACKENDS[plan.backend].from_specs(
                plan.specs, progress=self._instantiated, **(plan.backend_options or {}))
            self._notify("preparing", "initialising", 0, 0)
            self._initialize(layout, joints)
            if self.resumed_from is not None:
                self._notify("preparing", "resuming", 0, 0)
                resume_run(self, self.resumed_from, self._fresh, plan.start_values)
        except SimulationError as error:
            if not self._initialized:  # in initialization mode: the consistent start
                self._abort(started)   # failed, the scene's start is bad input
                raise InputError(str(error)) from None
            # after initialization (the outputs read at the start time, the algebraic
            # loops solved there): the run failed at its start, exit 1
            self._fail(error.located(0, self.time))
            self._phases["setup"] = clock.perf_counter() - self._wall_start
            for message in self.plan.warnings:
                self.warn(message)
            return
        except BaseException:
            self._abort(started)
            raise
        self.status = "running"
        if self.checkpoints is not None and self.resumed_from is not None and not self._fresh:
            self.checkpoints.resumed_at(self.time, self.scene.start_time)
        if self.coupling.kernel is not None and not self._text_reads \
                and not len(self.coupling.forces) and self.controller is None:
            self._advance = self._kernel_advance
        if self.scenario is not None:
            self._unmodified_advance, self._advance = self._advance, self._scenario_advance
        for message in self.plan.warnings:
            self.warn(message)
        for message in self.backend.notes():  # what a lost worker ends
            self.warn(message)
        if self.backend.has_workers:  # for a progress line
            for observer in self.observers:
                if hasattr(observer, "waiting"):
                    observer.waiting = self.backend.waiting
        if self._end_when_lost:
            self.backend.watch_head(lambda what: end_lost(self, what))  # never left to
            # Ray's own timeouts
        self._phases["setup"] = clock.perf_counter() - self._wall_start
        if self.resumed_from is not None and not self._fresh:
            return  # the results hold the rows up to the checkpoint already
        try:
            self._read_texts()
            row = self._row()
            self._check_finite(row)
            self._notify("stepped", StepRecord(0, self.time, self._chosen(row),
                                               texts=self._recorded_texts()))
        except SimulationError as error:
            self._fail(error.located(0, self.time))
        except OutputError as error:
            self._fail(error)

    def _abort(self, started) -> None:
        """The start failed on bad input: the ``started`` observers aborted, the
        subsystems released."""
        for observer in started:
            observer.aborted()
        if self.backend is not None:
            self.backend.close()
        if self.checkpoints is not None:
            self.checkpoints.close()
        self.status = "aborted"

    def _carry_start_values(self) -> None:
        """In initialization mode, carry connected values along every chain of
        connections (outputs calculated from parameters feed inputs and parameters
        downstream), pass after pass in dependency order."""
        transfer, texts = self.plan.start_transfer, self.plan.text_transfer
        numbers = transfer is not None and transfer.size
        if not numbers and not (texts is not None and texts.size):
            return
        for _ in range(self.plan.start_passes):
            if numbers:
                outputs = np.concatenate(self.backend.read_outputs())
                self.backend.write_inputs(transfer.inputs(outputs), start=True)
            self._read_texts()
            self._write_texts()

    # --- String values: moved and recorded around the coupling's numeric step ----
    def _read_texts(self) -> None:
        if self._text_reads:
            self._texts = [text for texts in self.backend.read_texts() for text in texts]

    def _write_texts(self) -> None:
        transfer = self.plan.text_transfer
        if transfer is not None and transfer.size:
            self.backend.write_texts(transfer.inputs(self._texts))

    def _recorded_texts(self) -> tuple[str, ...]:
        return tuple(self._texts[i] for i in self.plan.text_index)

    def _initialize(self, layout, joints) -> None:
        plan, settings = self.plan, self.settings
        self._carry_start_values()
        glued = self.backend.subset(plan.glued)
        if plan.non_matching and settings.start != "rest":
            layout, joints = plan.assemble(self._positions(glued, layout))
        forces, reported, warning = start_forces(settings.start, glued, layout, joints)
        if warning:
            self.warn(warning)
        sensitivity = self._start_sensitivity(glued, layout, forces)
        self.backend.finish_initialization()
        self._initialized = True
        if plan.non_matching and settings.start == "rest":
            layout, joints = plan.assemble(self._positions(glued, layout))
        for message in check_start(settings.start, glued, layout, joints, forces, reported,
                                   settings, self._step_size(0)):
            self.warn(message)
        self.layout = layout
        self.coupling = COUPLINGS[plan.coupling].from_plan(plan, self.backend, layout, joints,
                                                           settings, sensitivity)
        self.coupling.start(glued.kinematics() if layout.size else None, forces)
        self.coupling.solve_loops(self.plan.scene.start_time)
        for note in (self.coupling.loop_solver.notes if self.coupling.loop_solver else ()):
            self.warn(note)
        #: the connected sources, each once: what the coupling error watch follows and
        #: the error-controlled step's estimate weighs
        self._sources = plan.sources
        watched = self._sources
        if any(spec.table is not None for spec in plan.specs):
            # a table's columns are no coupling error: the table is the input, fed as
            # it is at each communication point (docs/inputs.md)
            watched = np.setdiff1d(watched, _table_reads(plan))
        if len(watched) and plan.step_control is None:
            self._watch = self._coupling_error_watch(watched)
        if plan.step_control is not None:
            self.controller = StepController(
                plan.step_control, self._take, self._estimated, self._estimated_labels(),
                self.backend, self.coupling, settings.step)

    def _start_sensitivity(self, glued, layout, forces):
        """In initialization mode, d a / d f of every glued subsystem (when the explicit
        coupling glues one that cannot save its state: its flexibility comes from it)."""
        if not self.plan.flexibility_at_start:
            return None
        local = layout.local_forces(np.zeros(layout.size) if forces is None else forces)
        sensitivity = glued.start_flexibility(
            local, [self.settings.perturbation * np.maximum(1.0, np.abs(f)) for f in local])
        for name, matrix in zip(glued.names, sensitivity):
            if not np.any(matrix):
                raise InputError(f"component '{name}': its port accelerations do not follow "
                                 "its forces in initialization mode, so the explicit coupling "
                                 "cannot measure its flexibility without a rollback")
        return sensitivity

    def _positions(self, glued, layout) -> dict:
        """Initial positions of the glued dofs, for non-matching joints."""
        positions = {}
        for spec_index, (u, _, _) in zip(self.plan.glued, glued.kinematics()):
            spec = self.plan.specs[spec_index]
            for port_dof, value in zip(spec.port_dofs, u):
                positions[(spec.name, port_dof.port, port_dof.dof)] = value
        return positions

    def _coupling_error_watch(self, sources) -> CouplingErrorWatch:
        """The watch of the connected sources (:mod:`~dsim.master.running.coupling_error`),
        each marked iterated where every value it feeds is made consistent at the
        communication point: iterated by the strong coupling, or the input of an
        algebraic loop solved there (no value passed on a step late)."""
        plan = self.plan
        transfer = plan.transfer
        reads = plan.read_names
        iterated = np.zeros(len(sources), dtype=bool)
        fed = np.zeros(transfer.size, dtype=bool)
        if plan.coupling == "strong":
            for index, begin, end in transfer.targets:
                fed[begin:end] = index in plan.iterated
        solver = self.coupling.loop_solver
        if solver is not None:
            for positions, active in zip(solver.positions, solver.active):
                if active:
                    fed[positions] = True
        if fed.any():  # a source is iterated when all it feeds is
            exchanged = np.zeros(max(len(reads), 1), dtype=bool)
            exchanged[transfer.gather[~fed]] = True
            iterated = ~exchanged[sources]
        watch = CouplingErrorWatch(sources, [reads[s] for s in sources], iterated)
        watch.add(self.coupling.outputs)
        return watch

    # --- steps -------------------------------------------------------------------
    def _take(self, time: float, size: float, index: int, end: float):
        """One macro step of every subsystem from ``time`` by ``size`` (s) to ``end``,
        the algebraic loops solved there: the coupling's report."""
        report = self.coupling.step(time, size, index)
        self.coupling.solve_loops(end)
        return report

    def _estimated(self) -> np.ndarray:
        """What an error-controlled step's estimate weighs: the connected values (each
        source once) and the glued ports' positions and velocities; where there is
        neither, every value read.  Not the joint forces nor accelerations: a force
        that makes two ports compatible to a tolerance is known only to that tolerance
        over the ports' flexibility, which grows as 1 / h**2 when the step shrinks."""
        outputs = self.coupling.outputs
        parts = [outputs[self._sources]] if len(self._sources) else []
        if self.layout.size:
            parts += [k for u, v, _ in self.coupling.glued.kinematics()
                      for k in (u, v) if k is not None]
        return np.concatenate(parts) if parts else outputs

    def _estimated_labels(self) -> list[str]:
        """The names of :meth:`_estimated`'s entries."""
        reads = self.plan.read_names
        labels = [reads[i] for i in self._sources]
        if self.layout.size:
            for index, (u, v, _) in zip(self.plan.glued, self.coupling.glued.kinematics()):
                spec = self.plan.specs[index]
                for kind, values in (("position", u), ("velocity", v)):
                    if values is not None:
                        labels += [f"{spec.name}.{p.port} {kind} {p.dof}"
                                   for p in spec.port_dofs[:len(values)]]
        return labels if labels else list(reads)

    def _row(self) -> np.ndarray:
        """The recorded values of the step (outputs, then joint forces): a new array."""
        outputs = self.coupling.outputs
        if not self._record_all:
            outputs = outputs[self.plan.record_index]
        if not len(self.coupling.forces):
            return outputs  # the coupling makes a new output array every step
        return np.concatenate((outputs, self.coupling.forces))

    def _chosen(self, row: np.ndarray) -> np.ndarray:
        """The recorded columns of a full row (``outputs``)."""
        return row if self._selected is None else row[self._selected]

    def _check_finite(self, row: np.ndarray) -> None:
        # a sum is finite exactly when every term is (or, rarely, when it overflows: then
        # the full check below runs); for a short row it is the cheapest test there is
        total = sum(row.tolist()) if len(row) < 64 else np.add.reduce(row)
        if math.isfinite(total) or np.isfinite(row).all():
            return
        bad = np.flatnonzero(~np.isfinite(row))
        column = self._columns[bad[0]]
        if bad[0] < len(self.plan.columns):
            component, variable = self.plan.recorded[bad[0]]
            what = f"component '{component}' output '{variable}'"
        else:
            what = f"joint '{self.layout.joint_of[bad[0] - len(self.plan.columns)]}' " \
                   f"force '{column}'"
        raise SimulationError(f"{what} is not finite ({row[bad[0]]})", time=self.time,
                              step=self.index)

    def step(self) -> bool:
        """Take one macro step; False when the run has ended (stop time reached,
        failed or stopped)."""
        if self.status != "running":
            return False
        if self._stop_requested:
            self.status = "interrupted"
            if self.checkpoints is not None and self.index:  # between two steps: whole
                self.checkpoints.take(self)
            return False
        index, time = self.index, self.time
        started = clock.perf_counter()
        following = index + 1
        if following < self.planned_steps:  # as step_time and _step_size say
            end = self.scene.start_time + following * self.settings.step
            size = self.settings.step
        else:
            end, size = self.step_time(following), self._step_size(index)
        try:
            report = self._advance(time, size, following, end)
            self.index, self.time = following, end
            row = self._row()
            self._check_finite(row)
            if self._watch is not None:
                self._watch.add(self.coupling.outputs)
            self._phases["steps"] += clock.perf_counter() - started
            self._iterations[report.iterations] += 1
            # a StepRecord made as its own _make makes it, without its Python __new__
            record = _record(StepRecord, (following, end, self._chosen(row),
                                          report.iterations, report.refreshed,
                                          report.residual, self._recorded_texts()
                                          if self._text_reads else ()))
            self._emit(record)
        except (Terminated, SimulationError, OutputError, KeyboardInterrupt) as stop:
            return self._stopped(stop, following, end)
        if following >= self.planned_steps:
            self.status = "completed"
            return False
        if self.checkpoints is not None and self._held is None and \
                self.checkpoints.due(end):
            self.checkpoints.take(self)
        return True

    def _glued_advance(self, time: float, size: float, index: int, end: float):
        """Macro step ``index`` from ``time`` by ``size`` to ``end`` (s): the coupling's
        step (error-controlled steps across it with step auto), the algebraic loops
        solved, String values passed on; what it took (a StepReport)."""
        if self._text_reads:
            self._write_texts()
        # a step makes tens of thousands of short-lived objects at 10,000 components
        # and few cycles: the collector's passes over them (two full ones a step of
        # chain_10000 on Ray) wait for the step's end (collector.py)
        with collector_paused():
            if self.controller is None:
                report = self._take(time, size, index, end)
            else:  # error-controlled steps across the output interval
                report = self.controller.advance(time, size, index, end)
                for note in self.controller.notes[len(self._said_notes):]:
                    self._said_notes.append(note)
                    self.warn(note)
        if report.cuts:
            self._warn_cut(index, end, size / 2 ** report.cuts)
        if report.lost and self.coupling.least_squares_steps <= CUTS_SAID:
            self.warn(f"step {index} (t = {end:.6g} s): the gluing matrix lost rank "
                      "(a singular configuration): the step was accepted in the "
                      f"least-squares sense, {report.lost:.3e} of residual left along "
                      "the direction no joint force changes")
        self._read_texts()
        return report

    def _kernel_advance(self, time: float, size: float, index: int, end: float):
        """:meth:`_glued_advance` of a system whose coupling's kernel takes the whole
        step (no joint, no algebraic loop, no String, no force column): only the
        kernel's call, nothing made per step that can be made once."""
        return self.coupling.step(time, size, index)

    def _scenario_advance(self, time: float, size: float, index: int, end: float):
        """:meth:`_glued_advance` (or :meth:`_kernel_advance`) with the scenario's events
        of the communication point ``time`` applied before the step and its output
        modifications after it (:mod:`dsim.master.running.scenario`)."""
        point = index - 1
        self.scenario.at_point(point, time, self.coupling.outputs, self.backend,
                               self.coupling)
        cuts = self.scenario.cuts(point)
        if not cuts:
            report = self._unmodified_advance(time, size, index, end)
            self.scenario.stepped(self.coupling.outputs)
            return report
        # --events exact: the step in parts that end at the events' times, each part
        # a step of its own size (every FMU takes any: planning/scenario.py checks)
        reports, start = [], time
        for part_end in [*cuts, end]:
            reports.append(self._unmodified_advance(start, part_end - start, index,
                                                    part_end))
            self.scenario.stepped(self.coupling.outputs)
            if part_end != end:
                self.scenario.at_time(point, part_end, self.coupling.outputs,
                                      self.backend, self.coupling)
            start = part_end
        return StepReport.of_parts(reports)

    def _emit(self, record) -> None:
        """Hand a step's record to the observers; off the output grid it is held, and
        recorded only if the run ends there."""
        index = record.index
        if index % self._record_every and index < self.planned_steps:
            self._held = record
        else:
            self._held = None
            for stepped in self._stepped:
                stepped(record)

    def _stopped(self, stop: BaseException, index: int, end: float) -> bool:
        """What a step that raised ``stop`` in step ``index`` (ending at ``end`` s)
        leaves: the run ended by an FMU, failed, or interrupted; False (no next step)."""
        if isinstance(stop, Terminated):
            self._end_by(stop)
        elif isinstance(stop, SimulationError):
            self._fail(stop.located(index, end))
        elif isinstance(stop, OutputError):
            self._fail(stop)
        else:  # KeyboardInterrupt
            self._stop_requested = "interrupted by the user"
            self.signal = signal.SIGINT
            self.status = "interrupted"
        return False

    def _end_by(self, ended: Terminated) -> None:
        """An FMU ended the simulation: the run ends normally at the last communication
        point every component reached together (this one), every row kept."""
        self.ended_by = {"component": ended.component, "time": ended.time}
        self.status = "completed"
        self.warn(f"{ended.message}: the run ends at t = {self.time:.9g} s, step "
                  f"{self.index} of {self.planned_steps} (the last communication point "
                  "every component reached)")

    def _warn_cut(self, index: int, end: float, smallest: float) -> None:
        """Say that a step was cut (the first few; the statistics count them all)."""
        cuts = self.coupling.cuts
        if cuts <= CUTS_SAID:
            self.warn(f"step {index} (t = {end:.6g} s): Newton did not converge over the "
                      f"whole step; it passed in steps of {smallest:g} s"
                      + (" (further cut steps are counted in the statistics: step_cuts)"
                         if cuts == CUTS_SAID else ""))

    def _flush_rows(self) -> None:
        """Write the rows still pending (a run shorter than a flush interval has all
        of them pending): rows that cannot be written fail a run that had completed,
        as they would have failed it during a step; after a failure or an interrupt
        they are a warning beside how the run ended."""
        for observer in self.observers:
            flush = getattr(observer, "flush", None)
            if flush is None:
                continue
            try:
                flush()
            except OutputError as error:
                if self.status == "completed":
                    self._fail(error)
                else:
                    self.warnings.append(str(error))

    def _fail(self, error: Exception) -> None:
        self.error = error
        self.status = "failed"

    def stop(self, reason: str = "stopped", signal_number: int | None = None) -> None:
        """End the run after the current step, as interrupted."""
        self._stop_requested = reason
        if signal_number is not None:
            self.signal = signal_number

    # --- the end -----------------------------------------------------------------
    def finish(self) -> RunResult:
        """Release the subsystems, make the statistics and the result, and let every
        observer finish (also after a failure or an interrupt)."""
        started = clock.perf_counter()
        if self.status == "running":
            self.status = "interrupted"
            self._stop_requested = self._stop_requested or "stopped before the stop time"
        if self._held is not None:  # the last converged step, off the output grid
            held, self._held = self._held, None
            try:
                for stepped in self._stepped:
                    stepped(held)
            except OutputError as error:
                self.warnings.append(str(error))
        if self._watch is not None and self.status == "completed":
            warning = self._watch.warning(self.plan.coupling)
            if warning:
                self.warn(warning)
        self._flush_rows()
        if self.backend is not None:  # said after how the run ended, not before
            self.warnings += [f"releasing the subsystems: {error}"
                              for error in self.backend.close()]
        self._phases["finish"] = clock.perf_counter() - started
        message = self._end_message()
        result = RunResult(self.status, message, self.time, self.index,
                           warnings=self.warnings, error=self.error, signal=self.signal)
        result.statistics = run_statistics(self.plan, self.counts(),
                                           clock.perf_counter() - self._wall_start)
        self._checkpoint_statistics(result.statistics)
        for observer in self.observers:
            try:
                observer.finished(result)
            except Exception as error:  # one observer must not stop the others
                result.warnings.append(f"{type(observer).__name__}: {error}")
            result.files.update(getattr(observer, "files", {}))
        return result

    def _checkpoint_statistics(self, statistics: dict) -> None:
        """The run's checkpoints and the one it went on from, in its statistics."""
        if self.checkpoints is not None:
            statistics["checkpoints"] = self.checkpoints.statistics()
            self.checkpoints.close()
        if self.resumed_from is not None:
            found = self.resumed_from
            statistics["resumed" if not self._fresh else "started_from"] = {
                "checkpoint": str(found.folder), "step": found.step, "time": found.time,
                "skipped": list(found.skipped)}

    def _end_message(self) -> str:
        """What ended the run: a failed run's error, an interrupted run's reason with
        where it stopped; "" for a run still going or completed."""
        if self.status == "failed":
            return str(self.error)
        if self.status == "interrupted":
            return (f"{self._stop_requested} (stopped at t = {self.time:g} s, "
                    f"step {self.index} of {self.planned_steps})")
        return ""

    def counts(self, ask: bool = True) -> RunCounts:
        """What the run counted so far (:class:`~dsim.master.running.counts.RunCounts`);
        ``ask=False``: without asking the subsystems (another thread, while the main
        one may be inside an FMU: their counters are then left out)."""
        phases = dict(self._phases)
        coupling = self.coupling
        if coupling is not None:
            phases.update({f"steps: {k}": v for k, v in coupling.seconds.items()})
        backend = self.backend
        subsystems = None
        if ask and backend is not None:
            subsystems = list(zip(backend.names, backend.counters(), backend.places()))
        return RunCounts(
            status=self.status, error=self.error, time=self.time, steps=self.index,
            planned_steps=self.planned_steps, ended_by=self.ended_by,
            warnings=tuple(self.warnings),
            iterations=dict(self._iterations),  # a copy: abandon() reads it elsewhere
            phases=phases, coupling=coupling.counts() if coupling is not None else {},
            columns=self._columns,
            step_control=self.controller.statistics() if self.controller else None,
            coupling_error=self._watch.statistics() if self._watch is not None else None,
            subsystems=subsystems,
            lost_workers=backend.losses() if backend is not None else [],  # the driver's
            message=self._end_message() or None,
            scenario=None if self.scenario is None else list(self.scenario.applied))

    def run(self, handle_signals: bool = True) -> RunResult:
        """Start (unless started), step to the end and finish.  With
        ``handle_signals`` (main thread only), SIGINT and SIGTERM end the run after
        the current step, as interrupted, with everything written; a second one ends
        the process at once, also while an FMU is stuck in its step, with the
        converged rows and the statistics kept (:mod:`dsim.master.running.interrupts`)."""
        watch = nullcontext()
        if handle_signals and threading.current_thread() is threading.main_thread():
            watch = SignalWatch(self)
            # the process is the run's: it may end it when the Ray head is lost
            self._end_when_lost = True
        with watch:  # over finish() too: releasing a subsystem may hang as well
            if self.status == "created":
                self.start()
            while self.step():
                pass
            return self.finish()

    def abandon(self, signal_number: int | None, lost: str | None = None) -> RunResult:
        """The run as far as it got, for a process that ends at once (a second signal,
        or ``lost``: what the run cannot go on without, such as the Ray head), made
        from another thread while the main thread may be inside an FMU: no subsystem
        is called and no worker asked (the counters of workers elsewhere are not known
        then, only where they ran)."""
        name = signal.Signals(signal_number).name if signal_number else ""
        if lost is not None:
            self.status = status = "failed"
            message = (f"{lost} (stopped at t = {self.time:g} s, step {self.index} of "
                       f"{self.planned_steps})")
            self.error = SimulationError(message)
        elif self.status in ("completed", "failed"):  # ended already: it says so
            status = self.status
            message = (str(self.error) if self.error else "completed") + \
                f"; then ended at once by {name} while the subsystems were released"
        else:
            self.stop(self._stop_requested or f"interrupted by {name}",
                      self.signal or signal_number)
            self.status = status = "interrupted"
            message = (f"{self._stop_requested}, then ended at once by {name} (stopped at "
                       f"t = {self.time:g} s, step {self.index} of {self.planned_steps})")
        result = RunResult(status, message, self.time, self.index, warnings=list(self.warnings),
                           error=self.error, signal=signal_number)
        components = None
        backend = self.backend
        if backend is not None and backend.remote:
            components = {component: {"worker": dict(place)} if place else {}
                          for component, place in zip(backend.names, backend.places())}
        wall = clock.perf_counter() - (self._wall_start or clock.perf_counter())
        result.statistics = run_statistics(self.plan, self.counts(ask=False), wall,
                                           components)
        result.statistics["message"] = message
        return result


def _table_reads(plan) -> np.ndarray:
    """Where the table components' outputs are in the run's flat outputs."""
    found, offset = [], 0
    for spec in plan.specs:
        if spec.table is not None:
            found.extend(range(offset, offset + len(spec.reads)))
        offset += len(spec.reads)
    return np.array(found, dtype=int)
