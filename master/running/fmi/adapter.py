"""What the adapters of FMI 1.0 and 3.0 co-simulation and of Model Exchange share:
an FMU instance through fmpy's bindings of its version, with every call checked,
values read and written by dsim's variable kinds, and the glued ports' forces and
kinematics.

FMI 2.0 co-simulation, the hot path of every shipped scene, has its own adapter
(:mod:`.cs2`) that calls the library with ctypes arrays made once; the others go
through fmpy's convenience methods, which build their arguments per call (what the
benchmarks of docs/third_party.md measure).
"""
from __future__ import annotations

import numpy as np

from dsim.master.errors import InputError, SimulationError
from dsim.master.reading.fmi_description import describe
from dsim.master.reading.fmu_archive import unzipped
from dsim.master.running.fmi.checkpoint import Checkpoint
from dsim.master.running.fmi.messages import ask_for_logging, errors_logged, forget, logged_error
from dsim.master.running.fmi.spec import SubsystemSpec
from dsim.master.running.subsystem import Subsystem

#: the FMI types read and written with another type's functions, by FMI version:
#: FMI 1.0 and 2.0 Enumerations with the Integer ones, FMI 3.0's with the Int64 ones
ACCESSED_AS = {"1": {"Enumeration": "Integer"}, "2": {"Enumeration": "Integer"},
               "3": {"Enumeration": "Int64"}}


def accessor(fmu, verb: str, fmi_type: str, fmi_version: str):
    """fmpy's ``get`` or ``set`` (``verb``) method of ``fmi_type`` values on ``fmu``, an
    FMU of ``fmi_version`` ("1.0", "2.0", "3.0")."""
    return getattr(fmu, verb + ACCESSED_AS[fmi_version[0]].get(fmi_type, fmi_type))


class FmpyAdapter(Checkpoint, Subsystem):
    """An FMU instance of any FMI version, glued at its port dofs.  A subclass opens
    the instance (:meth:`_open`), steps it (:meth:`do_step`) and saves its state."""

    #: the FMI version's prefix of its function names, for messages ("fmi3", "fmi")
    prefix = "fmi2"
    #: the counters' names of a step and of a state save and restore (the statistics
    #: count them: :mod:`dsim.master.recording.statistics`)
    DO_STEP, GET_STATE, SET_STATE = "fmi2DoStep", "fmi2GetFMUstate", "fmi2SetFMUstate"

    def __init__(self, spec: SubsystemSpec):
        super().__init__()
        self.name = spec.name
        self.spec = spec
        self.path = spec.path
        self.description = describe(spec.path)
        self.variables = self.description.by_name
        self.interface = tuple((p.port, p.dof) for p in spec.port_dofs)
        self.output_names = tuple(spec.reads)
        self.time = spec.start_time
        self.fatal = False
        self._initializing = True
        self._stepped = False
        self._location = spec.location or spec.name
        forget(spec.name)
        ports = spec.port_dofs
        self._force_vrs = [p.force for p in ports]
        kinds = [[getattr(p, kind) for p in ports]
                 for kind in ("position", "velocity", "acceleration")]
        self._kinematic_vrs = [vrs if vrs and all(vr is not None for vr in vrs) else None
                               for vrs in kinds]
        self.fmu = None
        try:
            self.fmu = self._open(unzipped(spec.path))
        except InputError:
            raise
        except Exception as error:  # fmpy raises plain Exceptions for a missing library
            raise InputError(f"{self._location}: FMU {spec.path.name} cannot be loaded: "
                             f"{error}") from None
        self._checked("instantiate", self._instantiating, self._instantiated)
        self._checked("enter initialization mode", self._enter_initialization)
        for name, (_, value) in spec.parameters.items():
            self._checked(f"set {name}", self._set_values, [self.variables[name]], [value])

    def _instantiated(self) -> None:
        """Instantiate (:meth:`_instantiate`, with logging on), then ask for the FMU's
        warning and error log categories only (FMI 1.0 has no categories)."""
        self._instantiate()
        categories = self.description.log_categories if self.description.major >= 2 else ()
        ask_for_logging(self.fmu, self.name, categories, self.spec.fmu_log)

    # --- what a version provides ------------------------------------------------------
    def _open(self, folder: str):
        """fmpy's object for the extracted FMU (library loaded)."""
        raise NotImplementedError

    def _instantiate(self) -> None:
        raise NotImplementedError

    def _enter_initialization(self) -> None:
        raise NotImplementedError

    def _getter(self, fmi_type: str):
        """fmpy's getter of ``fmi_type`` values: (vrs, count) -> list."""
        raise NotImplementedError

    def _setter(self, fmi_type: str):
        """fmpy's setter of ``fmi_type`` values: (vrs, values)."""
        raise NotImplementedError

    # --- every call checked -----------------------------------------------------------
    def _checked(self, label: str, function, *args):
        """Call ``function`` (an fmpy method), counted and timed under ``label``; a
        failure is InputError while initialising (the instance freed), else
        SimulationError naming the component, the call and what the FMU logged; None
        when it failed in a way that is no error (an FMU that ended the simulation)."""
        result = None
        try:
            result = self._timed(label, function, *args)
        except (InputError, SimulationError):
            raise
        except Exception as error:  # fmpy's FMICallException, ctypes errors
            self._fail(label, " ".join(str(error).split()), getattr(error, "status", 3))
        if self._initializing and errors_logged(self.name):
            self._fail(label, "it logged an error and returned OK")
        return result

    # --- values by dsim's kinds -------------------------------------------------------
    def _get_values(self, variables) -> list:
        """The current values of ``variables`` (FMI 3.0 array elements read with their
        array), as Python numbers or strings."""
        result = [None] * len(variables)
        groups: dict = {}
        for i, variable in enumerate(variables):
            groups.setdefault((variable.fmi_type, variable.valueReference,
                               int(np.prod(variable.shape)) if variable.shape else 0),
                              []).append(i)
        by_type: dict = {}
        for (fmi_type, vr, size), indices in groups.items():
            by_type.setdefault(fmi_type, []).append((vr, size, indices))
        for fmi_type, entries in by_type.items():
            getter = self._getter(fmi_type)
            scalars = [e for e in entries if e[1] == 0]
            if scalars:
                values = getter([vr for vr, _, _ in scalars], len(scalars))
                for (_, _, indices), value in zip(scalars, values):
                    for i in indices:
                        result[i] = value
            for vr, size, indices in (e for e in entries if e[1]):
                values = getter([vr], size)
                for i in indices:
                    result[i] = values[variables[i].element]
        return result

    def _set_values(self, variables, values) -> None:
        """Set ``variables`` to ``values`` (an array element: its array is read, the
        element changed, the array written)."""
        by_type: dict = {}
        arrays: dict = {}
        for variable, value in zip(variables, values):
            if variable.shape:
                arrays.setdefault((variable.fmi_type, variable.valueReference),
                                  []).append((variable, value))
            else:
                by_type.setdefault(variable.fmi_type, []).append(
                    (variable.valueReference, _converted(variable, value)))
        for fmi_type, pairs in by_type.items():
            self._setter(fmi_type)([vr for vr, _ in pairs], [v for _, v in pairs])
        for (fmi_type, vr), pairs in arrays.items():
            size = int(np.prod(pairs[0][0].shape))
            current = list(self._getter(fmi_type)([vr], size))
            for variable, value in pairs:
                current[variable.element] = _converted(variable, value)
            self._setter(fmi_type)([vr], current)

    # --- Subsystem --------------------------------------------------------------------
    def set_forces(self, forces):
        if self._force_vrs:
            self._checked("set forces", self._setter("Float64" if self.prefix == "fmi3"
                                                     else "Real"),
                          self._force_vrs, [float(f) for f in forces])

    def _real_getter(self):
        return self._getter("Float64" if self.prefix == "fmi3" else "Real")

    def kinematics(self):
        n = len(self.interface)
        if not n:
            return (np.zeros(0),) * 3
        wanted = self.spec.kinds if self._stepped else (True, True, True)
        result = []
        for vrs, want in zip(self._kinematic_vrs, wanted):
            if vrs is None or not want:
                result.append(None)
            else:
                result.append(np.array(self._checked("read kinematics", self._real_getter(),
                                                     vrs, len(vrs)), dtype=float))
        return tuple(result)

    def read_outputs(self) -> np.ndarray:
        variables = [self.variables[n] for n in self.spec.reads]
        values = self._checked("read outputs", self._get_values, variables)
        return np.array([float(v) for v in values], dtype=float)

    def write_inputs(self, values) -> None:
        variables = [self.variables[n] for n in self.spec.writes]
        self._checked("write inputs", self._set_values, variables, list(values))

    def write_start_inputs(self, values) -> None:
        variables = [self.variables[n] for n in self.spec.start_writes]
        self._checked("write start values", self._set_values, variables, list(values))

    def set_values(self, names, values) -> None:
        self._checked("set values", self._set_values, [self.variables[n] for n in names],
                      list(values))

    def read_texts(self) -> list[str]:
        variables = [self.variables[n] for n in self.spec.text_reads]
        values = self._checked("read strings", self._get_values, variables) if variables \
            else []
        return [(v.decode("utf-8", "replace") if isinstance(v, bytes) else str(v or ""))
                for v in values]

    def write_texts(self, values) -> None:
        variables = [self.variables[n] for n in self.spec.text_writes]
        if variables:
            self._checked("write strings", self._set_values, variables,
                          [str(v) for v in values])

    def terminate(self):
        """Terminate and free the instance (nothing after Fatal); a failure here is the
        caller's to report."""
        if self.fmu is None or not self.fmu.component or self.fatal:
            self._gone()
            return
        forget(self.name)
        try:
            self._free_saved()
            if not self._initializing:
                self._terminate()
        except Exception as error:
            reason = logged_error(self.name)
            raise SimulationError(f"component '{self.name}': {error}"
                                  + (f" ({reason})" if reason else "")) from None
        finally:
            self.fmu.freeInstance()
            self.fmu.component = None
            self._gone()

    def _terminate(self) -> None:
        self.fmu.terminate()

    def _free_saved(self) -> None:
        """Free a saved FMU state, if the adapter holds one."""


def _converted(variable, value):
    """A value as the setter of the variable's type takes it."""
    if variable.type == "Real":
        return float(value)
    if variable.type in ("Integer", "Enumeration"):
        return int(round(float(value)))
    if variable.type == "Boolean":
        if isinstance(value, str):
            return value.strip().lower() in ("true", "1")
        return bool(value)
    return value if isinstance(value, str) else str(value)
