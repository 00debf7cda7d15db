"""The SI units of every variable of dsim's own FMUs, written into their
modelDescription.xml when ``dsim build-fmus`` builds them.

pythonfmu 0.7 writes no ``unit`` attribute and no UnitDefinitions, so the build
completes the XML (FMI 2.0 section 2.2.2): a ``<UnitDefinitions>`` element with the
units the FMU uses, each with its SI base exponents (``<BaseUnit kg="1" m="1"
s="-2"/>``) and, where it helps a reader, a display unit (``deg`` for ``rad``), and
``unit`` (and ``displayUnit``) on each ``<Real>``.  The table is the one place that
says a variable's unit: a Real variable of a shipped FMU that no rule names fails
the build, so a new variable cannot ship without one.  Only the XML changes: the
FMU's code, its GUID and every number it computes stay as they were.
"""
from __future__ import annotations

import re

from lxml import etree

#: unit name -> (SI base exponents, display units as (name, factor)) with
#: value_display = factor * value (FMI 2.0 DisplayUnit, offset 0 here)
UNITS = {
    "m": ({"m": 1}, ()),
    "m/s": ({"m": 1, "s": -1}, ()),
    "m/s2": ({"m": 1, "s": -2}, ()),
    "rad": ({"rad": 1}, (("deg", 57.29577951308232),)),
    "rad/s": ({"rad": 1, "s": -1}, (("deg/s", 57.29577951308232),)),
    "rad/s2": ({"rad": 1, "s": -2}, (("deg/s2", 57.29577951308232),)),
    "N": ({"kg": 1, "m": 1, "s": -2}, ()),
    "N.m": ({"kg": 1, "m": 2, "s": -2}, ()),
    "kg": ({"kg": 1}, ()),
    "kg.m": ({"kg": 1, "m": 1}, ()),
    "kg/m3": ({"kg": 1, "m": -3}, ()),
    "N/m": ({"kg": 1, "s": -2}, ()),
    "N/m2": ({"kg": 1, "m": -1, "s": -2}, ()),
    "N.s/m": ({"kg": 1, "s": -1}, ()),
    "N.s2/m2": ({"kg": 1, "m": -1}, ()),
    "Pa": ({"kg": 1, "m": -1, "s": -2}, (("MPa", 1e-6),)),
    "m2": ({"m": 2}, ()),
    "m4": ({"m": 4}, ()),
    "s": ({"s": 1}, ()),
    "1/s": ({"s": -1}, ()),
    "Hz": ({"s": -1}, ()),
}
#: the display unit a variable of each unit shows in, where one helps
DISPLAY = {"rad": "deg"}

#: the unit of each kinematic and force variable of a port (DESIGN.md, "Ports"):
#: translations (x y z) and rotations (rx ry rz)
_PORT = [(r"(^|\.)f_[xyz]$", "N"), (r"(^|\.)f_r[xyz]$", "N.m"),
         (r"(^|\.)u_[xyz]$", "m"), (r"(^|\.)u_r[xyz]$", "rad"),
         (r"(^|\.)v_[xyz]$", "m/s"), (r"(^|\.)v_r[xyz]$", "rad/s"),
         (r"(^|\.)a_[xyz]$", "m/s2"), (r"(^|\.)a_r[xyz]$", "rad/s2")]

#: model identifier -> [(regular expression on the variable name, unit)], the first
#: match wins; "" is a Real without a unit (a ratio, a count, a quantity of mixed units)
RULES = {
    "SpringMass": _PORT + [
        (r"^m\[", "kg"), (r"^(k|k_ground)\[", "N/m"), (r"^(k1|k1_ground)\[", "N/m2"),
        (r"^(c|c_ground)\[", "N.s/m"), (r"^(c1|c1_ground)\[", "N.s2/m2"),
        (r"^(F0|Fa)\[", "N"), (r"^omega\[", "rad/s"), (r"^phase\[", "rad"),
        (r"^(x0|x|bump)\[", "m"), (r"^(v0|v)\[", "m/s"), (r"^a\[", "m/s2"),
        (r"^(bump_start|bump_duration)\[", "s")],
    "ElasticBody": _PORT + [
        (r"\.F0?_[xyz]$", "N"), (r"^thickness$", "m"), (r"^youngs_modulus$", "Pa"),
        (r"^poisson_ratio$", ""), (r"^density$", "kg/m3"), (r"^rayleigh_alpha$", "1/s"),
        (r"^rayleigh_beta$", "s"), (r"^load_frequency$", "Hz")],
    "Linkage2D": _PORT + [
        (r"^(x|y)$", "m"), (r"^theta$", "rad"), (r"^(vx|vy)$", "m/s"), (r"^omega$", "rad/s"),
        (r"^(ax|ay)$", "m/s2"), (r"^alpha$", "rad/s2"), (r"^torque$", "N.m"),
        (r"^baumgarte_frequency$", "rad/s"),
        # xi and rho_inf are ratios; the drift is m for some constraint rows, rad for
        # others; the counts are counts
        (r"^(baumgarte_damping|spectral_radius|constraint_violation|newton_iterations"
         r"|newton_roundoff_steps)$", "")],
    "FlexibleLink2D": _PORT + [
        (r"^(length|x0|y0|reference\.x|reference\.y|deflection|stretch)$", "m"),
        (r"^density$", "kg/m3"), (r"^area$", "m2"), (r"^young$", "Pa"),
        (r"^second_moment$", "m4"), (r"^stiffness_damping$", "s"),
        (r"^(theta0|reference\.theta)$", "rad"),
        (r"^(vx0|vy0|reference\.vx|reference\.vy)$", "m/s"),
        (r"^(omega0|omega|reference\.omega)$", "rad/s"), (r"^reference\.alpha$", "rad/s2"),
        (r"^(gravity_x|gravity_y)$", "m/s2"), (r"^mean_axis_violation$", "kg.m"),
        (r"^(tolerance|pim_iterations)$", "")],
}


def unit_of(identifier: str, name: str) -> str:
    """The unit of variable ``name`` of FMU ``identifier`` ("" for none); KeyError
    when no rule names it (the build stops: every Real gets a decision)."""
    for pattern, unit in RULES[identifier]:
        if re.search(pattern, name):
            return unit
    raise KeyError(f"{identifier}: no unit is declared for Real variable '{name}' "
                   "(build_fmus/units.py)")


def add_units(root, identifier: str) -> None:
    """Complete a parsed FMI 2.0 modelDescription (``root``) of FMU ``identifier`` with
    its UnitDefinitions and the ``unit``/``displayUnit`` of every Real variable."""
    used = []
    for variable in root.find("ModelVariables"):
        real = variable.find("Real")
        if real is None:
            continue
        unit = unit_of(identifier, variable.get("name"))
        if unit:
            real.set("unit", unit)
            if unit in DISPLAY:
                real.set("displayUnit", DISPLAY[unit])
            used.append(unit)
    old = root.find("UnitDefinitions")
    if old is not None:
        root.remove(old)
    if not used:
        return
    definitions = etree.Element("UnitDefinitions")
    for name in dict.fromkeys(used):
        exponents, displays = UNITS[name]
        unit = etree.SubElement(definitions, "Unit", name=name)
        etree.SubElement(unit, "BaseUnit", {k: str(v) for k, v in exponents.items()})
        for display, factor in displays:
            etree.SubElement(unit, "DisplayUnit", name=display, factor=repr(factor))
    # FMI 2.0's order: ModelExchange?, CoSimulation?, UnitDefinitions, TypeDefinitions, ...
    anchor = None
    for tag in ("CoSimulation", "ModelExchange"):
        found = root.find(tag)
        if found is not None and (anchor is None or root.index(found) > root.index(anchor)):
            anchor = found
    root.insert(root.index(anchor) + 1 if anchor is not None else 0, definitions)
