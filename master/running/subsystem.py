"""The handle through which the couplings drive a subsystem.

The algorithm never sees an FMU: it sees a :class:`Subsystem` with a small,
batched interface (one call moves every glued dof of the subsystem): save and
restore state, set interface forces, step, read interface kinematics, read
outputs and write inputs.  :class:`~dsim.master.running.fmi.cs2.CoSimulation2Subsystem` implements it over
fmpy; :class:`CoreSubsystem` over an in-process physics core (algorithm tests
without FMI); a backend decides where each one runs.
"""
from __future__ import annotations

import time
from abc import ABC, abstractmethod
from collections import defaultdict
from contextlib import contextmanager

import numpy as np

from dsim.master.running.timeline import size_to

Kinematics = tuple[np.ndarray, np.ndarray, np.ndarray]


class Subsystem(ABC):
    """One subsystem.  ``interface`` lists its glued (port, dof) pairs: the order of
    the force vector it takes and of the kinematics it returns (empty when it is in
    no joint); ``output_names`` the variables :meth:`read_outputs` returns."""

    name: str
    interface: tuple[tuple[str, str], ...] = ()
    output_names: tuple[str, ...] = ()
    #: the attributes in which :meth:`save_state` keeps the saved state: a
    #: :meth:`snapshot` takes another state beside it by swapping them
    SAVED: tuple[str, ...] = ()

    def __init__(self):
        self._dirty = False
        #: connected inputs ramping over the step, written again after each restore
        #: (:meth:`hold_inputs`; the strong coupling iterates them around a joint Newton)
        self._held = None
        #: FMI function (or core method) -> [calls, seconds]
        self.counters: dict[str, list] = defaultdict(lambda: [0, 0.0])

    def _timed(self, label: str, function, *args):
        start = time.perf_counter()
        try:
            return function(*args)
        finally:
            entry = self.counters[label]
            entry[0] += 1
            entry[1] += time.perf_counter() - start

    # --- what an implementation provides ------------------------------------------
    @abstractmethod
    def save_state(self) -> None:
        """Remember the current state as the start of the macro step."""

    @abstractmethod
    def restore_state(self) -> None:
        """Go back to the state saved by :meth:`save_state`."""

    @abstractmethod
    def set_forces(self, forces: np.ndarray) -> None:
        """Interface forces (N, N.m) in ``interface`` order."""

    @abstractmethod
    def do_step(self, time: float, step_size: float) -> None:
        """Advance from ``time`` by ``step_size`` (s)."""

    @abstractmethod
    def kinematics(self) -> Kinematics:
        """Interface positions, velocities, accelerations (None where absent)."""

    def read_outputs(self) -> np.ndarray:
        """Values of ``output_names`` now (float; Integer and Boolean as numbers)."""
        return np.zeros(0)

    def write_inputs(self, values: np.ndarray) -> None:
        """Set the inputs that causal connections feed (in the subsystem's order)."""

    def read_texts(self) -> list[str]:
        """Values of the String variables the subsystem reads after every step."""
        return []

    def write_texts(self, values) -> None:
        """Set the String inputs that connections feed."""

    def write_start_inputs(self, values: np.ndarray) -> None:
        """Set what connections feed at initialization (fixed parameters too)."""
        self.write_inputs(values)

    def set_values(self, names, values) -> None:
        """Set the variables ``names`` to ``values`` between steps (a scenario's event:
        an input no connection feeds, a tunable parameter), as their types take them."""
        raise NotImplementedError(f"subsystem '{self.name}' cannot set values by name")

    def terminate(self) -> None:
        """Release what the subsystem holds."""

    def _free_saved(self) -> None:
        """Release the saved state (an FMU state: fmi2FreeFMUstate); nothing to release
        where it is plain data."""

    # --- a state kept beside the macro step's: the error-controlled step -------------
    def _slot(self) -> tuple:
        return tuple(getattr(self, name, None) for name in self.SAVED)

    def _put(self, values) -> None:
        for name, value in zip(self.SAVED, values):
            setattr(self, name, value)

    @contextmanager
    def _holding(self, values):
        """The saved state swapped for ``values`` while the block runs."""
        held = self._slot()
        self._put(values)
        try:
            yield
        finally:
            self._put(held)

    def snapshot(self):
        """The current state, kept beside the one :meth:`save_state` holds (which stays):
        a handle for :meth:`rollback` and :meth:`discard`.  The error-controlled macro
        step takes a step, goes back and takes it again in halves."""
        with self._holding((None,) * len(self.SAVED)):
            self.save_state()
            return self._slot()

    def rollback(self, snapshot) -> None:
        """Go back to a :meth:`snapshot` (kept: it can be gone back to again)."""
        with self._holding(snapshot):
            self.restore_state()
        self._dirty = False

    def discard(self, snapshot) -> None:
        """Release a :meth:`snapshot`."""
        with self._holding(snapshot):
            self._free_saved()

    # (the same by a key, for a backend whose subsystems live in another process: the
    #  states stay with the instances, the driver holds the key)
    def keep_snapshot(self, key) -> None:
        """:meth:`snapshot`, kept here under ``key``."""
        self.__dict__.setdefault("_kept", {})[key] = self.snapshot()

    def rollback_to(self, key) -> None:
        """:meth:`rollback` to the snapshot kept under ``key``."""
        self.rollback(self._kept[key])

    def drop_snapshot(self, key) -> None:
        """:meth:`discard` the snapshot kept under ``key``."""
        self.discard(self._kept.pop(key))

    def snapshot_checkpoint(self, key) -> dict:
        """:meth:`checkpoint` of the snapshot kept under ``key`` (the state it was in
        then, not the one :meth:`save_state` holds): a fresh instance goes on from
        there and keeps it under the same key."""
        with self._holding(self._kept[key]):
            return self.checkpoint()

    def statistics(self) -> dict:
        """FMI function (or core method) -> [calls, seconds]."""
        return {name: list(entry) for name, entry in self.counters.items()}

    # --- a checkpoint: the state as data, for another process (docs/checkpoints.md) ---
    def checkpoint(self) -> dict:
        """The state saved by the last :meth:`save_state` as plain data (bytes, numbers,
        arrays): what a fresh instance of the same subsystem, out of initialization
        mode, goes on from (:meth:`resume`), in another process or on another machine."""
        raise NotImplementedError(f"component '{self.name}' cannot serialize its state")

    def resume(self, state: dict) -> None:
        """Go on from a :meth:`checkpoint` of another instance: its state set, and kept
        as the saved one."""
        raise NotImplementedError(f"component '{self.name}' cannot serialize its state")

    def restore_counters(self, counters: dict) -> None:
        """Take ``counters`` (what :meth:`statistics` gave) as the counts so far: a run
        resumed from a checkpoint counts on from the run that wrote it."""
        self.counters = defaultdict(lambda: [0, 0.0],
                                    {name: list(entry) for name, entry in counters.items()})

    @contextmanager
    def uncounted(self):
        """The FMI calls made in the block left out of the counts (a checkpoint's own:
        a run with checkpoints counts what a run without them counts)."""
        held = self.statistics()
        try:
            yield
        finally:
            self.restore_counters(held)

    def current_checkpoint(self) -> dict:
        """:meth:`checkpoint` of the state now (at a communication point), its calls
        not counted; the saved state stays as it was."""
        with self.uncounted():
            snapshot = self.snapshot()
            try:
                with self._holding(snapshot):
                    return self.checkpoint()
            finally:
                self.discard(snapshot)

    def finish_initialization(self) -> None:
        """Leave initialization mode (nothing to do for an in-process core)."""

    # --- what the couplings call ----------------------------------------------------
    def begin_step(self) -> None:
        """Start a macro step: the current state is the one to come back to."""
        self.save_state()
        self._dirty = False

    def trial_step(self, forces: np.ndarray, time: float, step_size: float) -> Kinematics:
        """Step from the saved state with ``forces`` and return the kinematics.
        The first trial of a macro step needs no restore."""
        if self._dirty:
            self.restore_state()
            if self._held is not None:  # a restored FMU state holds the old inputs
                self.write_input_ramp(*self._held)
        kinematics = self.advance(forces, time, step_size)
        self._dirty = True
        return kinematics

    def advance(self, forces: np.ndarray, time: float, step_size: float) -> Kinematics:
        """Step with ``forces`` from where the subsystem is, with no rollback, and
        return the kinematics."""
        self.set_forces(forces)
        self.do_step(time, step_size)
        self._dirty = False
        return self.kinematics()

    #: communication steps per macro step of a subsystem exchanged once per step (its
    #: inputs held over them, or extrapolated where :meth:`input_ramp` says how:
    #: ``--substeps``)
    substeps = 1

    def exchange(self, time: float, step_size: float) -> np.ndarray:
        """One plain step (a subsystem in no joint: never saved nor restored), in
        :attr:`substeps` equal steps where there are several, then its outputs."""
        if self.substeps == 1:
            self.do_step(time, step_size)
        else:
            ramp = self.input_ramp(time)
            end, size, t = time + step_size, step_size / self.substeps, time
            for _ in range(self.substeps - 1):
                if ramp is not None:
                    ramp(t)
                self.do_step(t, size)
                t = t + size
            if ramp is not None:
                ramp(t)
            self.do_step(t, size_to(t, end, size))  # the last lands where one step would
        return self.read_outputs()

    def input_ramp(self, time: float):
        """For the substeps of a macro step from ``time`` (s): a function of a
        substep's start time (s) that sets the inputs there, or None: the inputs
        written at the macro step's start are held (here, always)."""
        return None

    def exchange_with(self, values, time: float, step_size: float) -> np.ndarray:
        """:meth:`write_inputs` of ``values`` (None: no input is connected), then
        :meth:`exchange`: a free subsystem's whole macro step in one call."""
        if values is not None:
            self.write_inputs(values)
        return self.exchange(time, step_size)

    def write_input_ramp(self, start: np.ndarray, end: np.ndarray, step_size: float) -> None:
        """Connected inputs that move from ``start`` (at the step's start) to ``end``
        (at its end) over the next step of ``step_size`` s: a subsystem that cannot
        interpolate inputs holds ``end``."""
        self.write_inputs(end)

    def hold_inputs(self, start, end, step_size: float) -> None:
        """Connected inputs ramping from ``start`` to ``end`` over the step, written now
        and after every restore of this step's trials (None: none held)."""
        self._held = None if end is None else (start, end, step_size)
        if end is not None:
            self.write_input_ramp(start, end, step_size)

    def trial_exchange(self, start, end, time: float, step_size: float) -> np.ndarray:
        """Step from the saved state (restored when a trial ran since) with connected
        inputs ramping from ``start`` to ``end`` (None: none), then the outputs."""
        if self._dirty:
            self.restore_state()
        if end is not None:
            self.write_input_ramp(start, end, step_size)
        self.do_step(time, step_size)
        self._dirty = True
        return self.read_outputs()

    def flexibility(self, forces: np.ndarray, time: float, step_size: float,
                    deltas: np.ndarray, base: Kinematics) -> list[np.ndarray]:
        """Interface flexibility by perturbation (eq. 4.45/4.46): for each glued
        dof k, re-step from the saved state with force k raised by ``deltas[k]``;
        returns [du/df, dv/df, da/df], each n x n (column k: response to force k).
        ``base`` is the response to ``forces`` itself."""
        n = len(forces)
        result = [np.zeros((n, n)) for _ in range(3)]
        for k in range(n):
            perturbed = forces.copy()
            perturbed[k] += deltas[k]
            response = self.trial_step(perturbed, time, step_size)
            for matrix, new, old in zip(result, response, base):
                if new is not None and old is not None:
                    matrix[:, k] = (new - old) / deltas[k]
        return result

    def start_flexibility(self, forces: np.ndarray, deltas: np.ndarray) -> np.ndarray:
        """d a / d f at the start time, without stepping (initialization mode): for
        each glued dof k, write the forces with entry k raised by ``deltas[k]`` and
        read the accelerations; the forces are written back at the end."""
        n = len(forces)
        base = self.kinematics()[2]
        result = np.zeros((n, n))
        for k in range(n):
            perturbed = np.array(forces, dtype=float)
            perturbed[k] += deltas[k]
            self.set_forces(perturbed)
            result[:, k] = (self.kinematics()[2] - base) / deltas[k]
        self.set_forces(forces)
        return result


class CoreSubsystem(Subsystem):
    """A physics core (:class:`dsim.fmus.interface.InterfaceCore`) driven in process,
    glued at the named subset of its interface.  Until
    :meth:`finish_initialization` it behaves as an FMU in initialization mode: the
    start accelerations follow the forces written."""

    SAVED = ("_saved",)

    def __init__(self, name: str, core, interface=None, start_time: float = 0.0):
        super().__init__()
        self.name = name
        self.core = core
        self.interface = tuple(core.interface if interface is None else interface)
        self._index = [core.interface.index(pair) for pair in self.interface]
        self._all_forces = np.zeros(len(core.interface))
        self._saved = None
        self._start_time = start_time
        self._initializing = True
        core.set_interface_forces(self._all_forces)
        core.initialize(start_time)
        self.output_names = tuple(core.outputs())

    def finish_initialization(self) -> None:
        self._initializing = False

    def save_state(self):
        self._saved = self._timed("get_state", self.core.get_state)

    def restore_state(self):
        self._timed("set_state", self.core.set_state, self._saved)

    def set_forces(self, forces):
        self._all_forces[self._index] = forces
        self.core.set_interface_forces(self._all_forces)
        if self._initializing:
            self.core.initialize(self._start_time)

    def do_step(self, time, step_size):
        self._timed("step", self.core.step, time, step_size)

    def kinematics(self):
        u, v, a = self.core.interface_kinematics()
        return u[self._index], v[self._index], a[self._index]

    def read_outputs(self):
        values = self.core.outputs()
        return np.array([values[name] for name in self.output_names], dtype=float)
