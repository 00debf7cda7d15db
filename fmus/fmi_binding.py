"""What every pythonfmu wrapper of an :class:`~dsim.fmus.interface.InterfaceCore` shares.

pythonfmu before 0.7 found the model class by a regular expression that wants
``class Name(Fmi2Slave):`` verbatim, so the shared part is not a base class; it is
this binding object, which a wrapper creates in ``__init__`` and calls from its FMI
callbacks.  A wrapper may declare its variables once for its class
(:class:`Variable`, :func:`port_variables`) instead of registering them per
instance.  It registers the port variables of DESIGN.md (``P.f_x`` input,
``P.u_x``/``P.v_x``/``P.a_x`` outputs), answers batched reads and writes of them,
computes outputs when they are read, and implements the complete FMU state (the
core's numerical state plus inputs).

In initialization mode the port outputs follow the force inputs (FMI 2.0 lets a
master read calculated outputs there): the core is built at the first read, and
every force written recomputes the initial accelerations.  A master can so find
start forces that make the initial accelerations compatible before the first step.

Parameters the core refuses (a ``ValueError`` from ``build_core``) must leave an
instance the master can still free.  pythonfmu 0.7 answers every Python exception,
in any callback, with fmi2Fatal, and has already released the instance's Python
objects when it does (its fmi2FreeInstance would release them a second time), so
the refusal is never raised: it is logged with status fmi2Error, the callback
returns normally, and a step asked of the refused instance is discarded.  (pythonfmu
has no way for Python code to return fmi2Error: a return value of
``exit_initialization_mode`` or of a setter is ignored, ``False`` from ``do_step``
gives fmi2Discard.)
"""
from __future__ import annotations

import abc
import pickle

import numpy as np
from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Status

from .interface import InterfaceCore

KINEMATIC_PREFIXES = ("u", "v", "a")
#: pythonfmu variable type -> how Fmi2Slave's getters convert a value of it
CONVERT = {Real: float, Integer: int, Boolean: bool, String: str}


class Variable:
    """One FMI variable of a wrapper class, declared once for all its instances: its
    pythonfmu type (``Real``, ``Integer``, ...), name and attributes, and how it is read
    (``get(slave)``) and written (``set(slave, value)``, None: not settable) in one
    instance.

    pythonfmu registers variables per instance, each a ``ScalarVariable`` with a getter
    and a setter closed over the instance: 95 variables and about 110 kB for each
    SpringMass instance (a chain of 10,000 held 1.1 GB of them).  At run time
    pythonfmu's C side calls only the slave's methods (``get_real``, ``set_integer``,
    ...), never its variables; a class that declares its variables (``variables``, see
    :func:`glued_slave`) so answers from one table made per class, and registers
    pythonfmu's variables only for the model description, when the FMU is built.
    """

    __slots__ = ("kind", "name", "options", "get", "set")

    def __init__(self, kind, name: str, get, set=None, **options):
        self.kind, self.name, self.get, self.set, self.options = kind, name, get, set, options

    def bound(self, slave):
        """pythonfmu's variable of this one in ``slave`` (to register it there)."""
        get, put = self.get, self.set
        return self.kind(self.name, getter=lambda: get(slave),
                         setter=None if put is None else (lambda value: put(slave, value)),
                         **self.options)


def port_variables(interface, output_names=()) -> list[Variable]:
    """The variables of :class:`CoreBinding`, in its order: the force input of every port
    dof (``P.f_x``), then its position, velocity and acceleration outputs (``P.u_x``,
    ``P.v_x``, ``P.a_x``), then the named outputs; each reads the slave's ``binding``."""
    interface, n = tuple(interface), len(interface)
    variables = [Variable(
        Real, f"{port}.f_{dof}", causality=Fmi2Causality.input,
        variability=Fmi2Variability.continuous, start=0.0,
        description="force (moment for r*) applied at the port, N or N.m",
        get=lambda slave, i=i: float(slave.binding.forces[i]),
        set=lambda slave, value, i=i: slave.binding._set_forces([i], [value]))
        for i, (port, dof) in enumerate(interface)]
    for row, (prefix, what) in enumerate(zip(
            KINEMATIC_PREFIXES, ("position", "velocity", "acceleration"))):
        variables += [Variable(
            Real, f"{port}.{prefix}_{dof}", causality=Fmi2Causality.output,
            variability=Fmi2Variability.continuous, description=f"global {what} of the port",
            get=lambda slave, k=(row + 1) * n + i, row=row: slave.binding._readable((row,))[k])
            for i, (port, dof) in enumerate(interface)]
    variables += [Variable(Real, name, causality=Fmi2Causality.output,
                           variability=Fmi2Variability.continuous,
                           get=lambda slave, k=4 * n + j: slave.binding._readable((3,))[k])
                  for j, name in enumerate(output_names)]
    return variables


#: (wrapper class, interface, output names) -> (value reference -> place in the
#: readable values, the batch cache): one per class whose variables are declared
_LAYOUTS: dict[tuple, tuple] = {}


def _place_table(references) -> np.ndarray:
    """Value reference -> place in the readable values (-1: not a port or output)."""
    place = np.full(max(references, default=-1) + 1, -1, dtype=int)
    place[references] = np.arange(len(references))
    return place


#: a batch whose core's reader was not asked for yet
_UNASKED = object()


class CoreBinding:
    """Port variables, output cache and state of one wrapped core.

    The master reads and writes port variables in batches (every glued dof at once);
    pythonfmu calls one Python getter per variable.  The binding therefore answers a
    batch of port and output variables itself (:meth:`get_reals`, :meth:`set_reals`):
    one table lookup and one numpy gather, and one ``set_interface_forces`` per
    batch of forces.  Outputs are computed when they are read, not after every step
    and restore (a trial step whose outputs nobody reads costs nothing extra).
    """

    #: (value references, what :meth:`places` found for them) of the last batch read
    #: and of the last batch of forces written
    _last_get = _last_set = (None, None)

    def __init__(self, slave, interface, output_names=()):
        self.slave = slave
        self.interface = tuple(interface)
        self.core: InterfaceCore | None = None
        #: why the parameters make no core (logged at fmi2Error), None until then
        self.refusal: str | None = None
        self.initializing = False
        self.start_time = 0.0
        n = len(self.interface)
        self.forces = np.zeros(n)
        self.output_names = tuple(output_names)
        # sections of the readable values out of date: positions, velocities,
        # accelerations, named outputs (each computed only when read)
        self._stale = [True] * 4
        # readable values: forces, then u, v, a per dof, then the named outputs
        self._values = np.zeros(4 * n + len(self.output_names))
        #: id of a batch :meth:`places` found -> this core's reader of it (None: none)
        self._readers: dict[int, object] = {}
        declared = getattr(type(slave), "declared", None)
        if declared is None:  # a wrapper that registers its variables per instance
            references = []
            for variable in port_variables(self.interface, self.output_names):
                bound = variable.bound(slave)
                slave.register_variable(bound, nested=False)
                references.append(bound.value_reference)
            self._place = _place_table(references)
            self._batches: dict[tuple, tuple | None] = {}
        else:  # declared once per class: so are the places, and the batches they make
            key = (type(slave), self.interface, self.output_names)
            if key not in _LAYOUTS:
                by_name = {variable.name: vr for vr, variable in declared.items()}
                _LAYOUTS[key] = (_place_table([by_name[variable.name] for variable in
                                               port_variables(*key[1:])]), {})
            self._place, self._batches = _LAYOUTS[key]

    # --- batched access (the master's calls) ----------------------------------------
    def places(self, vrs, forces_only: bool = False):
        """(places of value references in the readable values, the sections they fall
        in), or None when one of them is not a port variable or output (or,
        ``forces_only``, not a force input)."""
        # a master asks for the same batch call after call: compare it with the last
        # one of its kind before building and hashing a key
        last = self._last_set if forces_only else self._last_get
        if last[0] == vrs:
            return last[1]
        key = (tuple(vrs), forces_only)
        if key not in self._batches:
            vrs = np.asarray(vrs, dtype=int)
            n = len(self.interface)
            limit = n if forces_only else len(self._values)
            found = None
            if vrs.size and vrs.min() >= 0 and vrs.max() < len(self._place):
                places = self._place[vrs]
                if places.min() >= 0 and places.max() < limit:
                    sections = tuple(sorted({min((int(p) - n) // n, 3) if n else 3
                                             for p in places if p >= n}))
                    found = (places, sections)
            self._batches[key] = found
        found = self._batches[key]
        if forces_only:
            self._last_set = (list(vrs), found)
        else:
            self._last_get = (list(vrs), found)
        return found

    def get_reals(self, found) -> list[float]:
        """Values at the places :meth:`places` found (a batch of one kinematic kind
        straight from the core's state, when the core can: no full vector between)."""
        places, sections = found
        if self.core is not None:
            # the reader is this instance's core's: a batch (and what places found)
            # may be shared by every instance of a class that declares its variables
            reader = self._readers.get(id(found), _UNASKED)
            if reader is _UNASKED:
                reader = self._readers[id(found)] = self._reader(places, sections)
            if reader is not None:
                return reader().tolist()
        return self._readable(sections)[places].tolist()

    def _reader(self, places, sections):
        """The core's reader of places that all hold one kinematic kind, else None."""
        n = len(self.interface)
        if len(sections) != 1 or sections[0] > 2:
            return None
        start = (sections[0] + 1) * n
        if places.min() < start or places.max() >= start + n:
            return None
        return self.core.kinematic_reader(sections[0], places - start)

    def set_reals(self, found, values) -> None:
        """Forces at the places :meth:`places` (``forces_only``) found."""
        self._set_forces(found[0], values)

    # --- values --------------------------------------------------------------------
    def _set_forces(self, indices, values) -> None:
        self.forces[indices] = values
        self._values[:len(self.interface)] = self.forces
        if self.core is not None:
            self.core.set_interface_forces(self.forces)
            if self.initializing:  # the start forces decide the initial accelerations
                self.core.initialize(self.start_time)
            self._stale = [True] * 4

    def _readable(self, sections) -> np.ndarray:
        """The readable values, with ``sections`` (0 positions, 1 velocities,
        2 accelerations, 3 named outputs) brought up to date."""
        if self.core is None and self.initializing:
            self.build()
        if self.core is None:
            return self._values
        n = len(self.interface)
        kinds = [s for s in sections if s < 3 and self._stale[s]]
        if len(kinds) > 1:  # several kinds: the core computes them together
            self._values[n:4 * n].reshape(3, n)[...] = self.core.interface_kinematics()
            self._stale[:3] = [False] * 3
        elif kinds:
            start = (kinds[0] + 1) * n
            self._values[start:start + n] = self.core.interface_kinematic(kinds[0])
            self._stale[kinds[0]] = False
        if 3 in sections and self._stale[3]:
            values = self.core.outputs()
            self._values[4 * n:] = [values[name] for name in self.output_names]
            self._stale[3] = False
        return self._values

    def build(self) -> bool:
        """Build the core from the parameters set so far, once; False when they make
        none (the reason is then logged at fmi2Error and kept in :attr:`refusal`)."""
        if self.core is None and self.refusal is None:
            try:
                self.attach(self.slave.build_core(), self.start_time)
            except ValueError as error:
                self.core, self.refusal = None, str(error)
                self.slave.log(f"{self.slave.instance_name}: {error}", Fmi2Status.error)
        return self.core is not None

    def attach(self, core: InterfaceCore, start_time: float) -> None:
        """Take over a freshly built core and initialise it at ``start_time``."""
        self.core = core
        self._readers = {}
        core.set_interface_forces(self.forces)
        core.initialize(start_time)
        self._stale = [True] * 4

    def step(self, time: float, step_size: float) -> bool:
        if self.core is None:  # refused parameters, and a master that went on regardless
            self.slave.log(f"{self.slave.instance_name}: no step without a model "
                           f"({self.refusal or 'not initialised'})", Fmi2Status.error)
            return False
        self.core.step(time, step_size)
        self._stale = [True] * 4
        return True

    def get_state(self) -> dict:
        """The complete FMU state: core state, inputs (a restore must bring back
        the inputs too, as fmi2SetFMUstate does) and nothing derived."""
        return {"core": self.core.get_state() if self.core else None,
                "forces": self.forces.copy(),
                # what a fresh instance needs besides (a state moved to another process)
                "caches": self.core.caches() if self.core else None}

    def set_state(self, state: dict) -> None:
        self.forces = np.array(state["forces"], dtype=float)
        self._values[:len(self.interface)] = self.forces
        if self.core is not None and state["core"] is not None:
            self.core.set_state(state["core"])
            # a state deserialized here comes from another instance: its caches once
            if state.pop("moved", False) and state.get("caches") is not None:
                self.core.set_caches(state["caches"])
            self.core.set_interface_forces(self.forces)
            self._stale = [True] * 4


#: the state serialized last and its bytes: pythonfmu serializes a state twice in a
#: row, once for fmi2SerializedFMUstateSize and once for fmi2SerializeFMUstate (a
#: third of a Ray worker's checkpoint of a SpringMass, 10 of 30 us)
_last_serialized: list = [None, b""]


def state_to_bytes(state) -> bytes:
    """Serialise an FMU state (numpy arrays inside, so pickle rather than JSON).  The
    call right after one for the same state object gives the bytes of that one, once
    (pythonfmu's pair of calls; a state moved in from another process is changed when
    it is set, so the bytes are never kept longer)."""
    if state is _last_serialized[0]:
        data = _last_serialized[1]
        _last_serialized[:] = [None, b""]
        return data
    data = pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL)
    _last_serialized[:] = [state, data]
    return data


def state_from_bytes(data: bytes):
    """Inverse of :func:`state_to_bytes`, marked as moved (from another instance)."""
    state = pickle.loads(data)
    if isinstance(state, dict):
        state["moved"] = True
    return state


def glued_slave(cls):
    """Class decorator for a pythonfmu slave of a glueable core.

    The slave's ``__init__`` creates ``self.binding`` (a :class:`CoreBinding`) and the
    slave defines ``build_core(self)``, which makes the core from the parameters set
    so far; this decorator adds the FMI callbacks every such wrapper shares (start
    time, initialisation, step, complete state and its serialisation).  A
    ``ValueError`` from ``build_core`` is logged as an fmi2Error and not raised (see
    the module's docstring), so a master can tell the user which parameter the model
    refused and still free the instance; an ``ArithmeticError`` from a step (the
    core's own iteration failed) discards the step.  (A decorator and not a base class:
    pythonfmu before 0.7 found the model class by the line ``class Name(Fmi2Slave):``.)

    A class with a ``variables`` attribute (a sequence of :class:`Variable`, its own
    then :func:`port_variables`) declares them once: value reference = place in it,
    every FMI get and set of them answered from that table, and pythonfmu's variables
    registered only to write the model description (``to_xml``, when the FMU is built).
    """
    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self.binding.start_time = start_time

    def enter_initialization_mode(self):
        self.binding.initializing = True

    def exit_initialization_mode(self):
        self.binding.build()
        self.binding.initializing = False

    def do_step(self, current_time, step_size):
        # a core whose own iteration fails on this step (a linkage's Newton, a flexible
        # link's PIM) discards the step (fmi2Discard): its state before the step can
        # be restored and the master may retry a smaller one; anything else is fatal
        try:
            return self.binding.step(current_time, step_size)
        except ArithmeticError as error:
            self.log(f"{self.instance_name}: {error}", Fmi2Status.discard)
            return False

    def _get_fmu_state(self):
        return self.binding.get_state()

    def _set_fmu_state(self, state):
        self.binding.set_state(state)

    def get_real(self, vrs):
        places = self.binding.places(vrs)
        if places is None:  # parameters and the like: one getter per variable
            return get_each(self, vrs, Real)
        return self.binding.get_reals(places)

    def set_real(self, vrs, values):
        places = self.binding.places(vrs, forces_only=True)
        if places is None:
            return set_each(self, vrs, values, Real)
        self.binding.set_reals(places, values)

    for method in (setup_experiment, enter_initialization_mode, exit_initialization_mode,
                   do_step, _get_fmu_state, _set_fmu_state, get_real, set_real):
        if method.__name__ not in cls.__dict__:
            setattr(cls, method.__name__, method)
    if "variables" in cls.__dict__:
        _declare(cls, cls.variables)
    cls._fmu_state_to_bytes = staticmethod(state_to_bytes)
    cls._fmu_state_from_bytes = staticmethod(state_from_bytes)
    abc.update_abstractmethods(cls)
    return cls


def get_each(slave, vrs, kind) -> list:
    """Values of the variables ``vrs`` of type ``kind`` (``Real``, ...) of ``slave``, one
    getter each: from its class's declared table, else pythonfmu's registered variables."""
    declared = getattr(type(slave), "declared", None)
    if declared is None:
        return getattr(Fmi2Slave, f"get_{kind.__name__.lower()}")(slave, vrs)
    values = []
    for vr in vrs:
        variable = declared[vr]  # a KeyError, as Fmi2Slave's: no such variable
        if variable.kind is not kind:
            raise TypeError(f"Variable with valueReference={vr} is not of type "
                            f"{kind.__name__}!")
        values.append(CONVERT[kind](variable.get(slave)))
    return values


def set_each(slave, vrs, values, kind) -> None:
    """Set the variables ``vrs`` of type ``kind`` of ``slave``, one setter each (as
    :func:`get_each`)."""
    declared = getattr(type(slave), "declared", None)
    if declared is None:
        return getattr(Fmi2Slave, f"set_{kind.__name__.lower()}")(slave, vrs, values)
    for vr, value in zip(vrs, values):
        variable = declared[vr]
        if variable.kind is not kind or variable.set is None:
            raise TypeError(f"Variable with valueReference={vr} is not a settable "
                            f"{kind.__name__}!")
        variable.set(slave, value)


def _declare(cls, variables) -> None:
    """Give ``cls`` its declared ``variables`` (:class:`Variable`, value references in
    their order) as one table for every instance: FMI get and set calls answered from
    it, pythonfmu's variables registered only when the model description is written."""
    cls.declared = dict(enumerate(variables))
    for kind in (Integer, Boolean, String):
        name = kind.__name__.lower()
        if f"get_{name}" not in cls.__dict__:
            setattr(cls, f"get_{name}", lambda self, vrs, kind=kind: get_each(self, vrs, kind))
        if f"set_{name}" not in cls.__dict__:
            setattr(cls, f"set_{name}", lambda self, vrs, values, kind=kind:
                    set_each(self, vrs, values, kind))

    def to_xml(self, model_options=None):
        # the model description (when the FMU is built) is written from pythonfmu's
        # variables: registered here, in the declared order (value reference = index)
        if not self.vars:
            for variable in cls.declared.values():
                self.register_variable(variable.bound(self), nested=False)
        return Fmi2Slave.to_xml(self, model_options or {})

    if "to_xml" not in cls.__dict__:
        cls.to_xml = to_xml
