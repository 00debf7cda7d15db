"""Unit conversion between connected variables (SSP 1.0 Units, FMI 2.0 UnitDefinitions).

A unit is its SI base exponents (kg m s A K mol cd rad) and value_SI = factor * value +
offset; a connection converts from its start unit to its end unit when both are known
and differ, and refuses units of different dimensions.  Written here because a unit
is three numbers and two tables, which no maintained package reads from SSP and FMI.
"""
from __future__ import annotations

import math

from dsim.master.reading.fmi_description import describe as describe_fmu
from dsim.master.reading.ssp_values import BASE_UNITS
from dsim.master.scene import Unit


def variable_unit(variable) -> str | None:
    """The unit name of an FMU variable (its own, or its declared type's: the
    description resolves it)."""
    return variable.unit


def fmu_units(path) -> dict[str, Unit]:
    """name -> Unit of an FMU's UnitDefinitions."""
    result = {}
    for unit in describe_fmu(path).unitDefinitions:
        if unit.exponents is None:
            result[unit.name] = Unit(unit.name, (0,) * len(BASE_UNITS))
        else:
            result[unit.name] = Unit(unit.name, tuple(unit.exponents[b] for b in BASE_UNITS),
                                     unit.factor, unit.offset)
    return result


def describe(unit: Unit) -> str:
    """The unit's dimension as base exponents ('m s-1'; '1' for none)."""
    parts = [f"{b}{'' if e == 1 else e}" for b, e in zip(BASE_UNITS, unit.exponents) if e]
    return " ".join(parts) or "1"


def conversion(start: Unit, end: Unit) -> tuple[float, float]:
    """(factor, offset) with value_end = factor * value_start + offset; ValueError for
    units of different dimensions."""
    if start.exponents != end.exponents:
        raise ValueError(f"'{start.name}' ({describe(start)}) and '{end.name}' "
                         f"({describe(end)}) are not the same dimension")
    return start.factor / end.factor, (start.offset - end.offset) / end.factor


def same_unit(first: str, second: str, known: dict) -> bool:
    """Whether unit names ``first`` and ``second`` mean one unit: the same name, or two
    definitions (``known``: name -> Unit) with the same exponents, factor and offset."""
    if first == second:
        return True
    a, b = known.get(first), known.get(second)
    return a is not None and b is not None and (a.exponents, a.factor, a.offset) == (
        b.exponents, b.factor, b.offset)


def _units_by_reference(variables: dict) -> dict[int, str]:
    """value reference -> unit of the Real variables of an FMU (``variables``: by name)."""
    return {v.valueReference: v.unit for v in variables.values()
            if v.type in ("Real", "Float64", "Float32") and v.unit}


#: what a joint exchanges for each glued dof, with the port variable's kind letter
_JOINT_KINDS = (("force", "f"), ("position", "u"), ("velocity", "v"),
                ("acceleration", "a"))


def joint_unit_problem(joint, a_dofs, b_dofs, usable: dict, known: dict) -> str | None:
    """The first place where joint ``joint`` glues port variables of two units (one line),
    or None.  A joint exchanges the numbers as they are, with no conversion (unlike a
    connection), so both sides' force and kinematics of a dof must be in one unit; a side
    that declares no unit is taken as it is.  ``usable``: component path -> its
    variables by name; ``known``: component path -> its units by name (with the SSD's)."""
    by_reference = {}
    for port_dof in list(a_dofs) + list(b_dofs):
        if port_dof.component not in by_reference:
            by_reference[port_dof.component] = _units_by_reference(
                usable.get(port_dof.component, {}))
    for name, letter in _JOINT_KINDS:
        for dof in joint.dofs:
            seen = {}
            for side in (a_dofs, b_dofs):
                for port_dof in side:
                    reference = getattr(port_dof, name)
                    unit = by_reference[port_dof.component].get(reference)
                    if port_dof.dof != dof or reference is None or not unit:
                        continue
                    where = f"{port_dof.component}.{port_dof.port}.{letter}_{dof}"
                    for other_unit, (other, owner) in seen.items():
                        units = {**known.get(port_dof.component, {}), **known.get(owner, {})}
                        if not same_unit(unit, other_unit, units):
                            return (f"{joint.location}: joint '{joint.name}' glues {other} in "
                                    f"'{other_unit}' to {where} in '{unit}': a joint "
                                    "exchanges values unconverted, so both ports must use "
                                    "one unit")
                    seen.setdefault(unit, (where, port_dof.component))
    return None


def column_units(usable: dict, recorded, labels, joint_of, sides: dict) -> dict[str, str]:
    """The unit of every numeric column a run records: ``time`` in s, each output
    ``component.variable`` in its FMU variable's unit, each joint force ``J.f_dof`` in the
    unit of the force variable it feeds ('' where an FMU declares none).  ``recorded``:
    (component, variable) pairs; ``labels``, ``joint_of``: the gluing layout's force
    columns and their joints; ``sides``: joint -> (side a, side b) PortDofs."""
    units = {"time": "s"}
    for path, name in recorded:
        variable = usable.get(path, {}).get(name)
        units[f"{path}.{name}"] = (variable.unit or "") if variable is not None else ""
    by_reference = {path: _units_by_reference(variables) for path, variables in usable.items()}
    for label, joint in zip(labels, joint_of):
        dof = label.rsplit(".f_", 1)[-1]
        found = [by_reference.get(p.component, {}).get(p.force)
                 for side in sides.get(joint, ((), ())) for p in side if p.dof == dof]
        units[label] = next((u for u in found if u), "")
    return units


#: display units an FMU may name without defining them: (unit, display unit) ->
#: (factor, offset), display value = factor * value + offset
KNOWN_DISPLAY = {("rad", "deg"): (180.0 / math.pi, 0.0),
                 ("rad/s", "deg/s"): (180.0 / math.pi, 0.0),
                 ("rad/s2", "deg/s2"): (180.0 / math.pi, 0.0),
                 ("rad/s", "rpm"): (30.0 / math.pi, 0.0), ("K", "degC"): (1.0, -273.15)}


def display_unit(variable, definitions: dict) -> dict | None:
    """How the FMU would show ``variable`` (its ``displayUnit``): {"unit": the display
    unit, "factor", "offset"} with display value = factor * value + offset, from the
    FMU's DisplayUnit of the variable's unit (``definitions``: unit name ->
    UnitDefinition) or a known pair (rad -> deg); None when it declares none, or one
    it does not define and dsim does not know."""
    shown, unit = getattr(variable, "display_unit", None), variable.unit
    if not shown or not unit or shown == unit:
        return None
    defined = definitions.get(unit)
    for name, factor, offset in (defined.display if defined is not None else ()):
        if name == shown:
            return {"unit": shown, "factor": factor, "offset": offset}
    if (unit, shown) in KNOWN_DISPLAY:
        factor, offset = KNOWN_DISPLAY[unit, shown]
        return {"unit": shown, "factor": factor, "offset": offset}
    return None


def column_display_units(usable: dict, recorded, sources: dict) -> dict[str, dict]:
    """The display unit (:func:`display_unit`) of every recorded output column that
    declares one: ``usable``: component -> variable name -> Variable; ``recorded``:
    (component, variable) pairs; ``sources``: component -> its FMU."""
    result, definitions = {}, {}
    for path, name in recorded:
        variable = usable.get(path, {}).get(name)
        if variable is None or not getattr(variable, "display_unit", None):
            continue
        if path not in definitions:
            definitions[path] = {u.name: u for u in describe_fmu(sources[path]).unitDefinitions}
        shown = display_unit(variable, definitions[path])
        if shown is not None:
            result[f"{path}.{name}"] = shown
    return result
