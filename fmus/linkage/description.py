"""A planar mechanism as a description (JSON text): what a user writes to model their
own linkage in the Linkage2D FMU, and what dsim's scenes ship in their parameter files.

The description mirrors :class:`~dsim.fmus.linkage.elements.Mechanism` (SI units, local
points in the body frame, ``null`` for ground)::

    {"bodies": [{"name": "crank", "mass": 1.0, "inertia": 0.0833,
                 "x": 0.35, "y": 0.35, "theta": 0.785, "vx": 0, "vy": 0, "omega": 6.28}],
     "revolutes": [{"name": "O1", "body_i": "crank", "point_i": [-0.5, 0],
                    "body_j": null, "point_j": [0, 0]}],
     "prismatics": [{"name": "rail", "body": "slider", "point": [0, 0],
                     "origin": [0, 0], "axis": [1, 0]}],
     "drivers": [{"name": "drive", "body_i": "crank", "body_j": null,
                  "law": {"kind": "constant_speed", "angle0": 0.785, "speed": 6.283}}],
     "springs": [{"name": "s", "body_i": ..., "point_i": ..., "body_j": ..., "point_j": ...,
                  "stiffness": 100, "damping": 1, "length0": 0.5}],
     "bushings": [{... "stiffness": 1e6, "damping": 1414}],
     "ports": [{"name": "A", "body": "crank", "point": [0.5, 0], "dofs": ["x", "y"]}],
     "gravity": [0, -9.81]}

Every list may be left out.  Laws: ``constant_speed`` (angle0, speed, start_time),
``cosine_ramp_speed`` (angle0, speed, ramp_time, start_time), ``sine_angle``
(angle0, amplitude, frequency, phase).  Any mistake is a ValueError naming the
element and the field.
"""
from __future__ import annotations

import json
from dataclasses import asdict, fields

from .elements import (AngleDriver, Body, Bushing, Mechanism, Port, Prismatic, Revolute,
                       SpringDamper)
from .laws import ConstantSpeed, CosineRampSpeed, SineAngle

#: description list -> element class
ELEMENTS = {"bodies": Body, "revolutes": Revolute, "prismatics": Prismatic,
            "drivers": AngleDriver, "springs": SpringDamper, "bushings": Bushing,
            "ports": Port}
#: law kind -> law class
LAWS = {"constant_speed": ConstantSpeed, "cosine_ramp_speed": CosineRampSpeed,
        "sine_angle": SineAngle}
_POINTS = {"point", "point_i", "point_j", "origin", "axis"}


def _element(cls, values, where: str):
    if not isinstance(values, dict):
        raise ValueError(f"{where}: must be an object, got {type(values).__name__}")
    names = {f.name for f in fields(cls)}
    unknown = sorted(set(values) - names)
    if unknown:
        raise ValueError(f"{where}: unknown field {', '.join(unknown)} (fields: "
                         f"{', '.join(sorted(names))})")
    values = dict(values)
    for key in _POINTS & set(values):
        point = values[key]
        if not (isinstance(point, (list, tuple)) and len(point) == 2):
            raise ValueError(f"{where}: {key} must be a pair [x, y], got {point!r}")
        values[key] = (float(point[0]), float(point[1]))
    if "dofs" in values:
        values["dofs"] = tuple(values["dofs"])
    if cls is AngleDriver:
        values["law"] = _law(values.get("law"), f"{where}.law")
    try:
        return cls(**values)
    except TypeError as error:  # a missing field
        raise ValueError(f"{where}: {error}") from None


def _law(values, where: str):
    if not isinstance(values, dict) or values.get("kind") not in LAWS:
        raise ValueError(f"{where}: needs a kind among {', '.join(LAWS)}")
    values = dict(values)
    cls = LAWS[values.pop("kind")]
    names = {f.name for f in fields(cls)}
    unknown = sorted(set(values) - names)
    if unknown:
        raise ValueError(f"{where}: unknown field {', '.join(unknown)} (fields: "
                         f"{', '.join(sorted(names))})")
    return cls(**{k: float(v) for k, v in values.items()})


def mechanism_from_text(text: str) -> Mechanism:
    """The checked :class:`Mechanism` of a description (JSON text)."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as error:
        raise ValueError(f"mechanism description: not JSON: {error}") from None
    if not isinstance(data, dict):
        raise ValueError("mechanism description: must be a JSON object")
    unknown = sorted(set(data) - set(ELEMENTS) - {"gravity"})
    if unknown:
        raise ValueError(f"mechanism description: unknown key {', '.join(unknown)} (keys: "
                         f"{', '.join(list(ELEMENTS) + ['gravity'])})")
    lists = {}
    for key, cls in ELEMENTS.items():
        items = data.get(key, [])
        if not isinstance(items, list):
            raise ValueError(f"mechanism description: {key} must be a list")
        lists[key] = [_element(cls, item, f"{key}[{k}]") for k, item in enumerate(items)]
    gravity = data.get("gravity", [0.0, 0.0])
    mech = Mechanism(**lists, gravity=(float(gravity[0]), float(gravity[1])))
    mech.validate()
    return mech


def mechanism_to_text(mech: Mechanism) -> str:
    """A mechanism's description (JSON text, full precision); inverse of
    :func:`mechanism_from_text`."""
    kinds = {cls: kind for kind, cls in LAWS.items()}
    data = {}
    for key in ELEMENTS:
        items = []
        for element in getattr(mech, key):
            values = asdict(element)
            if isinstance(element, AngleDriver):
                values["law"] = {"kind": kinds[type(element.law)], **asdict(element.law)}
            items.append(values)
        if items:
            data[key] = items
    data["gravity"] = list(mech.gravity)
    return json.dumps(data, separators=(",", ":"))
