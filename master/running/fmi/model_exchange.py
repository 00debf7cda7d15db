"""A Model Exchange FMU (FMI 2.0 or 3.0) as a subsystem: dsim integrates it between
communication points (:mod:`.integrator`) and handles its events as the standard says.

One communication step t -> t + H:

- the real inputs (glued port forces, connected inputs) move linearly from their
  values at t to the values written for t + H when they are *end-of-step* values
  (a joint's forces always are: the gluing solves for the force at t + H; a
  connection's are when the coupling iterates connections), and are held at the
  written value otherwise (a plain exchange writes the value the source had at t);
- the integrator runs segment by segment: up to the next time event (the FMU's
  ``nextEventTime``) or the step's end, stopping early at a state event (a sign
  change of an event indicator, located to the solver's tolerance); after each
  segment ``CompletedIntegratorStep`` may ask for a step event;
- at an event: event mode, the discrete-state iteration until the FMU needs no more,
  continuous-time mode, and the integrator restarts from the states the event left.

Rollback (the coupling's save and restore): the FMU state where the FMU can get and
set it (``canGetAndSetFMUstate``), with what the adapter itself keeps (time, the
inputs at the step's start, the next time event).  Without it the continuous states
are restored, which is exact for a model whose discrete states change only at
events: a trial step in which an event fired cannot be taken back, and fails with
one line naming the component and the time.
"""
from __future__ import annotations

import ctypes

import numpy as np
from fmpy.fmi2 import FMU2Model
from fmpy.fmi3 import FMU3Model

from dsim.master.errors import SimulationError
from dsim.master.running.fmi.adapter import FmpyAdapter, accessor
from dsim.master.running.fmi.integrator import SolverSettings, make_integrator
from dsim.master.running.fmi.library import raw, sharing
from dsim.master.running.fmi.messages import CALLBACKS2, STATUS, logger3

_DOUBLE_P = ctypes.POINTER(ctypes.c_double)


class ModelExchangeSubsystem(FmpyAdapter):
    """An FMI 2.0 or 3.0 Model Exchange FMU, integrated by dsim."""

    #: one integration over a communication step counts as the component's step
    DO_STEP = "integrate"

    def __init__(self, spec):
        self.fmi3 = spec.fmi_version.startswith("3")
        self.prefix = "fmi3" if self.fmi3 else "fmi2"
        self.GET_STATE, self.SET_STATE = (("fmi3GetFMUState", "fmi3SetFMUState") if self.fmi3
                                          else ("fmi2GetFMUstate", "fmi2SetFMUstate"))
        super().__init__(spec)
        description = self.description
        self.nx = len(description.states) if description.states else 0
        self.nz = description.numberOfEventIndicators
        self.settings = SolverSettings.of(spec.solver)
        self._x = np.zeros(self.nx)
        self._dx = np.zeros(self.nx)
        self._z = np.zeros(self.nz)
        self._nominal = np.ones(self.nx)
        # real inputs the master writes: forces first, then connected Real inputs
        real_writes = [n for n in spec.writes if self.variables[n].type == "Real"]
        self._input_vrs = list(self._force_vrs) + [self.variables[n].valueReference
                                                   for n in real_writes]
        self._input_places = [spec.writes.index(n) for n in real_writes]
        #: the inputs a table feeds: where each is among the ramped inputs (forces
        #: first), ramped over every step along the table (:mod:`.table_inputs`)
        self._table_places = None if spec.table_inputs is None else np.array(
            [len(self._force_vrs) + self._input_places.index(place)
             for place in spec.table_inputs.places], dtype=int)
        self._start = np.zeros(len(self._input_vrs))  # inputs at the step's start
        self._end = np.zeros(len(self._input_vrs))    # ... and written for its end
        self._ramp = False
        # Joints that compare positions only (fixed joints on the displacement measure)
        # take the forces held at their end value over the step: with the force ramped
        # from its start value the compatibility at the step's end weighs F_n twice as
        # much as F_n+1 (h^2/3 against h^2/6 for exact integration), and the joint force
        # sequence grows as (-2)^n.  Held, the step's end depends on F_n+1 alone.
        # Velocity and acceleration measures weigh the ends alike or F_n+1 only: ramped.
        self._hold_forces = tuple(spec.kinds) == (True, False, False)
        #: the coupling writes end-of-step values of connected inputs (iterated
        #: connections): they are interpolated too, as the forces always are
        self.interpolate_inputs = False
        self._step_start = spec.start_time
        self._step_size = 0.0
        self._next_event = None
        self._saved = None
        self._fmu_state = None
        self.can_save = bool(description.modelExchange.canGetAndSetFMUstate)
        self._events_in_step = 0
        self.integrator = None

    # --- FMI version specifics --------------------------------------------------------
    def _open(self, folder):
        kind = FMU3Model if self.fmi3 else FMU2Model
        return sharing(kind)(guid=self.description.guid, unzipDirectory=folder,
                    modelIdentifier=self.description.modelExchange.modelIdentifier,
                    instanceName=self.name)

    def _instantiate(self):
        if self.fmi3:
            self.fmu.instantiate(loggingOn=True, logMessage=logger3(self.name))
        else:
            self.fmu.instantiate(callbacks=CALLBACKS2, loggingOn=True)

    def _enter_initialization(self):
        spec = self.spec
        if self.fmi3:
            self.fmu.enterInitializationMode(startTime=spec.start_time,
                                             stopTime=spec.stop_time)
        else:
            self.fmu.setupExperiment(startTime=spec.start_time, stopTime=spec.stop_time)
            self.fmu.enterInitializationMode()

    def _getter(self, fmi_type):
        method = accessor(self.fmu, "get", fmi_type, self.spec.fmi_version)
        if self.fmi3:
            return method
        return lambda vrs, count: method(vrs)

    def _setter(self, fmi_type):
        return accessor(self.fmu, "set", fmi_type, self.spec.fmi_version)

    def _update_discrete_states(self):
        """One pass of the event iteration: (more passes needed, terminate, states
        changed, next event time or None)."""
        if self.fmi3:
            more, stop, _, changed, defined, when = self.fmu.updateDiscreteStates()
        else:
            more, stop, _, changed, defined, when = self.fmu.newDiscreteStates()
        return more, stop, changed, (when if defined else None)

    # --- the ODE view the integrator drives -------------------------------------------
    # The integrator calls these a dozen times per communication step: they go to the
    # library's functions bound once with ready-made pointers (fmpy's methods convert
    # their arguments on every call, which costs more than a small model's equations).
    def _bind_raw(self) -> None:
        prefix = self.prefix
        names = {"time": f"{prefix}SetTime", "set_x": f"{prefix}SetContinuousStates",
                 "get_x": f"{prefix}GetContinuousStates",
                 "dx": "fmi3GetContinuousStateDerivatives" if self.fmi3
                 else "fmi2GetDerivatives",
                 "z": f"{prefix}GetEventIndicators",
                 "inputs": "fmi3SetFloat64" if self.fmi3 else "fmi2SetReal"}
        self._raw = {}
        for key, name in names.items():
            self._raw[key] = (raw(self.fmu, name), name)
        self._handle = ctypes.c_void_p(self.fmu.component)
        self._xin = np.zeros(self.nx)
        self._pointers = {key: array.ctypes.data_as(_DOUBLE_P) for key, array in (
            ("x", self._x), ("xin", self._xin), ("dx", self._dx), ("z", self._z))}
        count = len(self._input_vrs)
        self._input_values = np.zeros(count)
        self._input_refs = (ctypes.c_uint * count)(*self._input_vrs)
        self._input_pointer = self._input_values.ctypes.data_as(_DOUBLE_P)

    def _raw_call(self, key: str, *args) -> None:
        function, name = self._raw[key]
        status = function(self._handle, *args)
        if status > 1:
            self._fail(name, f"it returned {STATUS.get(status, status)}", status)

    def _set_inputs(self, values) -> None:
        self._input_values[:] = values
        count = len(self._input_vrs)
        if self.fmi3:
            self._raw_call("inputs", self._input_refs, ctypes.c_size_t(count),
                           self._input_pointer, ctypes.c_size_t(count))
        else:
            self._raw_call("inputs", self._input_refs, ctypes.c_size_t(count),
                           self._input_pointer)

    def set_time(self, t: float) -> None:
        """Set the FMU's time and the inputs interpolated to it."""
        self._raw_call("time", ctypes.c_double(t))
        if self._ramp:
            weight = (t - self._step_start) / self._step_size
            self._set_inputs(self._start + weight * (self._end - self._start))

    def get_x(self) -> np.ndarray:
        self._raw_call("get_x", self._pointers["x"], ctypes.c_size_t(self.nx))
        return self._x

    def set_x(self, x) -> None:
        self._xin[:] = x
        self._raw_call("set_x", self._pointers["xin"], ctypes.c_size_t(self.nx))

    def get_dx(self) -> np.ndarray:
        self._raw_call("dx", self._pointers["dx"], ctypes.c_size_t(self.nx))
        return self._dx

    def get_z(self) -> np.ndarray:
        if self.nz:
            self._raw_call("z", self._pointers["z"], ctypes.c_size_t(self.nz))
        return self._z

    def nominals(self) -> np.ndarray:
        if self.nx:
            self.fmu.getNominalsOfContinuousStates(self._nominal.ctypes.data_as(_DOUBLE_P),
                                                   self.nx)
        return self._nominal

    # --- modes and events -------------------------------------------------------------
    def finish_initialization(self) -> None:
        """Leave initialization mode, run the event iteration the standard asks for
        there, and enter continuous-time mode."""
        self._checked("exit initialization mode", self.fmu.exitInitializationMode)
        self._initializing = False
        # FMI 2.0 and 3.0 alike: leaving initialization mode enters event mode
        self._checked("event iteration", self._event_iteration)
        self._start = self._current_inputs()
        self._end = self._start.copy()
        self._bind_raw()
        self.integrator = make_integrator(self, self.settings)

    def _current_inputs(self) -> np.ndarray:
        if not self._input_vrs:
            return np.zeros(0)
        getter = self.fmu.getFloat64 if self.fmi3 else (lambda vrs, n: self.fmu.getReal(vrs))
        return np.array(getter(self._input_vrs, len(self._input_vrs)), dtype=float)

    def _event_iteration(self) -> None:
        """From event mode: update discrete states until the FMU needs no more pass,
        then continuous-time mode."""
        for _ in range(1000):
            more, stop, _, next_event = self._update_discrete_states()
            if stop and self._stepped:
                # the FMU ends the simulation at an event of a step: the step ends it
                # (:meth:`_integrate`)
                self._stop_asked = True
                break
            if stop:  # at the start, leaving initialization: the run ends normally
                # there, its first row kept (the first step raises Terminated)
                self.ended_at = self._ended_at_start = self.time
                break
            if not more:
                break
        else:
            raise SimulationError(f"component '{self.name}': its event iteration did not "
                                  f"settle in 1000 passes at t = {self.time:g} s",
                                  time=self.time)
        self._next_event = next_event
        self.fmu.enterContinuousTimeMode()

    def _handle_event(self, t: float) -> None:
        self.fmu.enterEventMode()
        self._event_iteration()
        self._events_in_step += 1
        if self.integrator is not None:
            self.integrator.reset(t)

    # --- Subsystem --------------------------------------------------------------------
    def set_values(self, names, values) -> None:
        """Set variables between steps: a continuous Real input in continuous-time mode;
        anything else (a discrete input, a tunable parameter) in event mode, as FMI asks,
        with the event iteration after it (the integrator restarts there)."""
        variables = [self.variables[n] for n in names]
        if self._initializing or all(v.causality == "input" and v.type == "Real" and
                                     v.variability == "continuous" for v in variables):
            super().set_values(names, values)
            return
        self._checked("enter event mode", self.fmu.enterEventMode)
        self._checked("set values", self._set_values, variables, list(values))
        self._checked("event iteration", self._event_iteration)
        if self.integrator is not None:
            self.integrator.reset(self.time)

    def set_forces(self, forces):
        n = len(self._force_vrs)
        if not n:
            return
        if self._initializing:
            super().set_forces(forces)
            return
        self._end[:n] = forces

    def write_inputs(self, values) -> None:
        super().write_inputs(values)
        if not self._initializing and self._input_places:
            values = np.asarray(values, dtype=float)
            n = len(self._force_vrs)
            self._end[n:] = values[self._input_places]
            if not self.interpolate_inputs:  # a value the source had at t: held
                self._start[n:] = self._end[n:]

    def write_input_ramp(self, start, end, step_size) -> None:
        """Connected inputs at the step's start and end: the integrator interpolates."""
        self.write_inputs(end)
        n = len(self._force_vrs)
        if self._input_places:
            self._start[n:] = np.asarray(start, dtype=float)[self._input_places]

    SAVED = ("_fmu_state", "_saved")

    def save_state(self):
        self._free_saved()
        if self.can_save:
            self._fmu_state = self._checked(self.GET_STATE, self.fmu.getFMUState
                                            if self.fmi3 else self.fmu.getFMUstate)
        x = self._timed("save continuous states", self.get_x).copy() if self.nx and \
            not self.can_save else (self.get_x().copy() if self.nx else None)
        self._saved = (self.time, x, self._start.copy(), self._next_event)
        self._events_in_step = 0

    def restore_state(self):
        time, x, start, next_event = self._saved
        # back before the end (unless the FMU ended the simulation at the start)
        self.ended_at, self._stop_asked = self._ended_at_start, False
        if self.can_save:
            setter = self.fmu.setFMUState if self.fmi3 else self.fmu.setFMUstate
            self._checked(self.SET_STATE, setter, self._fmu_state)
        else:
            if self._events_in_step:
                raise SimulationError(
                    f"component '{self.name}': an event in an iterated step at "
                    f"t = {self.time:g} s changed its discrete states, and the FMU cannot "
                    "save its state (canGetAndSetFMUstate is false): dsim can restore only "
                    "its continuous states", time=self.time)
            self.fmu.setTime(time)
            if x is not None:
                self._timed("restore continuous states", self.set_x, x)
        self.time = time
        self._start = start.copy()
        self._next_event = next_event
        self._events_in_step = 0

    def _free_saved(self) -> None:
        if self._fmu_state is not None:
            free = self.fmu.freeFMUState if self.fmi3 else self.fmu.freeFMUstate
            try:
                free(self._fmu_state)
            finally:
                self._fmu_state = None

    def checkpoint(self) -> dict:
        """The saved FMU state as bytes (fmi2SerializeFMUstate, fmi3SerializeFMUState)
        with what dsim's integration keeps beside it: the time, the inputs at the
        step's start and those written for its end, the next time event."""
        if not self.can_save:
            raise NotImplementedError(f"component '{self.name}': its FMU cannot save its "
                                      "state (canGetAndSetFMUstate is false)")
        data = self._checked(f"{self.prefix}SerializeFMU{'S' if self.fmi3 else 's'}tate",
                             self.fmu.serializeFMUState, self._fmu_state)
        time, x, start, next_event = self._saved
        return {"fmu": bytes(data), "time": time, "x": x, "start": start,
                "next_event": next_event, "end": self._end.copy(), "stepped": self._stepped}

    def resume(self, checkpoint: dict) -> None:
        state = self._checked(f"{self.prefix}DeserializeFMU{'S' if self.fmi3 else 's'}tate",
                              self.fmu.deserializeFMUState, checkpoint["fmu"])
        self._free_saved()
        self._fmu_state = state
        self._saved = (checkpoint["time"], checkpoint["x"],
                       np.array(checkpoint["start"], dtype=float), checkpoint["next_event"])
        self.restore_state()
        self._end = np.array(checkpoint["end"], dtype=float)
        self._stepped, self._dirty = checkpoint["stepped"], False

    def restore_counters(self, counters: dict) -> None:
        counters = dict(counters)  # the integrator counts its own evaluations
        evaluations = counters.pop("right-hand side evaluations", None)
        super().restore_counters(counters)
        if evaluations is not None and self.integrator is not None:
            self.integrator.evaluations = evaluations[0]

    _stop_asked = False

    def do_step(self, time, step_size):
        if self.ended_at is not None:
            self._raise_ended()
        self._stepped = True
        self._checked(self.DO_STEP, self._integrate, time, step_size)

    def _integrate(self, time: float, step_size: float) -> None:
        stop = time + step_size
        self._step_start, self._step_size = time, step_size
        if self._hold_forces:  # the start values are the end values: no ramp
            self._start[:len(self._force_vrs)] = self._end[:len(self._force_vrs)]
        if self._table_places is not None:  # along the table to the step's end
            start, end = self.spec.table_inputs.ends(time, step_size)
            self._start[self._table_places] = start
            self._end[self._table_places] = end
        self._ramp = bool(len(self._input_vrs)) and not np.array_equal(self._start, self._end)
        if not self._ramp and len(self._input_vrs):
            self._set_inputs(self._end)
        self.set_time(time)
        self.integrator.reset(time)
        t = time
        guard = 0
        while t < stop:
            guard += 1
            if guard > 100000:
                raise SimulationError(f"component '{self.name}': more than 100000 events "
                                      f"in one step at t = {t:g} s (chattering)", time=t)
            target = stop
            if self._next_event is not None and t <= self._next_event < stop:
                target = self._next_event
            if self.nx or self.nz:
                t, state_event = self.integrator.advance(t, target)
            else:
                t, state_event = target, False
            self.set_time(t)
            self.time = t
            step_event, terminate = self.fmu.completedIntegratorStep()
            time_event = self._next_event is not None and t >= self._next_event
            if (state_event or time_event or step_event) and not terminate:
                self._handle_event(t)
            if terminate or self._stop_asked:
                # ended by the FMU: at the step's end the step is kept, before it the
                # run ends at the step's start (Checkpoint._ended raises then)
                self._ended(t, stop)
                break
            if t >= target and target == stop:
                break
        self.time = stop
        self._start = self._end.copy()
        self._ramp = False

    def statistics(self) -> dict:
        counters = super().statistics()
        if self.integrator is not None:
            counters["right-hand side evaluations"] = [self.integrator.evaluations, 0.0]
        return counters
