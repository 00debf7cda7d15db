"""An FMI 3.0 co-simulation FMU as a subsystem, through fmpy's FMI 3.0 binding.

Float64/Float32, the integer types, Boolean, String and Enumeration variables are
read and written by dsim's kinds (:mod:`.adapter`); array variables as their
elements (``name[i]`` columns).  The instance runs without event mode and without
early return (``eventModeUsed``, ``earlyReturnAllowed`` false): dsim steps from one
communication point to the next.  Rollback is the FMU state (``fmi3GetFMUState``)
where the FMU can get and set it.  An FMU that asks to end the run (``terminateSimulation``
from ``fmi3DoStep``) ends it at that step, its rows kept.
"""
from __future__ import annotations

from fmpy.fmi3 import FMU3Slave

from dsim.master.errors import SimulationError
from dsim.master.running.fmi.adapter import FmpyAdapter
from dsim.master.running.fmi.library import sharing
from dsim.master.running.fmi.messages import logger3


class CoSimulation3Subsystem(FmpyAdapter):
    """An FMI 3.0 co-simulation FMU."""

    prefix = "fmi3"
    DO_STEP, GET_STATE, SET_STATE = "fmi3DoStep", "fmi3GetFMUState", "fmi3SetFMUState"

    def __init__(self, spec):
        self._state = None
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
        return getattr(self.fmu, "get" + {"Enumeration": "Int64"}.get(fmi_type, fmi_type))

    def _setter(self, fmi_type):
        return getattr(self.fmu, "set" + {"Enumeration": "Int64"}.get(fmi_type, fmi_type))

    def finish_initialization(self) -> None:
        self._checked("exit initialization mode", self.fmu.exitInitializationMode)
        self._initializing = False

    def save_state(self):
        self._free_saved()
        self._state = self._checked(self.GET_STATE, self.fmu.getFMUState)

    def restore_state(self):
        self._checked(self.SET_STATE, self.fmu.setFMUState, self._state)

    def _free_saved(self):
        if self._state is not None:
            try:
                self.fmu.freeFMUState(self._state)
            finally:
                self._state = None

    def do_step(self, time, step_size):
        self.time = time
        self._stepped = True
        _, terminate, _, _ = self._checked(self.DO_STEP, self.fmu.doStep, time, step_size)
        if terminate:
            raise SimulationError(f"component '{self.name}': the FMU asked to end the "
                                  f"simulation at t = {time + step_size:g} s",
                                  time=time + step_size)
