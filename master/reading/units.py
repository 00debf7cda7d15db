"""Unit conversion between connected variables (SSP 1.0 Units, FMI 2.0 UnitDefinitions).

A unit is its SI base exponents (kg m s A K mol cd rad) and value_SI = factor * value +
offset; a connection converts from its start unit to its end unit when both are known
and differ, and refuses units of different dimensions.  Written here because a unit
is three numbers and two tables, which no maintained package reads from SSP and FMI.
"""
from __future__ import annotations

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
