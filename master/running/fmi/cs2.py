"""One FMI 2.0 co-simulation FMU instance as a :class:`~dsim.master.running.subsystem.Subsystem`.

fmpy loads the shared library and binds the FMI functions; the calls of the time
loop go to those raw functions with value-reference and value arrays allocated
once per batch (fmpy's convenience getters build new ctypes arrays on every call,
which costs more than a small FMU's whole step).  Every call passes one
checkpoint that counts and times it per FMI function and turns a status above
fmi2Warning into a :class:`~dsim.master.errors.SimulationError` naming the component,
the function, the status and what the FMU logged.  An FMU that fails while it is
instantiated and initialised with the scene's parameters is bad input (an
:class:`~dsim.master.errors.InputError`, exit 2); so is one that logs an error there
while its call returns fmi2OK (what a pythonfmu FMU can do instead of returning
fmi2Error: :mod:`dsim.fmus.fmi_binding`).  An instance that failed there is freed at
once, unless it returned fmi2Fatal; the libraries stay loaded either way
(:mod:`dsim.master.tools.process_exit` says how a command then ends).
"""
from __future__ import annotations

import ctypes
import time as clock
from pathlib import Path

import numpy as np
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (FMU2Slave, fmi2FMUstate, fmi2LastSuccessfulTime, fmi2Terminated,
                       fmi2ValueReference)

from dsim.master.errors import InputError, SimulationError
from dsim.master.reading.fmi_description import describe
from dsim.master.reading.fmu_archive import unzipped
from dsim.master.running.fmi.checkpoint import Checkpoint
from dsim.master.running.fmi.input_slopes import InputSlopes, extrapolated_places
from dsim.master.running.fmi import library
from dsim.master.running.fmi.messages import STATUS as SHARED_STATUS
from dsim.master.running.fmi.messages import (CALLBACKS2, WARNING, ask_for_logging, errors_logged,
                                             forget, logged_error)
from dsim.master.running.fmi.spec import SubsystemSpec
from dsim.master.running.subsystem import Subsystem

#: the status names as FMI 2.0 spells them (fmi2OK, ...)
STATUS = {number: f"fmi2{name}" for number, name in SHARED_STATUS.items()}
#: FMI type -> (ctypes value type, get function, set function)
TYPES = {"Real": (ctypes.c_double, "fmi2GetReal", "fmi2SetReal"),
         "Integer": (ctypes.c_int, "fmi2GetInteger", "fmi2SetInteger"),
         "Enumeration": (ctypes.c_int, "fmi2GetInteger", "fmi2SetInteger"),
         "Boolean": (ctypes.c_int, "fmi2GetBoolean", "fmi2SetBoolean")}


class _Call:
    """One FMI function of one instance, called with ready-made ctypes arguments (no
    per-call argument conversion), counted and timed, its status checked."""

    __slots__ = ("function", "name", "owner", "calls", "seconds")

    def __init__(self, owner: "CoSimulation2Subsystem", name: str):
        # a function object of the library without fmpy's argtypes (their conversion
        # costs as much as the call): arguments are passed as ctypes objects
        self.function = library.raw(owner.fmu, name)
        self.name = name
        self.owner = owner
        self.calls = 0
        self.seconds = 0.0

    def __call__(self, *args) -> None:
        start = clock.perf_counter()
        status = self.function(self.owner.handle, *args)
        self.seconds += clock.perf_counter() - start
        self.calls += 1
        if status > WARNING and self.name == "fmi2DoStep":
            # the step's end, for an FMU that discards it because it ends the simulation
            self.check(status, args[0].value + args[1].value)
        else:
            self.check(status)

    def check(self, status: int, end: float | None = None) -> None:
        """Fail on a status above fmi2Warning (or an error logged while initializing);
        ``end``: the end of the step a discarded fmi2DoStep was asked for (s)."""
        if status > WARNING:
            self.owner._fail(self.name, f"it returned {STATUS.get(status, status)}", status,
                             end)
        # a pythonfmu FMU cannot return fmi2Error: it refuses its parameters by logging
        # one while the call returns fmi2OK (after initialization a log is only a log)
        if self.owner._initializing and errors_logged(self.owner.name):
            self.owner._fail(self.name, f"it logged an error and returned "
                                        f"{STATUS.get(status, status)}", 3)


def _references(owner: "CoSimulation2Subsystem", vrs) -> tuple:
    """(their count, the fmi2ValueReference array) of the value references ``vrs``:
    the same objects for every instance of the FMU file (the C side only reads them)."""
    vrs = tuple(vrs)
    return library.shared(owner.fmu, ("references", vrs), lambda: (
        ctypes.c_size_t(len(vrs)), (fmi2ValueReference * len(vrs))(*vrs)))


class _Batch:
    """Value references of one FMI type, a value array (and its numpy view), and the
    bound get and set calls, allocated once."""

    def __init__(self, owner: "CoSimulation2Subsystem", kind: str, vrs):
        ctype, get_name, set_name = TYPES[kind]
        self.kind = kind
        self.size = len(vrs)
        self.count, self.vrs = _references(owner, vrs)
        self.values = (ctype * self.size)()
        self.array = np.ctypeslib.as_array(self.values) if self.size else np.zeros(0)
        self.get = owner.call(get_name)
        self.set = owner.call(set_name)
        self._convert = {"Real": np.asarray, "Boolean": self._as_boolean}.get(kind, np.rint)

    def read(self) -> np.ndarray:
        """The variables' current values (a view, valid until the next read)."""
        if self.size:
            self.get(self.vrs, self.count, self.values)
        return self.array

    def write(self, values) -> None:
        """Set the variables (Integer rounded, Boolean true where non-zero)."""
        if self.size:
            self.array[:] = self._convert(values)
            self.set(self.vrs, self.count, self.values)

    @staticmethod
    def _as_boolean(values):
        return np.asarray(values) != 0


class _Strings:
    """String variables read or written in one call (fmi2GetString / fmi2SetString)."""

    def __init__(self, owner: "CoSimulation2Subsystem", vrs):
        self.size = len(vrs)
        self.count, self.vrs = _references(owner, vrs)
        self.values = (ctypes.c_char_p * self.size)()
        self.get = owner.call("fmi2GetString") if self.size else None
        self.set = owner.call("fmi2SetString") if self.size else None

    def read(self) -> list[str]:
        if not self.size:
            return []
        self.get(self.vrs, self.count, self.values)
        return [(v or b"").decode("utf-8", "replace") for v in self.values]

    def write(self, texts) -> None:
        if self.size:
            for i, text in enumerate(texts):
                self.values[i] = str(text).encode("utf-8")
            self.set(self.vrs, self.count, self.values)


def _by_kind(values: np.ndarray, kinds, n: int) -> tuple:
    """(u, v, a) of ``n`` glued dofs from one batched read ``values`` that holds the
    kinds ``kinds`` says are present, in that order: views of ``values``, None for a
    kind the FMU lacks."""
    result, start = [], 0
    for present in kinds:
        if present:
            result.append(values[start:start + n])
            start += n
        else:
            result.append(None)
    return tuple(result)


def _batches(owner, variables: list) -> tuple[list[_Batch], list[np.ndarray]]:
    """Group variables by FMI type: one batch per type, and for each batch where its
    values go in (or come from) the caller's flat vector."""
    groups: dict[str, list[int]] = {}
    for i, variable in enumerate(variables):
        groups.setdefault(variable.type, []).append(i)
    batches, places = [], []
    for kind, indices in groups.items():
        if kind not in TYPES:
            raise InputError(f"variable '{variables[indices[0]].name}' is of type {kind}, "
                             "which dsim cannot read or write yet")
        batches.append(_Batch(owner, kind, [variables[i].valueReference for i in indices]))
        places.append(np.array(indices, dtype=int))
    return batches, places


class CoSimulation2Subsystem(Checkpoint, Subsystem):
    """An FMU instance made from a :class:`SubsystemSpec`, glued at its port dofs."""

    def __init__(self, spec: SubsystemSpec):
        super().__init__()
        self.name = spec.name
        self.path = Path(spec.path)
        self.spec = spec
        description = describe(self.path)
        variables = description.by_name
        port_dofs = spec.port_dofs
        self.interface = tuple((p.port, p.dof) for p in port_dofs)
        self.output_names = tuple(spec.reads)
        self._state = None
        self._ramp_vrs = None
        self._stepped = False
        #: the FMU returned fmi2Fatal: no call may follow
        self.fatal = False
        self.time = spec.start_time
        self._location = spec.location or spec.name
        try:
            self.fmu = library.sharing(FMU2Slave)(
                guid=description.guid, unzipDirectory=unzipped(self.path),
                modelIdentifier=description.coSimulation.modelIdentifier,
                instanceName=spec.name)
        except Exception as error:  # fmpy raises plain Exceptions for a missing library
            raise InputError(f"{self._location}: FMU {self.path.name} cannot be loaded: "
                             f"{error}") from None
        self._calls: dict[str, _Call] = {}
        #: the causal kernel that calls this FMU's step (fused_step), or None
        self._kernel = None
        self.handle = None
        forget(spec.name)
        # until finish_initialization() the instance is in initialization mode, where a
        # failing call means the model refused the scene's parameters: bad input
        self._initializing = True
        self._call("fmi2Instantiate", lambda: self._instantiating(
            lambda: self.fmu.instantiate(callbacks=CALLBACKS2, loggingOn=True)))
        self._call("fmi2SetDebugLogging", lambda: ask_for_logging(
            self.fmu, spec.name, description.log_categories, spec.fmu_log))
        self.handle = ctypes.c_void_p(self.fmu.component)
        self._forces = _Batch(self, "Real", [p.force for p in port_dofs])
        # u, v, a of every glued dof in one batched read; a kind the FMU lacks is None
        kinds = [[getattr(p, kind) for p in port_dofs]
                 for kind in ("position", "velocity", "acceleration")]
        present = [bool(vrs) and all(vr is not None for vr in vrs) for vrs in kinds]
        needed = [p and wanted for p, wanted in zip(present, spec.kinds)]
        # (batch, which kinds it holds): all the FMU has, and the ones the joints need
        self._kinematics_all = (_Batch(self, "Real", [vr for vrs, p in zip(kinds, present)
                                                      if p for vr in vrs]), present)
        self._kinematics_needed = (_Batch(self, "Real", [vr for vrs, p in zip(kinds, needed)
                                                         if p for vr in vrs]), needed)
        self._reads, self._read_places = _batches(self, [variables[n] for n in spec.reads])
        self._read_values = np.zeros(len(spec.reads))
        # one Real batch in order (the common case) is read straight into place
        self._read_direct = (len(self._reads) == 1 and self._reads[0].kind == "Real")
        self._writes, self._write_places = _batches(self, [variables[n] for n in spec.writes])
        self._write_direct = (self._writes[0] if len(self._writes) == 1
                              and self._writes[0].kind == "Real" else None)
        self._start_writes = _batches(self, [variables[n] for n in spec.start_writes])
        #: its Real inputs extrapolated over its substeps (``spec.input_derivatives``)
        self._slopes = self._input_slopes(spec, variables) if spec.input_derivatives else None
        #: the inputs a table feeds, given their slope before each step (None: none;
        #: the plan sets them only where the FMU can interpolate inputs)
        self._table_vrs = None if spec.table_inputs is None else [
            variables[spec.writes[place]].valueReference
            for place in spec.table_inputs.places]
        self._texts_in = _Strings(self, [variables[n].valueReference for n in spec.text_reads])
        self._texts_out = _Strings(self, [variables[n].valueReference
                                          for n in spec.text_writes])
        self._do_step = self.call("fmi2DoStep")
        self._step_size = ctypes.c_double(0.0)
        self._get_state = self.call("fmi2GetFMUstate")
        self._set_state = self.call("fmi2SetFMUstate")
        self._free_state = self.call("fmi2FreeFMUstate")
        self._call("fmi2SetupExperiment", lambda: self.fmu.setupExperiment(
            startTime=spec.start_time, stopTime=spec.stop_time))
        self._call("fmi2EnterInitializationMode", self.fmu.enterInitializationMode)
        self._set_parameters(spec.parameters, variables)

    # --- the checkpoint every FMI call passes ----------------------------------------
    def _call(self, label: str, function, *args):
        """Call through fmpy's convenience layer (set-up, rare calls); None when the
        call failed in a way that is no error (an FMU that ended the simulation)."""
        result = None
        try:
            result = self._timed(label, function, *args)
        except (InputError, SimulationError):
            raise
        except FMICallException as error:
            self._fail(label, str(error), error.status)
        except Exception as error:  # fmpy's "Failed to instantiate", ctypes errors
            self._fail(label, str(error))
        if self._initializing and errors_logged(self.name):
            self._fail(label, "it logged an error and returned fmi2OK")
        return result

    def call(self, name: str) -> _Call:
        """The time loop's binding of FMI function ``name`` (one per name)."""
        if name not in self._calls:
            self._calls[name] = _Call(self, name)
        return self._calls[name]

    def _statistics(self) -> dict:
        counters = {name: list(entry) for name, entry in self.counters.items()}
        for name, call in self._calls.items():
            if call.calls:
                entry = counters.setdefault(name, [0, 0.0])
                entry[0] += call.calls
                entry[1] += call.seconds
        return counters

    def _set_parameters(self, parameters: dict, variables: dict) -> None:
        setters = {"Real": self.fmu.setReal, "Integer": self.fmu.setInteger,
                   "Enumeration": self.fmu.setInteger, "Boolean": self.fmu.setBoolean,
                   "String": self.fmu.setString}
        for name, (_, value) in parameters.items():
            variable = variables[name]
            self._call("fmi2Set" + variable.type, setters[variable.type],
                       [variable.valueReference], [value])

    def set_values(self, names, values) -> None:
        """Set variables by name between steps (a scenario's event), each call counted,
        timed and checked as the parameters' are."""
        variables = describe(self.path).by_name
        self._set_parameters({name: (None, value) for name, value in zip(names, values)},
                             variables)

    def finish_initialization(self) -> None:
        """Leave initialization mode (the start forces set so far are the FMU's)."""
        self._call("fmi2ExitInitializationMode", self.fmu.exitInitializationMode)
        self._initializing = False

    # --- Subsystem -------------------------------------------------------------------
    SAVED = ("_state",)

    def _free_saved(self) -> None:
        if self._state is not None:
            self._free_state(ctypes.byref(self._state))
            self._state = None

    def save_state(self):
        # Free the held state before taking the next: asking an FMU to overwrite a state in
        # place (FMI 2.0 allows it) leaks the old one in pythonfmu, which always allocates.
        self._free_saved()
        state = fmi2FMUstate()
        self._get_state(ctypes.byref(state))
        self._state = state

    def restore_state(self):
        self._set_state(self._state)
        # back before the end: the step is taken again (unless it ended at the start)
        self.ended_at = self._ended_at_start

    def checkpoint(self) -> dict:
        """The state saved by the last :meth:`save_state` as bytes
        (fmi2SerializeFMUstate), with what this adapter keeps beside it: what a fresh
        instance of the same FMU needs to go on from there (:meth:`resume`), in
        another process or on another machine (a lost Ray worker)."""
        data = self._call("fmi2SerializeFMUstate", self.fmu.serializeFMUstate, self._state)
        return {"fmu": bytes(data), "time": self.time, "stepped": self._stepped,
                # the inputs of the last macro steps (their slope over the substeps)
                "slopes": None if self._slopes is None else self._slopes.kept()}

    def resume(self, checkpoint: dict) -> None:
        """Go on from a :meth:`checkpoint` of another instance of this FMU (this one
        out of initialization mode): its state set and kept as the saved one."""
        state = self._call("fmi2DeSerializeFMUstate", self.fmu.deSerializeFMUstate,
                           checkpoint["fmu"])
        if self._state is not None:
            self._free_state(ctypes.byref(self._state))
        self._state = state
        self.restore_state()
        self.time, self._stepped, self._dirty = checkpoint["time"], checkpoint["stepped"], False
        if self._slopes is not None and checkpoint.get("slopes") is not None:
            self._slopes.keep(checkpoint["slopes"])

    def set_forces(self, forces):
        self._forces.write(forces)

    def _termination(self):
        if not self.fmu.getBooleanStatus(fmi2Terminated):
            return None
        return self.fmu.getRealStatus(fmi2LastSuccessfulTime)

    def do_step(self, time, step_size):
        if self.ended_at is not None:
            self._raise_ended()
        self.time = time
        self._stepped = True
        if self._table_vrs is not None:
            self._table_slopes(time, step_size)
        self._do_step(ctypes.c_double(time), ctypes.c_double(step_size), 1)

    def _table_slopes(self, time: float, step_size: float) -> None:
        """The slopes of the inputs a table feeds over the step from ``time`` by
        ``step_size`` (s), set as their first derivatives (:mod:`.table_inputs`)."""
        self._set_derivatives(self._table_vrs,
                              self.spec.table_inputs.slopes(time, step_size))

    def _set_derivatives(self, vrs, slopes) -> None:
        """Set the first derivatives (1/s) ``slopes`` of the Real inputs ``vrs``
        (fmi2SetRealInputDerivatives, order 1), the call counted and checked."""
        self._call("fmi2SetRealInputDerivatives", self.fmu.setRealInputDerivatives,
                   vrs, [1] * len(vrs), list(slopes))

    def exchange(self, time, step_size):
        if self.substeps != 1:  # several steps per macro step
            return Subsystem.exchange(self, time, step_size)
        if self.ended_at is not None:
            self._raise_ended()
        if self._table_vrs is not None:
            self._table_slopes(time, step_size)
        self.time = time
        if step_size != self._step_size.value:
            self._step_size = ctypes.c_double(step_size)
        self._do_step(ctypes.c_double(time), self._step_size, 1)
        if self._read_direct:
            return self._reads[0].read().copy()
        return self.read_outputs()

    def exchange_with(self, values, time, step_size):
        """A free subsystem's macro step: ``fmi2SetReal`` of its inputs, ``fmi2DoStep``,
        ``fmi2GetReal`` of its outputs, each counted, timed and checked as every call
        is, through few Python layers (a causal system in process steps through the
        backend's kernel instead; this is the path of the others)."""
        writes, reads = self._write_direct, self._reads[0] if self._read_direct else None
        if values is None or writes is None or reads is None or not writes.size \
                or not reads.size or self._initializing or self.substeps != 1 \
                or self._table_vrs is not None:  # (slopes: set in exchange)
            return super().exchange_with(values, time, step_size)
        self._read_after(reads, self._put_and_step(writes, values, time, step_size))
        return reads.array.copy()

    def _put_and_step(self, writes, values, time: float, step_size: float,
                      restore: bool = False) -> float:
        """A fused step's calls up to the step: ``fmi2SetFMUstate`` (``restore``),
        ``fmi2SetReal`` of ``values`` into ``writes``, ``fmi2DoStep`` from ``time`` by
        ``step_size`` (s), each counted, timed and its status checked (not initializing:
        a status is all there is to check); the clock reading after the step."""
        handle, put, step = self.handle, writes.set, self._do_step
        self.time = time
        if step_size != self._step_size.value:
            self._step_size = ctypes.c_double(step_size)
        writes.array[:] = values
        t0 = clock.perf_counter()
        if restore:
            call = self._set_state
            status = call.function(handle, self._state)
            t1 = clock.perf_counter()
            call.calls += 1
            call.seconds += t1 - t0
            if status > 1:
                call.check(status)
            t0 = t1
        status = put.function(handle, writes.vrs, writes.count, writes.values)
        t1 = clock.perf_counter()
        put.calls += 1
        put.seconds += t1 - t0
        if status > 1:
            put.check(status)
        status = step.function(handle, ctypes.c_double(time), self._step_size, 1)
        t2 = clock.perf_counter()
        step.calls += 1
        step.seconds += t2 - t1
        if status > 1:
            step.check(status, time + self._step_size.value)
        return t2

    def _read_after(self, reads, t0: float) -> None:
        """``fmi2GetReal`` of ``reads`` into its array, counted, timed from ``t0`` (the
        clock reading after the step) and its status checked."""
        get = reads.get
        status = get.function(self.handle, reads.vrs, reads.count, reads.values)
        get.seconds += clock.perf_counter() - t0
        get.calls += 1
        if status > 1:
            get.check(status)

    def fused_step(self, inputs, outputs, time, step_size, kernel):
        """This FMU's causal macro step for a kernel that runs many FMUs in one loop
        (:class:`~dsim.master.running.fmi.causal_kernel.CausalKernel`), or None when
        it cannot be fused (inputs or outputs of another type than Real, or in
        initialization mode): ``(fmi2SetReal call and its arguments or None, fmi2DoStep
        and its, fmi2GetReal and its or None)``, every argument a ctypes object made
        here once: ``fmi2SetReal`` sends the float64 array ``inputs`` (a view into the
        kernel's buffer, None: no input), ``fmi2GetReal`` writes into ``outputs``, and
        ``time`` and ``step_size`` are the kernel's ``ctypes.c_double`` of the step.
        The kernel times each call into its ``seconds`` and counts them when
        :meth:`statistics` asks (``kernel.sync``)."""
        writes = self._write_direct
        if self.substeps != 1 or self._table_vrs is not None:
            return None  # several steps per macro step, or slopes: the generic exchange
        if self._initializing or (inputs is not None and (
                writes is None or len(inputs) != writes.size)) or (len(outputs) and (
                not self._read_direct or len(outputs) != self._reads[0].size)):
            return None
        handle, put, get = self.handle, None, None
        if inputs is not None:
            buffer = (ctypes.c_double * writes.size).from_buffer(inputs)
            put = (writes.set, (handle, writes.vrs, writes.count, buffer))
        if len(outputs):
            reads = self._reads[0]
            buffer = (ctypes.c_double * reads.size).from_buffer(outputs)
            get = (reads.get, (handle, reads.vrs, reads.count, buffer))
        self._kernel = kernel
        return put, (self._do_step, (handle, time, step_size, 1)), get

    def statistics(self) -> dict:
        """FMI function -> [calls, seconds], set-up and time loop together."""
        if self._kernel is not None:  # the calls a causal kernel made and not yet counted
            self._kernel.sync()
        return self._statistics()

    def restore_counters(self, counters: dict) -> None:
        # the time loop's bindings count apart (_statistics adds them): from zero now
        super().restore_counters(counters)
        for call in self._calls.values():
            call.calls, call.seconds = 0, 0.0

    def trial_step(self, forces, time, step_size):
        """A glued trial in one call: ``fmi2SetFMUstate`` (when a trial ran since the
        save), ``fmi2SetReal`` of the forces, ``fmi2DoStep``, ``fmi2GetReal`` of the
        kinematics the joints need, each counted, timed and checked as every call is,
        without the Python layers between them (a Newton iteration makes one per glued
        FMU).  Anything unusual (held inputs, an FMU that ended, initialization) takes
        the general path."""
        writes = self._forces
        if self._held is not None or self.ended_at is not None or self._initializing \
                or not writes.size or self._table_vrs is not None:  # (slopes: do_step)
            return super().trial_step(forces, time, step_size)
        self._stepped = True
        reads, kinds = self._kinematics_needed
        t2 = self._put_and_step(writes, forces, time, step_size, restore=self._dirty)
        if reads.size:
            self._read_after(reads, t2)
        self._dirty = True
        return _by_kind(reads.array.copy(), kinds, len(self.interface))

    def kinematics(self):
        n = len(self.interface)
        if not n:  # an unglued component: nothing to read
            return (np.zeros(0),) * 3
        # until the first step (initialization, the start check) every kind is read
        batch, kinds = self._kinematics_needed if self._stepped else self._kinematics_all
        return _by_kind(batch.read().copy(), kinds, n)

    def read_outputs(self) -> np.ndarray:
        if self._read_direct:
            return self._reads[0].read().copy()
        for batch, places in zip(self._reads, self._read_places):
            self._read_values[places] = batch.read()
        return self._read_values.copy()

    def read_texts(self) -> list[str]:
        return self._texts_in.read()

    def write_texts(self, values) -> None:
        self._texts_out.write(values)

    def write_start_inputs(self, values) -> None:
        """Set what connections feed at initialization (``spec.start_writes`` order)."""
        for batch, places in zip(*self._start_writes):
            batch.write(values[places])

    def write_inputs(self, values) -> None:
        if self._slopes is not None:
            self._slopes.wrote(values)
        if self._write_direct:  # one Real batch: the values are in its order
            batch = self._write_direct
            batch.array[:] = values
            batch.set(batch.vrs, batch.count, batch.values)
            return
        for batch, places in zip(self._writes, self._write_places):
            batch.write(values[places])

    def write_input_ramp(self, start, end, step_size) -> None:
        """Connected inputs at the step's start and end: an FMU that can interpolate
        inputs (canInterpolateInputs) gets the start values and their slope
        (fmi2SetRealInputDerivatives, order 1); any other holds the end values."""
        if self._ramp_vrs is None:
            self._ramp_vrs = self._real_input_places()
        places, vrs = self._ramp_vrs
        if not places:
            self.write_inputs(end)
            return
        self.write_inputs(start)
        start = np.asarray(start, dtype=float)[places]
        self._set_derivatives(vrs, (np.asarray(end, dtype=float)[places] - start) / step_size)

    def _input_slopes(self, spec: SubsystemSpec, variables: dict) -> InputSlopes | None:
        """The extrapolation of the Real continuous inputs among ``spec.writes`` over
        the substeps (:mod:`.input_slopes`), or None where there is none."""
        places = extrapolated_places(variables, spec.writes)
        if not places:
            return None
        references = _references(self, [variables[spec.writes[i]].valueReference
                                        for i in places])
        return InputSlopes(places, references, self.call("fmi2SetReal"),
                           self.call("fmi2SetRealInputDerivatives"))

    def input_ramp(self, time):
        """The extrapolated inputs over the substeps of a macro step from ``time`` (s)
        (:mod:`.input_slopes`), or None: held."""
        return None if self._slopes is None else self._slopes.ramp(time)

    def _real_input_places(self) -> tuple[list[int], list[int]]:
        """Where the inputs that take derivatives are in ``spec.writes`` (the same rule
        as over substeps: :func:`.input_slopes.extrapolated_places`) and their value
        references, when the FMU can interpolate inputs (else none)."""
        description = describe(self.path)
        if not description.coSimulation.canInterpolateInputs:
            return [], []
        variables = description.by_name
        places = extrapolated_places(variables, self.spec.writes)
        return places, [variables[self.spec.writes[i]].valueReference for i in places]

    def terminate(self):
        """fmi2Terminate and fmi2FreeInstance (after an error too: FMI 2.0 allows both;
        after fmi2Fatal nothing); a failure here is the caller's to report, never to
        replace the error that ended the run."""
        if self.fmu.component is None or self.fatal:
            self._gone()
            return
        forget(self.name)  # what it logs now is about the cleanup
        try:
            if self._state is not None:
                self.fmu.freeFMUstate(self._state)
                self._state = None
            if not self._initializing:  # fmi2Terminate is for the step mode
                self.fmu.terminate()
        except Exception as error:  # fmpy raises FMICallException
            reason = logged_error(self.name)
            raise SimulationError(f"component '{self.name}': {error}"
                                  + (f" ({reason})" if reason else "")) from None
        finally:
            self.fmu.freeInstance()
            self._gone()
