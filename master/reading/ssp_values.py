"""SSP values: parameter sets (.ssv), parameter mappings (.ssm), transformations and
units, as SSP 1.0 writes them; the pieces the SSD reader (dsim.master.reading.ssp) assembles.

Every function reads one element and appends what is wrong with it to ``problems``
(one line: file, element, what) instead of raising, so that a scene's problems are
reported together.
"""
from __future__ import annotations

import math

from lxml import etree

from dsim.master.scene import Transformation, Unit

NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "ssm": "http://ssp-standard.org/SSP1/SystemStructureParameterMapping",
    "glue": "urn:dsim:gluing:1",
}
#: SSP type element -> the value type dsim keeps
TYPES = {"Real": "Real", "Integer": "Integer", "Enumeration": "Integer",
         "Boolean": "Boolean", "String": "String",
         # SSP 2.0 (same namespaces) names FMI 3.0's types: a value in one is still a value
         "Float64": "Real", "Float32": "Real",
         **{f"{sign}Int{bits}": "Integer" for sign in ("", "U") for bits in (8, 16, 32, 64)}}
BASE_UNITS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")


def typed_value(kind: str, text: str | None):
    """The value of an SSP typed value element (``Real``, ``Integer``, ...): raises
    ValueError for text that is not one."""
    if kind == "Real":
        value = float(text)
        if not math.isfinite(value):
            raise ValueError(text)
        return value
    if kind in ("Integer", "Enumeration"):
        return int(text)
    if kind == "Boolean":
        if text not in ("true", "false", "1", "0"):
            raise ValueError(text)
        return text in ("true", "1")
    return text or ""


def _is_integer(text: str) -> bool:
    try:
        int(text)
    except ValueError:
        return False
    return True


def parameter_set(root, where: str, problems: list) -> dict:
    """name -> (type, value) of an ``ssv:ParameterSet`` element."""
    values = {}
    for parameter in root.iterfind(".//ssv:Parameter", NS):
        name = parameter.get("name", "")
        for child in parameter:
            kind = etree.QName(child).localname
            if kind not in TYPES:
                continue
            text = child.get("value")
            if kind == "Enumeration" and text and not _is_integer(text):
                # SSP 1.0 gives an enumeration value as the item's name ("Option 2"):
                # the plan maps it to the value of that item of the FMU variable's type
                values[name] = ("Enumeration", text)
                continue
            try:
                values[name] = (TYPES[kind], typed_value(TYPES[kind], text))
            except (TypeError, ValueError):
                problems.append(f"{where}: parameter '{name}' has bad {kind} value '{text}'")
    return values


def transformation(element, where: str, problems: list) -> Transformation | None:
    """The transformation an ``ssc`` transformation choice element holds (a connection's
    or a mapping entry's), or None if the element has none."""
    for kind, tag in (("linear", "LinearTransformation"),
                      ("boolean", "BooleanMappingTransformation"),
                      ("integer", "IntegerMappingTransformation"),
                      ("enumeration", "EnumerationMappingTransformation")):
        found = element.find(f"ssc:{tag}", NS)
        if found is None:
            continue
        if kind == "linear":
            try:
                factor = float(found.get("factor", 1.0))
                offset = float(found.get("offset", 0.0))
            except ValueError:
                problems.append(f"{where}: LinearTransformation factor and offset must be "
                                "numbers")
                return None
            return Transformation("linear", factor, offset)
        table = []
        value_kind = {"boolean": "Boolean", "integer": "Integer", "enumeration": "String"}[kind]
        for entry in found.iterfind("ssc:MapEntry", NS):
            try:
                pair = tuple(typed_value(value_kind, entry.get(side))
                             for side in ("source", "target"))
            except (TypeError, ValueError):
                problems.append(f"{where}: {tag} MapEntry source '{entry.get('source')}' "
                                f"target '{entry.get('target')}' is not a {kind} pair")
                continue
            table.append(pair)
        return Transformation(kind, table=tuple(table))
    return None


def parameter_mapping(root, where: str, problems: list, warnings: list) -> dict:
    """source name -> (target name, transformation or None) of an
    ``ssm:ParameterMapping`` element.  Entries with an empty source (OpenModelica
    writes hundreds: one per model parameter, most mapping nothing) map nothing:
    skipped, with one warning for them all."""
    mapping = {}
    empty = []
    for entry in root.iterfind("ssm:MappingEntry", NS):
        source, target = entry.get("source"), entry.get("target")
        if source == "" and target is not None:
            empty.append(target)
            continue
        if not source or not target:
            problems.append(f"{where}: MappingEntry needs source and target")
            continue
        mapping[source] = (target, transformation(entry, f"{where}: MappingEntry '{source}'",
                                                  problems))
    if empty:
        warnings.append(f"{where}: {len(empty)} MappingEntry with an empty source skipped "
                        f"(targets {', '.join(empty[:3])}{', ...' if len(empty) > 3 else ''})")
    return mapping


def apply_mapping(values: dict, mapping: dict, where: str, problems: list) -> dict:
    """Parameter values renamed and transformed by a mapping (unmapped names stay)."""
    result = {}
    for name, (kind, value) in values.items():
        if name not in mapping:
            result[name] = (kind, value)
            continue
        target, change = mapping[name]
        if change is not None:
            try:
                value = change.apply(value)
            except (KeyError, TypeError) as error:
                problems.append(f"{where}: parameter '{name}': mapping has no entry for "
                                f"{error}")
                continue
        result[target] = (kind, value)
    return result


def units(root, where: str, problems: list) -> dict[str, Unit]:
    """name -> Unit of an SSD's ``ssd:Units`` (SSP units by SI base exponents)."""
    result = {}
    for element in root.iterfind("ssd:Units/ssc:Unit", NS):
        name = element.get("name", "")
        base = element.find("ssc:BaseUnit", NS)
        try:
            exponents = tuple(int(base.get(b, 0)) if base is not None else 0
                              for b in BASE_UNITS)
            factor = float(base.get("factor", 1.0)) if base is not None else 1.0
            offset = float(base.get("offset", 0.0)) if base is not None else 0.0
        except ValueError:
            problems.append(f"{where}: Unit '{name}': BaseUnit attributes must be numbers")
            continue
        result[name] = Unit(name, exponents, factor, offset)
    return result
