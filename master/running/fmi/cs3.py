"""An FMI 3.0 co-simulation FMU as a subsystem, through fmpy's FMI 3.0 binding.

Float64/Float32, the integer types, Boolean, String and Enumeration variables are
read and written by dsim's kinds (:mod:`.adapter`); array variables as their
elements (``name[i]`` columns).  The instance runs without event mode and without
early return (``eventModeUsed``, ``earlyReturnAllowed`` false): dsim steps from one
communication point to the next.  Rollback is the FMU state (``fmi3GetFMUState``)
where the FMU can get and set it.  An FMU that asks to end the run (``terminateSimulation``
from ``fmi3DoStep``) ends it normally: at the step's end when the step is complete, at its
start when the FMU returned early or discarded it (:class:`~dsim.master.errors.Terminated`).
"""
from __future__ import annotations

import ctypes

from fmpy.fmi3 import FMU3Slave, fmi3Boolean, fmi3Float64

from dsim.master.running.fmi.adapter import FmpyAdapter, accessor
from dsim.master.running.fmi.library import sharing
from dsim.master.running.fmi.messages import STATUS, logger3


class CoSimulation3Subsystem(FmpyAdapter):
    """An FMI 3.0 co-simulation FMU."""

    prefix = "fmi3"
    DO_STEP, GET_STATE, SET_STATE = "fmi3DoStep", "fmi3GetFMUState", "fmi3SetFMUState"

    def __init__(self, spec):
        self._state = None
        self._raw_step = None
        super().__init__(spec)

    def _open(self, folder):
        return sharing(FMU3Slave)(guid=self.description.guid, unzipDirectory=folder,
                         modelIdentifier=self.description.coSimulation.modelIdentifier,
                         instanceName=self.name)

    def _instantiate(self):
        self.fmu.instantiate(loggingOn=True, logMessage=logger3(self.name))

    def _enter_initialization(self):
        self.fmu.enterInitializationMode(startTime=self.spec.start_time,
                                         stopTime=self.spec.stop_time)

    def _getter(self, fmi_type):
        return accessor(self.fmu, "get", fmi_type, "3.0")

    def _setter(self, fmi_type):
        return accessor(self.fmu, "set", fmi_type, "3.0")

    def finish_initialization(self) -> None:
        self._checked("exit initialization mode", self.fmu.exitInitializationMode)
        self._initializing = False

    SAVED = ("_state",)

    def save_state(self):
        self._free_saved()
        self._state = self._checked(self.GET_STATE, self.fmu.getFMUState)

    def restore_state(self):
        self._checked(self.SET_STATE, self.fmu.setFMUState, self._state)
        # back before the end: the step is taken again (unless it ended at the start)
        self.ended_at = self._ended_at_start

    def _free_saved(self):
        if self._state is not None:
            try:
                self.fmu.freeFMUState(self._state)
            finally:
                self._state = None

    def checkpoint(self) -> dict:
        """The saved state as bytes (fmi3SerializeFMUState) and the time it is at."""
        data = self._checked("fmi3SerializeFMUState", self.fmu.serializeFMUState,
                             self._state)
        return {"fmu": bytes(data), "time": self.time, "stepped": self._stepped}

    def resume(self, checkpoint: dict) -> None:
        state = self._checked("fmi3DeserializeFMUState", self.fmu.deserializeFMUState,
                              checkpoint["fmu"])
        self._free_saved()
        self._state = state
        self.restore_state()
        self.time, self._stepped, self._dirty = checkpoint["time"], checkpoint["stepped"], False

    def do_step(self, time, step_size):
        if self.ended_at is not None:
            self._raise_ended()
        self.time = time
        self._stepped = True
        if self._raw_step is None:
            # fmpy's doStep raises on fmi3Discard, and the out-arguments that say the
            # FMU ended the simulation (terminateSimulation, lastSuccessfulTime) are lost
            # with it: the library's function, called with them here
            self._raw_step = self.fmu.dll["fmi3DoStep"]
            self._raw_step.restype = ctypes.c_int
            self._raw_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double,
                                       ctypes.c_bool] + [ctypes.c_void_p] * 4
        flags = [fmi3Boolean() for _ in range(3)]  # event, terminate, early return
        reached = fmi3Float64(time)
        status = self._timed(self.DO_STEP, self._raw_step, self.fmu.component, time,
                             step_size, True, *map(ctypes.byref, flags),
                             ctypes.byref(reached))
        _, terminate, early = (bool(flag.value) for flag in flags)
        if terminate and status <= 2:
            # a complete step (fmi3OK) ends at its end; an early return or a discarded
            # step where the FMU says it is
            self._ended(reached.value if (early or status == 2) else time + step_size,
                        time + step_size)
        elif status > 1:
            self._fail(self.DO_STEP, f"it returned fmi3{STATUS.get(status, status)}",
                       status, time + step_size)
