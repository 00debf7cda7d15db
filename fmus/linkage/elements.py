"""The parts list of a planar mechanism: bodies, joints, drivers, force elements, ports.

Conventions (SI units throughout):

* A body's coordinates are the global position (x, y) of its centre of gravity (m)
  and its angle theta (rad, counter-clockwise from the global x axis).
* A point of a body is given by its local coordinates (m) in the body frame,
  whose origin is the centre of gravity.
* ``None`` as a body name means ground.  Ground points are global coordinates.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Optional

Law = Callable[[float], tuple[float, float, float]]


@dataclass
class Body:
    """A rigid body: mass (kg), inertia about the CG (kg.m^2), initial pose and rates.

    x, y (m) and theta (rad) place the CG; vx, vy (m/s) and omega (rad/s) are
    initial rates (projected onto the constraints at initialization).
    """

    name: str
    mass: float
    inertia: float
    x: float = 0.0
    y: float = 0.0
    theta: float = 0.0
    vx: float = 0.0
    vy: float = 0.0
    omega: float = 0.0


@dataclass
class Revolute:
    """Pin joint: point ``point_i`` of ``body_i`` coincides with ``point_j`` of ``body_j``.

    The reaction reported as ``<name>.f_x``, ``<name>.f_y`` is the force (N, global)
    that body_j exerts on body_i at the pin (the opposite acts on body_j).
    """

    name: str
    body_i: str
    point_i: tuple[float, float]
    body_j: Optional[str]
    point_j: tuple[float, float]


@dataclass
class Prismatic:
    """Slider on ground: ``point`` of ``body`` moves on the ground line through ``origin``
    with unit direction ``axis``, and the body keeps its initial angle.

    (Prismatic joints between two moving bodies are not implemented.)
    """

    name: str
    body: str
    point: tuple[float, float] = (0.0, 0.0)
    origin: tuple[float, float] = (0.0, 0.0)
    axis: tuple[float, float] = (1.0, 0.0)


@dataclass
class AngleDriver:
    """Prescribed angle theta_i - theta_j = law(t) (rad); body_j None means ground.

    ``law`` returns (angle, rate, acceleration); see :mod:`dsim.fmus.linkage.laws`.
    """

    name: str
    body_i: str
    law: Law
    body_j: Optional[str] = None


@dataclass
class SpringDamper:
    """Linear spring-damper between two points: tension (N) = k (L - length0) + c dL/dt.

    L is the distance between ``point_i`` of ``body_i`` and ``point_j`` of ``body_j``
    (body_j None: a ground point).  k in N/m, c in N.s/m, length0 in m.
    """

    name: str
    body_i: str
    point_i: tuple[float, float]
    body_j: Optional[str]
    point_j: tuple[float, float]
    stiffness: float
    damping: float = 0.0
    length0: float = 0.0


@dataclass
class Bushing:
    """Kelvin-Voigt bushing in global x and y (a flexible revolute joint, seed eq. 5.3).

    With q = p_i - p_j (m), the force on body_i is -(k q + c dq/dt) (N) and the
    opposite acts on body_j: the monolithic twin of a flexible glue joint.
    """

    name: str
    body_i: str
    point_i: tuple[float, float]
    body_j: Optional[str]
    point_j: tuple[float, float]
    stiffness: float
    damping: float = 0.0


@dataclass
class Port:
    """A glue point: ``point`` (local, m) of ``body`` with dofs among ``x y rz``.

    Input forces (N, global frame; N.m for rz) act on the body at the point; the
    outputs are the point's global position, velocity and acceleration.
    """

    name: str
    body: str
    point: tuple[float, float] = (0.0, 0.0)
    dofs: tuple[str, ...] = ("x", "y")


@dataclass
class Mechanism:
    """Everything a :class:`~dsim.fmus.linkage.core.Linkage` is built from.

    ``gravity`` is the global acceleration of gravity (m/s^2), e.g. (0, -9.81).
    """

    bodies: list[Body] = field(default_factory=list)
    revolutes: list[Revolute] = field(default_factory=list)
    prismatics: list[Prismatic] = field(default_factory=list)
    drivers: list[AngleDriver] = field(default_factory=list)
    springs: list[SpringDamper] = field(default_factory=list)
    bushings: list[Bushing] = field(default_factory=list)
    ports: list[Port] = field(default_factory=list)
    gravity: tuple[float, float] = (0.0, 0.0)

    def validate(self) -> None:
        """Raise ValueError naming the first inconsistent element."""
        names = [b.name for b in self.bodies]
        if len(set(names)) != len(names):
            raise ValueError(f"body names must be unique: {names}")
        if not names:
            raise ValueError("a mechanism needs at least one body")
        for b in self.bodies:
            if not (b.mass > 0 and b.inertia > 0):
                raise ValueError(f"body {b.name}: mass and inertia must be positive")
        known = set(names) | {None}
        for group in (self.revolutes, self.springs, self.bushings):
            for e in group:
                if e.body_i not in known or e.body_j not in known or e.body_i is None:
                    raise ValueError(f"{e.name}: unknown body {e.body_i!r} or {e.body_j!r}")
        for d in self.drivers:
            if d.body_i not in known or d.body_j not in known or d.body_i is None:
                raise ValueError(f"driver {d.name}: unknown body")
        for p in self.prismatics:
            if p.body not in names:
                raise ValueError(f"prismatic {p.name}: unknown body {p.body!r}")
        ports = [p.name for p in self.ports]
        if len(set(ports)) != len(ports):
            raise ValueError(f"port names must be unique: {ports}")
        for p in self.ports:
            if p.body not in names:
                raise ValueError(f"port {p.name}: unknown body {p.body!r}")
            bad = [d for d in p.dofs if d not in ("x", "y", "rz")]
            if bad or not p.dofs:
                raise ValueError(f"port {p.name}: dofs must be among x y rz, got {p.dofs}")
