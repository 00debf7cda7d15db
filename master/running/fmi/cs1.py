"""An FMI 1.0 co-simulation FMU as a subsystem, through fmpy's FMI 1.0 binding.

FMI 1.0 has no FMU state: such a component takes part through causal connections
(one step per communication point) or in a joint of the explicit coupling; the plan
refuses it in an iterated role with one line naming it.  FMI 1.0 has no
initialization mode either: parameters and start values are set after
``fmiInstantiateSlave``, and ``fmiInitializeSlave`` runs when its outputs are first
needed (FMI 1.0 defines them only after it): the start values connections carry
reach an FMI 1.0 FMU as inputs of the initialized slave.
"""
from __future__ import annotations

import ctypes

from fmpy.fmi1 import FMU1Slave

from dsim.master.errors import SimulationError
from dsim.master.running.fmi.adapter import FmpyAdapter, accessor
from dsim.master.running.fmi.library import sharing
from dsim.master.running.fmi.messages import CALLBACKS1, STATUS


class CoSimulation1Subsystem(FmpyAdapter):
    """An FMI 1.0 co-simulation FMU."""

    prefix = "fmi"
    DO_STEP = "fmiDoStep"
    _do_step = None

    def _open(self, folder):
        return sharing(FMU1Slave)(guid=self.description.guid, unzipDirectory=folder,
                         modelIdentifier=self.description.coSimulation.modelIdentifier,
                         instanceName=self.name)

    def _instantiate(self):
        self.fmu.instantiate(functions=CALLBACKS1, loggingOn=True)
        if not self.fmu.component:
            raise RuntimeError("fmiInstantiateSlave returned no instance")

    def _enter_initialization(self):
        """FMI 1.0 has no initialization mode: values are set before fmiInitializeSlave."""

    def _getter(self, fmi_type):
        method = accessor(self.fmu, "get", fmi_type, "1.0")
        return lambda vrs, count: method(vrs)

    def _setter(self, fmi_type):
        return accessor(self.fmu, "set", fmi_type, "1.0")

    _initialized = False

    def _initialize(self) -> None:
        """fmiInitializeSlave, once, before the first output is read."""
        if not self._initialized:
            self._initialized = True
            self._checked("fmiInitializeSlave", self.fmu.initialize, self.spec.start_time,
                          self.spec.stop_time)

    def read_outputs(self):
        self._initialize()
        return super().read_outputs()

    def kinematics(self):
        self._initialize()
        return super().kinematics()

    def read_texts(self):
        self._initialize()
        return super().read_texts()

    def finish_initialization(self) -> None:
        self._initialize()
        self._initializing = False

    def save_state(self):
        raise SimulationError(f"component '{self.name}': an FMI 1.0 FMU cannot save its "
                              "state, so it cannot be iterated", time=self.time)

    def restore_state(self):
        self.save_state()

    def begin_step(self) -> None:
        """Nothing to save: the explicit coupling never rolls an FMI 1.0 FMU back."""
        self._dirty = False

    def _termination(self):
        """FMI 1.0 names no "terminated" status; an FMU that answers
        fmiGetBooleanStatus with FMI 2.0's kind (fmi2Terminated = 3) true ended the
        simulation (one that does not answer: a discarded step like any other)."""
        get = getattr(self.fmu.dll, self.description.coSimulation.modelIdentifier
                      + "_fmiGetBooleanStatus")
        get.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.POINTER(ctypes.c_char)]
        get.restype = ctypes.c_int
        value = ctypes.c_char(b"\x00")
        if get(self.fmu.component, 3, ctypes.byref(value)) != 0 or value.value == b"\x00":
            return None
        reached = ctypes.c_double(self.time)
        real = getattr(self.fmu.dll, self.description.coSimulation.modelIdentifier
                       + "_fmiGetRealStatus")
        real.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.POINTER(ctypes.c_double)]
        real.restype = ctypes.c_int
        return reached.value if real(self.fmu.component, 2, ctypes.byref(reached)) == 0 \
            else self.time

    def do_step(self, time, step_size):
        if self.ended_at is not None:
            self._raise_ended()
        self.time = time
        self._stepped = True
        if self._do_step is None:
            # fmpy 0.3.32 declares fmiDoStep's result a string, which crashes the
            # process on any status but fmiOK: bound here with its C type
            self._do_step = getattr(self.fmu.dll, self.description.coSimulation
                                    .modelIdentifier + "_fmiDoStep")
            self._do_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double,
                                      ctypes.c_char]
            self._do_step.restype = ctypes.c_int
        status = self._timed(self.DO_STEP, self._do_step, self.fmu.component, time, step_size,
                             b"\x01")
        if status > 1:
            self._fail(self.DO_STEP, f"fmiDoStep returned {STATUS.get(status, status)}", status,
                       time + step_size)
