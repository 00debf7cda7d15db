"""dsim's own description of an FMU, whatever its FMI version (1.0, 2.0, 3.0) and
interfaces (co-simulation, Model Exchange): the one place that reads fmpy's parsed
modelDescription.xml.

Everything above this module (ports, units, parameters, the plan, ``dsim info``, the
web front end) reads an :class:`FmuDescription`, whose names follow the FMI standard's
own attribute names (``valueReference``, ``causality``, ``canGetAndSetFMUstate``) so
that a reader of the standard finds them, but whose values are normalised across
versions:

- ``Variable.type`` is one of dsim's value kinds: Real (FMI 3.0 Float64 and Float32),
  Integer (every FMI 3.0 integer type), Enumeration, Boolean, String, Binary, Clock;
  the type the FMU declares stays in ``Variable.fmi_type`` (the adapter calls the
  getter of that type);
- an FMI 3.0 array variable is listed as one scalar variable per element, named
  ``name[i]`` (``name[i,j]`` for more dimensions, 1-based as FMI's structured names),
  each with the array's value reference and its ``element`` (0-based, row major):
  results record the columns a user expects;
- FMI 1.0 causality/variability are mapped onto FMI 2.0's (``internal`` -> local,
  ``parameter`` variability -> causality parameter, fixed), and its co-simulation
  capabilities onto the 2.0 flags;
- a unit is resolved through the variable's declared type; an Enumeration's items
  are on the variable;
- the model structure: continuous states and their derivatives (Model Exchange), and
  each output's dependencies (None: the FMU declares none, so it may depend on every
  input: direct feedthrough is assumed, as the standard says).
"""
from __future__ import annotations

import threading
from dataclasses import dataclass, field
from functools import lru_cache
from itertools import product
from pathlib import Path

from fmpy import platform, platform_tuple, read_model_description, sharedLibraryExtension
from fmpy.model_description import ValidationError

from dsim.master.reading.digests import file_digest
from dsim.master.reading.input_tables import is_table_file, read_table

#: dsim's value kind of each FMI type name (1.0, 2.0 and 3.0)
KIND_OF_TYPE = {"Real": "Real", "Float64": "Real", "Float32": "Real",
                "Integer": "Integer", "Int8": "Integer", "UInt8": "Integer",
                "Int16": "Integer", "UInt16": "Integer", "Int32": "Integer",
                "UInt32": "Integer", "Int64": "Integer", "UInt64": "Integer",
                "Enumeration": "Enumeration", "Boolean": "Boolean", "String": "String",
                "Binary": "Binary", "Clock": "Clock"}
#: the interfaces of an FMU, as SSP's ``implementation`` attribute names them
CO_SIMULATION, MODEL_EXCHANGE = "CoSimulation", "ModelExchange"

#: what fmpy's checks say of a rule that does not change what the FMU computes
CONTINUOUS_DISCRETE = 'must have variability != "continuous"'


@dataclass(frozen=True)
class Variable:
    """One scalar variable (or one element of an FMI 3.0 array variable)."""

    name: str
    valueReference: int
    type: str
    causality: str
    variability: str
    initial: str | None = None
    start: object = None
    unit: str | None = None
    min: str | None = None
    max: str | None = None
    nominal: str | None = None
    description: str = ""
    #: the type the FMU declares (Float64, Int32, Real, ...): which getter reads it
    fmi_type: str = "Real"
    #: an Enumeration's items as (name, value)
    items: tuple[tuple[str, int], ...] = ()
    #: the name of the variable this one is the time derivative of (Model Exchange)
    derivative_of: str | None = None
    #: the array's shape and this element's place in it (FMI 3.0; () for a scalar)
    shape: tuple[int, ...] = ()
    element: int = 0
    #: the unit the FMU would show the value in (its own, or its declared type's
    #: displayUnit; None: its unit)
    display_unit: str | None = None


@dataclass(frozen=True)
class Interface:
    """One interface of an FMU (co-simulation or Model Exchange) and its capabilities."""

    kind: str
    modelIdentifier: str
    canGetAndSetFMUstate: bool = False
    canSerializeFMUstate: bool = False
    canHandleVariableCommunicationStepSize: bool = False
    canInterpolateInputs: bool = False
    maxOutputDerivativeOrder: int = 0
    canBeInstantiatedOnlyOncePerProcess: bool = False
    needsExecutionTool: bool = False
    providesDirectionalDerivative: bool = False
    needsCompletedIntegratorStep: bool = True


@dataclass(frozen=True)
class UnitDefinition:
    """A unit of the FMU's UnitDefinitions: SI base exponents, factor, offset."""

    name: str
    exponents: dict | None
    factor: float = 1.0
    offset: float = 0.0
    #: its DisplayUnits as (name, factor, offset): display value = factor * value +
    #: offset
    display: tuple[tuple[str, float, float], ...] = ()


@dataclass(frozen=True, eq=False)
class FmuDescription:
    """What dsim knows of an FMU before loading it: version, interfaces, variables,
    units, model structure, default experiment."""

    fmiVersion: str
    modelName: str
    guid: str
    coSimulation: Interface | None
    modelExchange: Interface | None
    modelVariables: tuple[Variable, ...]
    unitDefinitions: tuple[UnitDefinition, ...] = ()
    numberOfEventIndicators: int = 0
    #: names of the continuous states, in the FMU's state vector order (Model Exchange)
    states: tuple[str, ...] = ()
    #: output name -> the names of the inputs it depends on directly (None: undeclared)
    dependencies: dict = field(default_factory=dict)
    description: str = ""
    generationTool: str = ""
    author: str = ""
    version: str = ""
    defaultExperiment: object = None
    #: variables the FMU declares that dsim cannot exchange (Clock, Binary): name -> type
    unsupported: dict = field(default_factory=dict)
    #: the names of the FMU's LogCategories, in its order
    log_categories: tuple[str, ...] = ()

    @property
    def major(self) -> int:
        """1, 2 or 3."""
        return int(str(self.fmiVersion).split(".")[0])

    def interface(self, kind: str) -> Interface | None:
        """The interface named as SSP names it (CoSimulation, ModelExchange)."""
        return {CO_SIMULATION: self.coSimulation, MODEL_EXCHANGE: self.modelExchange}[kind]

    @property
    def interfaces(self) -> tuple[str, ...]:
        """The interfaces this FMU has, co-simulation first."""
        return tuple(k for k in (CO_SIMULATION, MODEL_EXCHANGE) if self.interface(k))

    def __post_init__(self):
        object.__setattr__(self, "by_name", {v.name: v for v in self.modelVariables})

    def variable(self, name: str) -> Variable:
        """The variable called ``name`` (KeyError when there is none)."""
        return self.by_name[name]

#: SHA-256 of an FMU file (:func:`~dsim.master.reading.digests.file_digest`, which
#: the archive checks compute anyway) -> (dsim's description, the rule it breaks that
#: dsim tolerates or None), for the last _KEPT read: the same FMU in another folder (a
#: scene unpacked again, a sweep's next point, a test's copy) is not parsed again
#: (fmpy's parse and schema check take about 20 ms)
_READ: dict[str, tuple] = {}
_KEPT = 256
_READ_LOCK = threading.Lock()  # dsim serve reads scenes in several threads


def _parsed(path: Path):
    """fmpy's parse of the FMU's modelDescription.xml, schema-checked, and the rule it
    breaks that dsim tolerates (or None).

    OpenModelica exports Enumeration (and other non-Real) variables with
    variability="continuous", which FMI 2.0 forbids but which changes nothing a
    co-simulation master does with them: such a description is read again without
    fmpy's semantic checks, and :func:`description_warning` says so."""
    try:
        return read_model_description(str(path)), None
    except ValidationError as error:
        if not error.problems or not all(CONTINUOUS_DISCRETE in p for p in error.problems):
            raise
        names = [p.split('"')[1] for p in error.problems]
        tolerated = (f"modelDescription.xml declares {len(names)} non-Real "
                     "variable(s) variability=\"continuous\" (FMI 2.0 forbids it; "
                     f"it changes nothing dsim does): {', '.join(names[:3])}"
                     f"{', ...' if len(names) > 3 else ''}")
    return read_model_description(str(path), validate=False), tolerated


def _described(path: Path) -> tuple:
    """(dsim's description, the tolerated rule or None) of the FMU at ``path``, read
    once per content (see _READ)."""
    # an unpacked FMU's folder is parsed each time; a missing file, fmpy says so
    key = file_digest(path) if path.is_file() else None
    found = _READ.get(key)
    if found is not None:
        return found
    md, tolerated = _parsed(path)
    found = (_description(md), tolerated)
    if key is not None:
        with _READ_LOCK:
            if len(_READ) >= _KEPT:
                del _READ[next(iter(_READ))]
            _READ[key] = found
    return found


@lru_cache(maxsize=64)
def _described_file(path: Path) -> tuple:
    """_described, cached per file."""
    return _described(Path(path))


def describe(path: Path) -> FmuDescription:
    """dsim's description of the FMU file at ``path`` (cached per file, and read once
    per content of the file: see _READ); of a table file (.csv, .mat: an SSP table
    component, ``--input``), the description of a source whose outputs are its columns
    (:func:`table_description`)."""
    if is_table_file(path):
        return table_description(read_table(path))
    return _described_file(path)[0]


#: a table's "interface": a source that saves and restores its state (its time) and
#: takes steps of any size; dsim runs it in process (dsim.master.running.tables)
TABLE_INTERFACE = Interface(CO_SIMULATION, "table", canGetAndSetFMUstate=True,
                            canSerializeFMUstate=True,
                            canHandleVariableCommunicationStepSize=True)


def table_description(table) -> FmuDescription:
    """The description of an input table (a
    :class:`~dsim.master.reading.input_tables.Table`) as the plan reads an FMU's: one
    continuous Real output per column (OMSimulator's table components have Real
    outputs), no input, no parameter, unitless (an SSP connector may give the unit)."""
    found = _TABLES.get(id(table))
    if found is not None and found[0] is table:
        return found[1]
    variables = tuple(Variable(name, index, "Real", "output", "continuous",
                               initial="calculated") for index, name in enumerate(table.names))
    description = FmuDescription("2.0", "table", "", TABLE_INTERFACE, None,
                                 variables, dependencies={n: () for n in table.names},
                                 generationTool="dsim (an input table)")
    _TABLES[id(table)] = (table, description)
    return description


#: id(table) -> (the table, its description): made once per table read
_TABLES: dict[int, tuple] = {}


def _description(md) -> FmuDescription:
    """dsim's description made of fmpy's ``md``."""
    major = int(md.fmiVersion.split(".")[0])
    declared = {}
    variables, unsupported = [], {}
    for v in md.modelVariables:
        kind = KIND_OF_TYPE.get(v.type, v.type)
        if kind in ("Clock", "Binary"):
            unsupported[v.name] = v.type
        declared[id(v)] = v.name
        variables.extend(_scalars(v, kind, major))
    states = tuple(declared[id(v.derivative)] for v in md.modelVariables
                   if v.derivative is not None)
    if major == 1:  # FMI 1.0 lists no derivatives: its states are the numbered ones
        states = ()
    dependencies = {u.variable.name: (None if u.dependencies is None else
                                      tuple(d.name for d in u.dependencies))
                    for u in md.outputs}
    units = tuple(UnitDefinition(u.name, None if u.baseUnit is None else
                                 {b: getattr(u.baseUnit, b) for b in _BASE},
                                 *(() if u.baseUnit is None else
                                   (u.baseUnit.factor, u.baseUnit.offset)),
                                 display=tuple((d.name, float(d.factor), float(d.offset))
                                               for d in u.displayUnits or () if d.name))
                  for u in md.unitDefinitions)
    return FmuDescription(
        fmiVersion=md.fmiVersion, modelName=md.modelName or "", guid=md.guid or "",
        coSimulation=_interface(md.coSimulation, CO_SIMULATION, major),
        modelExchange=_interface(md.modelExchange, MODEL_EXCHANGE, major),
        modelVariables=tuple(variables), unitDefinitions=units,
        numberOfEventIndicators=int(md.numberOfEventIndicators or 0), states=states,
        dependencies=dependencies, description=md.description or "",
        generationTool=md.generationTool or "", author=md.author or "",
        version=md.version or "", defaultExperiment=md.defaultExperiment,
        unsupported=unsupported,
        log_categories=tuple(c.name for c in md.logCategories if c.name))


_BASE = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")


def _interface(found, kind: str, major: int) -> Interface | None:
    if found is None:
        return None
    flags = {name: getattr(found, name, default) for name, default in (
        ("canGetAndSetFMUstate", False), ("canSerializeFMUstate", False),
        ("canHandleVariableCommunicationStepSize", False), ("canInterpolateInputs", False),
        ("maxOutputDerivativeOrder", 0), ("canBeInstantiatedOnlyOncePerProcess", False),
        ("needsExecutionTool", False))}
    flags["providesDirectionalDerivative"] = bool(
        getattr(found, "providesDirectionalDerivative", False)
        or getattr(found, "providesDirectionalDerivatives", False))
    if major == 1 and kind == CO_SIMULATION:
        # FMI 1.0 co-simulation has no state save; its step size is free unless the
        # FMU says otherwise (fmpy keeps the capabilities it reads)
        flags["canGetAndSetFMUstate"] = flags["canSerializeFMUstate"] = False
        flags["canHandleVariableCommunicationStepSize"] = bool(getattr(
            found, "canHandleVariableCommunicationStepSize", True))
    if kind == MODEL_EXCHANGE:
        flags["needsCompletedIntegratorStep"] = not getattr(
            found, "completedIntegratorStepNotNeeded", False)
    return Interface(kind, found.modelIdentifier, **flags)


def _fmi1_roles(v) -> tuple[str, str]:
    """FMI 1.0's (causality, variability) in FMI 2.0's words."""
    causality = {"internal": "local", "none": "local"}.get(v.causality, v.causality)
    variability = v.variability or "continuous"
    if variability == "parameter":
        return "parameter", "fixed"
    return causality or "local", variability


def _scalars(v, kind: str, major: int) -> list[Variable]:
    """One Variable per scalar of fmpy's variable ``v`` (an FMI 3.0 array gives one per
    element)."""
    declared = v.declaredType
    unit = v.unit or getattr(declared, "unit", None)
    low = v.min if v.min not in (None, "") else getattr(declared, "min", None)
    high = v.max if v.max not in (None, "") else getattr(declared, "max", None)
    items = ()
    if kind == "Enumeration" and declared is not None:
        items = tuple((item.name, int(item.value)) for item in declared.items)
    causality, variability = (_fmi1_roles(v) if major == 1
                              else (v.causality or "local", v.variability or (
                                  "continuous" if kind == "Real" else "discrete")))
    common = dict(valueReference=v.valueReference, type=kind, causality=causality,
                  variability=variability, initial=v.initial, unit=unit, min=low, max=high,
                  nominal=v.nominal, description=v.description or "", fmi_type=v.type,
                  display_unit=(getattr(v, "displayUnit", None)
                                or getattr(declared, "displayUnit", None)),
                  items=items, derivative_of=(v.derivative.name if v.derivative is not None
                                              else None))
    shape = tuple(_extent(d) for d in getattr(v, "dimensions", []) or [])
    if not shape:
        return [Variable(v.name, start=v.start, **common)]
    starts = str(v.start).split() if v.start not in (None, "") else []
    result = []
    for element, index in enumerate(product(*(range(1, n + 1) for n in shape))):
        start = starts[element] if element < len(starts) else (starts[0] if len(starts) == 1
                                                                else None)
        result.append(Variable(f"{v.name}[{','.join(map(str, index))}]", start=start,
                               shape=shape, element=element, **common))
    return result


def _extent(dimension) -> int:
    """A dimension's fixed size (a structural parameter's start value when it names one)."""
    if dimension.start not in (None, ""):
        return int(dimension.start)
    variable = dimension.variable
    return int(variable.start) if variable is not None and variable.start else 0


def description_warning(path: Path) -> str | None:
    """The rule ``path``'s modelDescription.xml breaks that dsim tolerates, or None."""
    if is_table_file(path):
        return None
    return _described_file(path)[1]


def variables_by_name(path: Path) -> dict[str, Variable]:
    """Name -> Variable of an FMU."""
    return describe(path).by_name


def can_roll_back(path: Path, interface: str = CO_SIMULATION) -> bool:
    """Whether the FMU can go back to a saved point in ``interface``: an FMU state
    (canGetAndSetFMUstate), or, for Model Exchange, its continuous states, which the
    master integrates itself (:mod:`dsim.master.running.fmi.model_exchange`)."""
    description = describe(path)
    found = description.interface(interface)
    if found is None:
        return False
    return found.canGetAndSetFMUstate or interface == MODEL_EXCHANGE


def library_members(path: Path, checked: bool = True) -> list[str]:
    """The archive members of the libraries for this platform that the FMU's
    interfaces name (one per distinct model identifier, co-simulation first).
    ``checked=False`` reads the description without fmpy's checks (whether there is
    a library at all is said before any complaint about the description); an
    unreadable description raises what fmpy raises."""
    if checked:
        description = describe(path)
        major = description.major
        identifiers = [description.interface(k).modelIdentifier
                       for k in description.interfaces]
    else:
        md = read_model_description(str(path), validate=False)
        major = int(md.fmiVersion.split(".")[0])
        identifiers = [i.modelIdentifier for i in (md.coSimulation, md.modelExchange) if i]
    folder = _platform_folder(major)
    return [f"binaries/{folder}/{identifier}{sharedLibraryExtension}"
            for identifier in dict.fromkeys(identifiers)]


def library_folder(description: FmuDescription) -> str:
    """The ``binaries/`` subfolder of this machine for the FMU's FMI version (FMI 3.0
    names platforms by tuple: x86_64-linux; FMI 1.0 and 2.0: linux64)."""
    return _platform_folder(description.major)


def _platform_folder(major: int) -> str:
    return platform_tuple if major >= 3 else platform


def chosen_interface(description: FmuDescription, implementation: str = "") -> str:
    """The interface a component runs: the one the SSD's ``implementation`` asks for,
    else co-simulation where the FMU has it, else Model Exchange.  ValueError with the
    reason when the FMU has no interface dsim runs for that request."""
    asked = implementation if implementation in (CO_SIMULATION, MODEL_EXCHANGE) else ""
    runnable = [k for k in description.interfaces
                if not (description.major == 1 and k == MODEL_EXCHANGE)]
    if asked:
        if description.interface(asked) is None:
            has = " and ".join(description.interfaces) or "no interface"
            raise ValueError(f'implementation="{asked}", but the FMU has {has}')
        if asked not in runnable:
            raise ValueError(f"FMI {description.fmiVersion} {asked} FMUs are not run by "
                             "dsim (FMI 1.0: co-simulation only)")
        return asked
    if not runnable:
        raise ValueError(f"an FMI {description.fmiVersion} "
                         f"{' and '.join(description.interfaces) or 'FMU without interface'}"
                         " FMU: dsim runs FMI 1.0 co-simulation and FMI 2.0 and 3.0 "
                         "co-simulation and Model Exchange FMUs")
    return runnable[0]
