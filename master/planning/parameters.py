"""Model parameters given for one run (``dsim run --set``, ``--set-file``,
``dsim.simulate(scene, parameters=...)``): start values of the components' FMU
variables, and the laws of the flexible joints, applied on top of everything the
scene binds.

A name is a dotted path: the component's path, a dot, the FMU variable's name as the
modelDescription writes it (``left.k_ground[1]``, ``frame.rail.thickness``); or a
joint's name, a dot and one of its law's coefficients (``j1.k0``).  The longest
component path that prefixes the name wins, so variables whose own names hold dots
(``load.F_x``) are reached too.

Every value is checked against each FMU's modelDescription (read from the archive;
no library is loaded), and every problem is one line of one
:class:`~dsim.master.errors.InputError` raised before anything runs: an unknown component,
joint or variable (the closest names offered), a value that is not of the variable's
type, a variable FMI 2.0 lets no master set (a constant, a calculated parameter, an
output the FMU calculates), a value outside the variable's min/max.  What the plan
knows later (an input that a connection or a joint writes) it checks itself
(:func:`written_by_master`).

The values reach the FMUs by the path the scene's own ``ParameterBinding`` values take
(``Component.parameters``, then ``fmi2Set*`` in initialization mode), so a value given
here and the same value in an .ssv parameter set give the same run, byte for byte.
"""
from __future__ import annotations

import difflib
import math
import numbers
import re
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

from dsim.master.errors import InputError
from dsim.master.planning.names import closest, owner_split
from dsim.master.reading.fmi_description import describe
from dsim.master.reading.scene_files import SCENE_RESOURCES, scene_file

#: where a value given for the run came from (``Component.origins``), and how
#: messages name it
ORIGIN = "given for the run (--set, --set-file, parameters=)"
#: every joint law coefficient a run may set (``--set j1.k0=VALUE``): what it is and
#: which joints have it.  The one list ``dsim info``, the messages, the ``--set``
#: help and docs/parameters.md give (tests/planning/test_parameter_names.py keeps the docs so).
#: The flexible law per dof is (k0 + k1|q|) q + (c0 + c1|qd|) qd = -F (docs/method.md).
JOINT_COEFFICIENTS = {
    "k0": ("flexible", "stiffness, per dof (N/m; N.m/rad on a rotation)"),
    "k1": ("flexible", "stiffness growing with abs(q), per dof (N/m^2; N.m/rad^2)"),
    "c0": ("flexible", "damping, per dof (N.s/m; N.m.s/rad)"),
    "c1": ("flexible", "damping growing with abs(qd), per dof (N.s^2/m^2; N.m.s^2/rad^2)"),
    "xi": ("penalized", "damping ratio of the penalized measure (1)"),
    "omega": ("penalized", "frequency of the penalized measure (rad/s)"),
}
#: joint law coefficients a run may set: per dof (one value for all, or one per dof)
JOINT_PER_DOF = tuple(k for k, (kind, _) in JOINT_COEFFICIENTS.items() if kind == "flexible")
#: ... and of the penalized measure (one value)
JOINT_SCALAR = tuple(k for k, (kind, _) in JOINT_COEFFICIENTS.items() if kind == "penalized")
#: coefficients that are physical only when not negative
NON_NEGATIVE = ("k0", "c0", "xi", "omega")
#: the SSP value type dsim keeps for an FMU variable type
KEPT_TYPE = {"Real": "Real", "Integer": "Integer", "Enumeration": "Integer",
             "Boolean": "Boolean", "String": "String"}


@dataclass(frozen=True)
class Settable:
    """A variable of a component that a run may set (``dsim info``, the web form)."""

    component: str
    name: str
    type: str
    causality: str
    variability: str
    unit: str | None
    start: str | None
    min: str | None
    max: str | None
    description: str
    #: an Enumeration's items as (name, value)
    items: tuple[tuple[str, int], ...] = ()

    @property
    def full_name(self) -> str:
        return f"{self.component}.{self.name}"


def _declared(variable, attribute: str):
    """A variable's attribute (the description has resolved its declared type's)."""
    own = getattr(variable, attribute, None)
    return None if own in (None, "") else own


def items_of(variable) -> tuple[tuple[str, int], ...]:
    """(name, value) of an Enumeration variable's items (its declared type's)."""
    return tuple(variable.items) if variable.type == "Enumeration" else ()


def refusal(variable) -> str | None:
    """Why FMI 2.0 lets no master set ``variable`` before the run starts (None: it
    may).  dsim sets values in initialization mode, where FMI 2.0 allows a variable
    that is not constant and is a parameter (fixed or tunable: both may be set
    before initialization), an input, or has initial="exact" or "approx"."""
    if variable.variability == "constant":
        return "a constant: FMI 2.0 lets no master set it"
    if variable.causality == "calculatedParameter":
        return "a calculated parameter: the FMU computes it from other parameters"
    if variable.causality == "independent":
        return "the independent variable (time)"
    if variable.causality in ("parameter", "input") or variable.initial in ("exact", "approx"):
        return None
    return (f"calculated by the FMU (causality {variable.causality}, initial="
            f"{variable.initial or 'calculated'}): FMI 2.0 lets no master set it")


def settable_variables(path: Path, component: str) -> list[Settable]:
    """Every variable of the FMU at ``path`` that a run may set, in the order of its
    modelDescription."""
    return [Settable(component, *fields) for fields in _settable_fields(describe(path))]


@lru_cache(maxsize=64)
def _settable_fields(description) -> tuple[tuple, ...]:
    """The fields of :class:`Settable` but the component, per settable variable of a
    description (read once per FMU: a scene of thousands of components shares a few)."""
    return tuple((variable.name, variable.type, variable.causality,
                  variable.variability or "", _declared(variable, "unit"), variable.start,
                  _declared(variable, "min"), _declared(variable, "max"),
                  variable.description or "", items_of(variable))
                 for variable in description.modelVariables
                 if refusal(variable) is None and variable.type in KEPT_TYPE)


# --- arrays sized by a parameter -----------------------------------------------------
#: the largest size a "number of" parameter's description gives (``1 to 4``)
_LIMIT_TEXT = re.compile(r"\b(?:1 to|1 \.\. ?|up to|at most)\s*(\d+)\b")
_ELEMENT = re.compile(r"^(.+)\[(\d+)\]$")


@dataclass(frozen=True)
class ArraySize:
    """Arrays of an FMU that a size parameter says how much of is used: the entries
    ``family[1]`` .. ``family[size]`` of each family (of ``length`` declared)."""

    parameter: str
    size: int
    length: int
    families: tuple[str, ...]

    def beyond(self, name: str) -> bool:
        """Whether variable ``name`` is an entry past the used size."""
        return name in _past(self.families, self.size, self.length)

    def text(self, component: str) -> str:
        """One line saying which entries are used, and how to use more."""
        shown = ", ".join(self.families[:4]) + (", ..." if len(self.families) > 4 else "")
        return (f"arrays {shown} used to [{self.size}] of [{self.length}] "
                f"({self.parameter} = {self.size}; --set {component}.{self.parameter} to use "
                "more)")


def _whole(value) -> int | None:
    try:
        number = float(str(value).strip())
    except (TypeError, ValueError):
        return None
    return int(number) if math.isfinite(number) and number.is_integer() else None


@lru_cache(maxsize=256)
def _past(families: tuple[str, ...], size: int, length: int) -> frozenset:
    return frozenset(f"{family}[{i}]" for family in families
                     for i in range(size + 1, length + 1))


def array_size(description, values: dict) -> ArraySize | None:
    """The size parameter of an FMU's arrays and its value in a scene, or None.  FMI
    2.0 has no array dimensions, so dsim reads the convention its own FMUs keep (and
    many others): arrays declared as ``m[1]`` .. ``m[N]`` for the largest model, and
    one Integer parameter, described as "number of ..." with the limit N (its
    ``max``, or "1 to N" in its description), saying how many entries the model
    uses.  ``values``: the scene's values (name -> (type, value) as
    ``Component.parameters``), else the FMU's start.  Found only where exactly one
    such parameter matches, and its value is below N: nothing is hidden otherwise."""
    found = _size_parameter(description)
    if found is None:
        return None
    variable, limit, sized = found
    given = values.get(variable.name)
    size = _whole(given[1] if isinstance(given, tuple) else given)
    size = size if size is not None else _whole(variable.start)
    if size is None or not 1 <= size < limit:
        return None
    return ArraySize(variable.name, size, limit, sized)


@lru_cache(maxsize=64)
def _size_parameter(description):
    """(the size parameter, N, the array families of length N) of a description, or
    None (read once per FMU)."""
    families: dict[str, set[int]] = {}
    for variable in description.modelVariables:
        match = _ELEMENT.match(variable.name)
        if match:
            families.setdefault(match.group(1), set()).add(int(match.group(2)))
    lengths = {base: max(indices) for base, indices in families.items()
               if indices == set(range(1, max(indices) + 1))}
    found = []
    for variable in description.modelVariables:
        if variable.type != "Integer" or variable.causality != "parameter" or \
                "number of" not in (variable.description or "").lower():
            continue
        limit = _whole(variable.max)
        if limit is None:
            said = _LIMIT_TEXT.search(variable.description or "")
            limit = int(said.group(1)) if said else None
        sized = tuple(base for base, length in lengths.items() if length == limit)
        if limit and sized:
            found.append((variable, limit, sized))
    return found[0] if len(found) == 1 else None


def _past_size(scene, components: dict, given: list[tuple[str, str, str]]) -> list[str]:
    """Problems of values given for a run to array entries past the size the scene
    (with the run's own values) gives the component's arrays: the model would ignore
    them.  ``given``: (full name, component path, variable name)."""
    problems = []
    for name, path, variable_name in given:
        component = components[path]
        description = scene.descriptions.get(component.source) or _described(component.source)
        sizes = array_size(description, component.parameters) if description else None
        if sizes is not None and sizes.beyond(variable_name):
            problems.append(f"parameter '{name}': component '{path}' uses its arrays to "
                            f"[{sizes.size}] ({sizes.parameter} = {sizes.size}): "
                            f"{variable_name} would have no effect (set "
                            f"{path}.{sizes.parameter} too to use it)")
    return problems


# --- values ------------------------------------------------------------------------
def _number(value, integer: bool):
    """``value`` (a Python number or text) as a float or int; ValueError if it is not
    one (a bool is no number here: True for a stiffness is a slip)."""
    if isinstance(value, bool):
        raise ValueError
    if isinstance(value, str):
        text = value.strip()
        try:
            number = int(text) if integer else float(text)
        except ValueError:
            number = float(text)  # '2.0' or '1e3' for an Integer: whole numbers pass
    elif isinstance(value, numbers.Real):
        number = value
    else:
        raise ValueError
    if integer:
        if isinstance(number, float) and not (math.isfinite(number) and number.is_integer()):
            raise ValueError
        return int(number)
    number = float(number)
    if not math.isfinite(number):
        raise ValueError
    return number


def convert(variable, value) -> tuple[object, str | None]:
    """``value`` (a Python value, or text to read by the variable's type) as the value
    the FMU variable takes, and what is wrong with it (None: nothing)."""
    kind = variable.type
    try:
        if kind == "Real":
            return _number(value, False), None
        if kind == "Integer":
            return _number(value, True), None
        if kind == "Boolean":
            if isinstance(value, bool):
                return value, None
            text = str(value).strip().lower() if isinstance(value, (str, int)) else None
            if text in ("true", "1"):
                return True, None
            if text in ("false", "0"):
                return False, None
            raise ValueError
        if kind == "String":
            if not isinstance(value, str):
                raise ValueError
            return value, None
        if kind == "Enumeration":
            items = items_of(variable)
            names = {name: number for name, number in items}
            if isinstance(value, str) and value.strip() in names:
                return names[value.strip()], None
            number = _number(value, True)
            if items and number not in names.values():
                raise ValueError
            return number, None
    except (TypeError, ValueError, OverflowError):
        wanted = {"Real": "a finite number", "Integer": "an integer",
                  "Boolean": "true or false", "String": "text",
                  "Enumeration": "one of " + ", ".join(
                      f"{name} ({number})" for name, number in items_of(variable))
                  if items_of(variable) else "an integer"}[kind]
        return value, f"is {kind}: '{value}' is not {wanted}"
    return value, f"is of type {kind}, which dsim cannot set"


def _limits(variable, value) -> str | None:
    """What is wrong with ``value`` against the variable's min and max, or None."""
    if variable.type not in ("Real", "Integer", "Enumeration"):
        return None
    low, high = _declared(variable, "min"), _declared(variable, "max")
    try:
        if low not in (None, "") and value < float(low):
            return f"is {value!r}, below its min {low}"
        if high not in (None, "") and value > float(high):
            return f"is {value!r}, above its max {high}"
    except ValueError:  # a min the description writes oddly: fmpy's checks say so
        return None
    return None


# --- joints ------------------------------------------------------------------------
def _joint_value(joint, coefficient: str, value) -> tuple[object, str | None]:
    """A joint law coefficient: a tuple (one per dof) or a float, and its problem."""
    if coefficient not in JOINT_COEFFICIENTS:
        own = joint_coefficients(joint)
        close = difflib.get_close_matches(coefficient, own, n=1, cutoff=0.5)
        return None, (f"joint '{joint.name}' has no coefficient '{coefficient}' ("
                      + (f"it has: {', '.join(own)}" if own else
                         f"a {joint.kind} joint on the {joint.measure} measure has no law "
                         "coefficient to set")
                      + (f"; closest: {close[0]}" if close else "") + ")")
    if coefficient in JOINT_PER_DOF and joint.kind != "flexible":
        return None, (f"joint '{joint.name}' is {joint.kind}: it has no spring or damper "
                      f"law, so '{coefficient}' cannot be set (only a flexible joint's)")
    if coefficient in JOINT_SCALAR and joint.measure != "penalized":
        return None, (f"joint '{joint.name}' measures {joint.measure}: '{coefficient}' is "
                      "a coefficient of the penalized measure")
    listed = value.split() if isinstance(value, str) else (
        list(value) if isinstance(value, (list, tuple)) else [value])
    try:
        values = [_number(v, False) for v in listed]
    except (TypeError, ValueError, OverflowError):
        return None, f"'{value}' is not a finite number or a list of them"
    size = len(joint.dofs) if coefficient in JOINT_PER_DOF else 1
    if len(values) == 1:
        values *= size
    if len(values) != size:
        return None, (f"{len(values)} values for joint '{joint.name}''s {size} dofs "
                      f"({' '.join(joint.dofs)}): give 1 or {size}")
    if coefficient in NON_NEGATIVE and any(v < 0 for v in values):
        return None, f"{value} is negative: '{coefficient}' must be at least 0"
    return (tuple(values) if coefficient in JOINT_PER_DOF else values[0]), None


# --- the scene with the values applied ----------------------------------------------
def _described(source):
    """The description of an FMU the scene was not read with (a Scene made by hand),
    or None where it cannot be read (the plan says why)."""
    try:
        return describe(source)
    except Exception:  # fmpy raises several kinds for a broken description
        return None


def with_parameters(scene, parameters: dict):
    """``scene`` with ``parameters`` (full name -> Python value or text) applied on
    top of every binding; what is wrong with them is added to ``scene.problems`` (one
    line each), so that the plan reports them with its own findings.  Each FMU's
    variables come from the descriptions the scene was read with (an FMU without one
    is refused by the plan, which says why)."""
    if not parameters:
        return scene
    problems: list[str] = []
    components = {c.path: c for c in scene.components}
    joints = {j.name: j for j in scene.joints}
    new_parameters = {path: dict(c.parameters) for path, c in components.items()}
    new_origins = {path: dict(c.origins) for path, c in components.items()}
    new_files = {path: dict(c.files) for path, c in components.items()}
    joint_changes: dict[str, dict] = {}
    applied, inputs, given_variables = {}, [], []
    base = Path(scene.inputs[0]).parent if scene.inputs else Path(scene.file).parent
    for name, value in parameters.items():
        name = str(name).strip()
        where = f"parameter '{name}'"
        owner = owner_split(name, components)
        if owner is None and owner_split(name, joints):
            joint_name, coefficient = owner_split(name, joints)
            converted, problem = _joint_value(joints[joint_name], coefficient, value)
            if problem:
                problems.append(f"{where}: {problem}")
            else:
                joint_changes.setdefault(joint_name, {})[coefficient] = converted
                applied[name] = list(converted) if isinstance(converted, tuple) else converted
            continue
        if owner is None:
            head = name.split(".")[0]
            hint = "" if "." in name else " (give COMPONENT.VARIABLE)"
            problems.append(f"{where}: no component or joint of the scene is named '{head}'"
                            + hint + closest(head, list(components) + list(joints)))
            continue
        path, variable_name = owner
        checked, problem = _checked_value(scene, components[path], variable_name, value,
                                          where)
        if problem:
            problems.append(problem)
        if checked is None:
            continue
        kind, converted = checked
        given_variables.append((name, path, variable_name))
        new_parameters[path][variable_name] = (kind, converted)
        new_origins[path][variable_name] = f"{where} {ORIGIN}"
        new_files[path].pop(variable_name, None)
        if kind == "String" and converted.startswith(SCENE_RESOURCES):
            file, problem = scene_file(base, variable_name, converted, where)
            if problem:
                problems.append(problem)
                continue
            new_files[path][variable_name] = file
            inputs.append(file)
        applied[name] = converted
    changed = tuple(replace(c, parameters=new_parameters[c.path], origins=new_origins[c.path],
                            files=new_files[c.path]) for c in scene.components)
    problems += _past_size(scene, {c.path: c for c in changed}, given_variables)
    new_joints = tuple(replace(j, **joint_changes[j.name]) if j.name in joint_changes else j
                       for j in scene.joints)
    return replace(scene, components=changed, joints=new_joints,
                   problems=tuple(scene.problems) + tuple(problems),
                   inputs=tuple(scene.inputs) + tuple(inputs),
                   overrides={**scene.overrides, **applied})


def _checked_value(scene, component, variable_name: str, value, where: str):
    """((the SSP type kept, the value converted), None) for a value a run gives
    ``component``'s variable, or (None, the problem); (None, None) where the FMU
    cannot be read (the plan says what is wrong with it)."""
    description = scene.descriptions.get(component.source) or _described(component.source)
    if description is None:
        return None, None
    variables = description.by_name
    variable = variables.get(variable_name)
    path = component.path
    if variable is None:
        settable = [v.name for v in variables.values() if refusal(v) is None]
        return None, (f"{where}: component '{path}' ({component.source.name}) has no "
                      f"variable '{variable_name}'" + closest(variable_name, settable))
    reason = refusal(variable)
    if reason:
        return None, f"{where}: variable '{variable_name}' of component '{path}' is {reason}"
    converted, problem = convert(variable, value)
    problem = problem or _limits(variable, converted)
    if problem:
        return None, f"{where}: variable '{variable_name}' of component '{path}' {problem}"
    return (KEPT_TYPE[variable.type], converted), None


def joint_coefficients(joint) -> tuple[str, ...]:
    """The law coefficients of ``joint`` a run may set (``j1.k0``)."""
    return ((JOINT_PER_DOF if joint.kind == "flexible" else ())
            + (JOINT_SCALAR if joint.measure == "penalized" else ()))


def master_writes(spec, path: Path) -> set[str]:
    """Names of the inputs of one subsystem that the master writes itself: its glued
    port forces (every step) and the variables connections feed."""
    forces = {dof.force for dof in spec.port_dofs}
    names = set(spec.start_writes) | set(spec.text_writes) | set(spec.writes)
    names |= {v.name for v in describe(path).modelVariables
              if v.type == "Real" and v.causality == "input" and v.valueReference in forces}
    return names


def free_settable(plan, index: int) -> list[Settable]:
    """What a run may set in component ``index`` of ``plan`` (``dsim info``'s list and
    the web form's rows): its settable variables but the inputs the master writes
    itself (:func:`master_writes`), and array entries past the size the scene gives
    them (:func:`array_size`)."""
    spec = plan.specs[index]
    component = plan.scene.component(spec.name)
    written = master_writes(spec, component.source)
    sizes = array_size(describe(spec.path), component.parameters)
    return [v for v in settable_variables(spec.path, spec.name) if v.name not in written
            and not (sizes and sizes.beyond(v.name))]


def written_by_master(scene, specs, usable: dict) -> list[str]:
    """Problems of values given for a run (``scene.overrides``) to inputs the master
    writes itself: a glued port's force (the joints set it every step) or an input a
    connection feeds (set at initialization and every step): the value would be
    replaced before the first step."""
    problems = []
    for spec in specs:
        variables = usable.get(spec.name, {})
        forces = {dof.force for dof in spec.port_dofs}
        fed = set(spec.start_writes) | set(spec.text_writes)
        for name in scene.component(spec.name).origins:
            if not scene.component(spec.name).origins[name].endswith(ORIGIN):
                continue
            variable = variables.get(name)
            if variable is None:
                continue
            if name in fed:
                problems.append(f"parameter '{spec.name}.{name}': a connection feeds this "
                                "input, and would replace the value before the first step")
            elif variable.type == "Real" and variable.valueReference in forces and \
                    variable.causality == "input":
                problems.append(f"parameter '{spec.name}.{name}': a joint sets this port "
                                "force every step, and would replace the value")
    return problems


def require_mapping(parameters) -> dict:
    """``parameters`` as a dict of names (InputError when it is not a mapping)."""
    if parameters is None:
        return {}
    if not hasattr(parameters, "items"):
        raise InputError(f"parameters: give a mapping of NAME -> value, not "
                         f"{type(parameters).__name__}")
    return dict(parameters.items())
