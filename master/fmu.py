"""One FMI 2.0 co-simulation FMU instance as a :class:`~master.subsystem.Subsystem`.

Value references are resolved once; every read and write of a step is one
batched fmpy call; every FMI call is counted and timed per function name, and
an FMI error becomes a :class:`~master.errors.SimulationError` naming the
component and the function.  An FMU that fails while it is instantiated and
initialised with the scene's parameters is bad input (an
:class:`~master.errors.InputError`, exit 2) and the message is the error the FMU
logged, so that a user learns which parameter it refused.
"""
from __future__ import annotations

import atexit
import shutil
from pathlib import Path

import numpy as np
from fmpy import calloc, extract, free
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

from master.errors import InputError, SimulationError
from master.ports import PortDof, model_description, variables_by_name
from master.subsystem import Subsystem

_UNZIPPED: dict[Path, str] = {}


@atexit.register
def _remove_unzipped() -> None:
    for folder in _UNZIPPED.values():
        shutil.rmtree(folder, ignore_errors=True)


def unzipped(path: Path) -> str:
    """Folder holding the extracted FMU (shared by every instance of the file)."""
    if path not in _UNZIPPED:
        _UNZIPPED[path] = extract(str(path))
    return _UNZIPPED[path]


def can_save_state(path: Path) -> bool:
    """Whether the FMU declares canGetAndSetFMUstate (needed for rollback)."""
    cs = model_description(path).coSimulation
    return bool(cs and cs.canGetAndSetFMUstate)


#: instance name -> the last (fmi2Status, one-line message) pairs it logged
_MESSAGES: dict[str, list[tuple[int, str]]] = {}


def _log(environment, instance, status, category, message):
    name = (instance or b"").decode("utf-8", "replace")
    text = " ".join((message or b"").decode("utf-8", "replace").split())
    _MESSAGES[name] = (_MESSAGES.get(name, []) + [(int(status), text)])[-20:]


# One callbacks structure for the whole process, alive as long as it is: fmpy's proxy
# (which formats the variadic message) keeps a single global pointer to the logger.
_CALLBACKS = fmi2CallbackFunctions()
_CALLBACKS.logger = fmi2CallbackLoggerTYPE(_log)
_CALLBACKS.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
_CALLBACKS.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
try:
    from ctypes import byref as _byref

    from fmpy.logging import addLoggerProxy as _add_logger_proxy
    _add_logger_proxy(_byref(_CALLBACKS))
except Exception:  # pragma: no cover - the proxy is a compiled fmpy extra
    pass


def logged_error(instance: str) -> str:
    """The first error an instance logged (fmi2Error before fmi2Fatal), or ''."""
    messages = _MESSAGES.get(instance, [])
    for level in (3, 4):
        for status, text in messages:
            if status == level and text:
                return text
    return ""


class FmuSubsystem(Subsystem):
    """An FMU instance glued at ``port_dofs``, recording ``record`` outputs.
    ``location`` names the component in the scene file (for input errors)."""

    def __init__(self, name: str, path: Path, port_dofs: list[PortDof],
                 parameters: dict, record: list[str], start_time: float, stop_time: float,
                 location: str = ""):
        super().__init__()
        self.name = name
        self.path = Path(path)
        description = model_description(self.path)
        variables = variables_by_name(self.path)
        self.interface = tuple((p.port, p.dof) for p in port_dofs)
        self._force_vrs = [p.force for p in port_dofs]
        self._kinematic_vrs = [[getattr(p, kind) for p in port_dofs]
                               for kind in ("position", "velocity", "acceleration")]
        # u, v, a of every glued dof in one batched read; a kind the FMU lacks is None
        self._kinematic_present = [all(vr is not None for vr in vrs)
                                   for vrs in self._kinematic_vrs]
        self._kinematic_read = [vr for vrs, present in zip(self._kinematic_vrs,
                                                           self._kinematic_present)
                                if present for vr in vrs]
        self.output_names = tuple(record)
        self._record_vrs = [variables[n].valueReference for n in record]
        self._state = None
        self.time = start_time
        self.fmu = FMU2Slave(guid=description.guid, unzipDirectory=unzipped(self.path),
                             modelIdentifier=description.coSimulation.modelIdentifier,
                             instanceName=name)
        _MESSAGES.pop(name, None)
        self._location = location or name
        # until finish_initialization() the instance is in initialization mode, where a
        # failing call means the model refused the scene's parameters: bad input
        self._initializing = True
        self._call("fmi2Instantiate", lambda: self.fmu.instantiate(
            callbacks=_CALLBACKS, loggingOn=True))
        self._call("fmi2SetupExperiment", lambda: self.fmu.setupExperiment(
            startTime=start_time, stopTime=stop_time))
        self._call("fmi2EnterInitializationMode", self.fmu.enterInitializationMode)
        self._set_parameters(parameters, variables)

    def finish_initialization(self) -> None:
        """Leave initialization mode (the start forces set so far are the FMU's)."""
        self._call("fmi2ExitInitializationMode", self.fmu.exitInitializationMode)
        self._initializing = False

    def _call(self, label: str, function, *args):
        try:
            return self._timed(label, function, *args)
        except SimulationError:
            raise
        except Exception as error:  # fmpy raises FMICallException, ctypes errors
            if self._initializing:
                # No fmi2FreeInstance: after fmi2Fatal the standard allows no further
                # call, and pythonfmu (0.7) has already released its Python objects when
                # it reports one: freeing the instance would release them twice and
                # crash the process later.
                self.fmu.component = None
                reason = logged_error(self.name) or f"{label} failed: {error}"
                raise InputError(f"{self._location}: FMU {self.path.name} cannot be "
                                 f"initialised with these parameters: {reason}") from None
            reason = logged_error(self.name)
            raise SimulationError(f"component '{self.name}': {label} failed: {error}"
                                  + (f" ({reason})" if reason else ""),
                                  time=self.time) from None

    def _set_parameters(self, parameters: dict, variables: dict) -> None:
        setters = {"Real": self.fmu.setReal, "Integer": self.fmu.setInteger,
                   "Enumeration": self.fmu.setInteger, "Boolean": self.fmu.setBoolean,
                   "String": self.fmu.setString}
        for name, (_, value) in parameters.items():
            variable = variables[name]
            self._call("fmi2Set" + variable.type, setters[variable.type],
                       [variable.valueReference], [value])

    # --- Subsystem -------------------------------------------------------------------
    def save_state(self):
        # Free the held state before taking the next: asking an FMU to overwrite a state in
        # place (FMI 2.0 allows it) leaks the old one in pythonfmu, which always allocates.
        if self._state is not None:
            self._call("fmi2FreeFMUstate", self.fmu.freeFMUstate, self._state)
            self._state = None
        self._state = self._call("fmi2GetFMUstate", self.fmu.getFMUstate)

    def restore_state(self):
        self._call("fmi2SetFMUstate", self.fmu.setFMUstate, self._state)

    def set_forces(self, forces):
        if self._force_vrs:
            self._call("fmi2SetReal", self.fmu.setReal, self._force_vrs, list(forces))

    def do_step(self, time, step_size):
        self.time = time
        self._call("fmi2DoStep", lambda: self.fmu.doStep(
            currentCommunicationPoint=time, communicationStepSize=step_size))

    def kinematics(self):
        if not self.interface:  # an unglued component: nothing to read
            return (np.zeros(0),) * 3
        values = np.array(self._call("fmi2GetReal", self.fmu.getReal, self._kinematic_read))
        n = len(self.interface)
        result, start = [], 0
        for present in self._kinematic_present:
            if present:
                result.append(values[start:start + n])
                start += n
            else:
                result.append(None)
        return tuple(result)

    def outputs(self):
        if not self._record_vrs:
            return []
        return self._call("fmi2GetReal", self.fmu.getReal, self._record_vrs)

    def get_reals(self, vrs: list[int]) -> list[float]:
        """Read Real variables by value reference (causal connections)."""
        return self._call("fmi2GetReal", self.fmu.getReal, vrs)

    def set_reals(self, vrs: list[int], values: list[float]) -> None:
        """Write Real inputs by value reference (causal connections)."""
        self._call("fmi2SetReal", self.fmu.setReal, vrs, values)

    def terminate(self):
        if self.fmu.component is None:  # never instantiated, or failed beyond any call
            return
        try:
            if self._state is not None:
                self.fmu.freeFMUstate(self._state)
                self._state = None
            if not self._initializing:  # fmi2Terminate is for the step mode
                self.fmu.terminate()
        finally:
            self.fmu.freeInstance()
