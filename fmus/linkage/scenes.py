"""Builders of the shipped mechanisms, whole (monolithic reference) or as glueable parts.

Crank slider (seed section 4.2.1, SCENES.md crank_slider_*), initial geometry with the
crank along +x, everything at rest (the crank law starts from zero speed):

    ground pivot O = (0, 0); crank tip A = (l1, 0); coupler A -> B = (l1 + l2, 0);
    slider at B on the line y = 0.

Bodies: ``crank`` (m1, I1 = m1 l1^2/12, CG at (l1/2, 0)), ``coupler`` (rho b^2 l2,
m l2^2/12, CG at (l1 + l2/2, 0)), ``slider`` (m3; its angle is locked, inertia 1).
Joints: revolute ``O`` (crank-ground), ``A`` (body_i coupler, body_j crank), ``B``
(body_i slider, body_j coupler), prismatic ``rail`` (slider on y = 0), driver
``drive`` (crank angle, w(t) = w (1 - cos(pi t / T)) / 2 for t < T, w after).
Ports (dofs x y): part ``crank`` has ``A``; part ``coupler`` has ``A`` and ``B``; part
``slider`` has ``P``; the whole mechanism has all three (crank tip ``A``, coupler end
``B``, slider ``P``) for observation.  Reactions ``A.f_x`` etc. of the whole model are
the force on body_i, which is the force the glue gives port b of joints
A = (crank.A, coupler.A) and B = (coupler.B, slider.P).

Four bar (seed section 5.3.2, SCENES.md four_bar_singular): a parallelogram with ground
pivots O1 = (0, 0), O2 = (2, 0), crank 1 m, coupler 2 m, rocker 1 m, uniform bars of
1 kg/m (I = m l^2/12), crank at 45 degrees at t = 0 driven at 2 pi rad/s; the coupler
starts from A = (cos 45, sin 45) to B = A + (2, 0).  Joints ``O1``, ``O2`` to ground,
``A`` (body_i coupler, body_j crank), ``B`` (body_i rocker, body_j coupler); with
``joints="flexible"`` A and B are :class:`Bushing` elements (k, c) instead.  Parts:
``crank`` (port A), ``coupler`` (ports A, B), ``rocker`` (port B).

Parts take their initial velocities from the whole mechanism (initialized at
``start_time``), so the glued and monolithic models start from the same state.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass

from .core import Linkage
from .elements import (AngleDriver, Body, Bushing, Mechanism, Port, Prismatic, Revolute)
from .laws import ConstantSpeed, CosineRampSpeed

CRANK_SLIDER_PARTS = ("crank", "coupler", "slider")
FOUR_BAR_PARTS = ("crank", "coupler", "rocker")


@dataclass(frozen=True)
class CrankSliderParameters:
    """The seed's crank slider (SI units): crank mass and length, coupler length,
    square section side and density, slider mass, crank speed law, gravity."""

    crank_mass: float = 50.0
    crank_length: float = 3.0
    coupler_length: float = 6.0
    coupler_section: float = 0.1
    coupler_density: float = 7850.0
    slider_mass: float = 20.0
    speed: float = 2.0 * math.pi
    ramp_time: float = 1.0
    gravity: tuple[float, float] = (0.0, 0.0)

    @property
    def coupler_mass(self) -> float:
        """rho b^2 l2 (kg): 471 for the seed's steel coupler."""
        return self.coupler_density * self.coupler_section ** 2 * self.coupler_length


def crank_slider_mechanism(params: CrankSliderParameters = CrankSliderParameters()) -> Mechanism:
    """The whole crank slider as a :class:`Mechanism` (see module docstring)."""
    l1, l2 = params.crank_length, params.coupler_length
    m1, m2 = params.crank_mass, params.coupler_mass
    return Mechanism(
        bodies=[Body("crank", m1, m1 * l1 ** 2 / 12.0, x=l1 / 2.0),
                Body("coupler", m2, m2 * l2 ** 2 / 12.0, x=l1 + l2 / 2.0),
                Body("slider", params.slider_mass, 1.0, x=l1 + l2)],
        revolutes=[Revolute("O", "crank", (-l1 / 2.0, 0.0), None, (0.0, 0.0)),
                   Revolute("A", "coupler", (-l2 / 2.0, 0.0), "crank", (l1 / 2.0, 0.0)),
                   Revolute("B", "slider", (0.0, 0.0), "coupler", (l2 / 2.0, 0.0))],
        prismatics=[Prismatic("rail", "slider")],
        drivers=[AngleDriver("drive", "crank",
                             CosineRampSpeed(0.0, params.speed, params.ramp_time))],
        ports=[Port("A", "crank", (l1 / 2.0, 0.0)), Port("B", "coupler", (l2 / 2.0, 0.0)),
               Port("P", "slider", (0.0, 0.0))],
        gravity=params.gravity)


def four_bar_mechanism(joints: str = "fixed", stiffness: float = 1e6,
                       damping: float = 2 * 0.707 * 1e3,
                       gravity: tuple[float, float] = (0.0, 0.0),
                       speed: float = 2.0 * math.pi,
                       angle0: float = math.pi / 4) -> Mechanism:
    """The whole parallelogram four bar (see module docstring); ``joints`` is
    ``"fixed"`` (revolutes A, B) or ``"flexible"`` (bushings A, B: k N/m, c N.s/m)."""
    c, s = math.cos(angle0), math.sin(angle0)
    ax, ay = c, s
    mech = Mechanism(
        bodies=[Body("crank", 1.0, 1.0 / 12.0, x=0.5 * c, y=0.5 * s, theta=angle0),
                Body("coupler", 2.0, 2.0 * 4.0 / 12.0, x=ax + 1.0, y=ay),
                Body("rocker", 1.0, 1.0 / 12.0, x=2.0 + 0.5 * c, y=0.5 * s, theta=angle0)],
        revolutes=[Revolute("O1", "crank", (-0.5, 0.0), None, (0.0, 0.0)),
                   Revolute("O2", "rocker", (-0.5, 0.0), None, (2.0, 0.0))],
        drivers=[AngleDriver("drive", "crank", ConstantSpeed(angle0, speed))],
        ports=[Port("A", "crank", (0.5, 0.0)), Port("B", "coupler", (1.0, 0.0))],
        gravity=gravity)
    pins = [("A", "coupler", (-1.0, 0.0), "crank", (0.5, 0.0)),
            ("B", "rocker", (0.5, 0.0), "coupler", (1.0, 0.0))]
    for name, bi, si, bj, sj in pins:
        if joints == "fixed":
            mech.revolutes.append(Revolute(name, bi, si, bj, sj))
        elif joints == "flexible":
            mech.bushings.append(Bushing(name, bi, si, bj, sj, stiffness, damping))
        else:
            raise ValueError(f"joints must be 'fixed' or 'flexible', not {joints!r}")
    return mech


def _initialized_whole(mech: Mechanism, start_time: float, **kwargs) -> Linkage:
    whole = Linkage(copy.deepcopy(mech), **kwargs)
    whole.initialize(start_time)
    return whole


def _part(mech: Mechanism, body: str, ports: list[Port], whole: Linkage) -> Mechanism:
    """The sub-mechanism of one body: its ground joints and drivers, the given ports,
    and its initial pose and rates taken from the initialized whole ``whole``."""
    i = whole.body_names.index(body)
    b = copy.deepcopy(next(x for x in mech.bodies if x.name == body))
    b.x, b.y, b.theta = (float(v) for v in whole.q[i])
    b.vx, b.vy, b.omega = (float(v) for v in whole.v[i])
    return Mechanism(
        bodies=[b],
        revolutes=[j for j in mech.revolutes if j.body_i == body and j.body_j is None],
        prismatics=[p for p in mech.prismatics if p.body == body],
        drivers=[d for d in mech.drivers if d.body_i == body and d.body_j is None],
        ports=ports, gravity=mech.gravity)


def crank_slider(part: str = "whole", params: CrankSliderParameters = CrankSliderParameters(),
                 start_time: float = 0.0, **linkage_options) -> Linkage:
    """A :class:`Linkage` of the whole crank slider or of one part
    (``"crank"``, ``"coupler"``, ``"slider"``); options go to :class:`Linkage`."""
    if part == "whole":
        return Linkage(crank_slider_mechanism(params), **linkage_options)
    return Linkage(crank_slider_part(part, params, start_time, **linkage_options),
                   **linkage_options)


def crank_slider_part(part: str, params: CrankSliderParameters = CrankSliderParameters(),
                      start_time: float = 0.0, **linkage_options) -> Mechanism:
    """The :class:`Mechanism` of one crank slider part, its initial state from the
    whole mechanism initialized at ``start_time``."""
    mech = crank_slider_mechanism(params)
    whole = _initialized_whole(mech, start_time, **linkage_options)
    l1, l2 = params.crank_length, params.coupler_length
    ports = {"crank": [Port("A", "crank", (l1 / 2.0, 0.0))],
             "coupler": [Port("A", "coupler", (-l2 / 2.0, 0.0)),
                         Port("B", "coupler", (l2 / 2.0, 0.0))],
             "slider": [Port("P", "slider", (0.0, 0.0))]}
    if part not in ports:
        raise ValueError(f"crank slider part must be whole or one of {CRANK_SLIDER_PARTS}")
    return _part(mech, part, ports[part], whole)


def four_bar(part: str = "whole", joints: str = "fixed", stiffness: float = 1e6,
             damping: float = 2 * 0.707 * 1e3, gravity: tuple[float, float] = (0.0, 0.0),
             start_time: float = 0.0, **linkage_options) -> Linkage:
    """A :class:`Linkage` of the whole four bar or of one part
    (``"crank"``, ``"coupler"``, ``"rocker"``); parts are the same for both joint kinds."""
    if part == "whole":
        return Linkage(four_bar_mechanism(joints, stiffness, damping, gravity),
                       **linkage_options)
    return Linkage(four_bar_part(part, gravity, start_time, **linkage_options),
                   **linkage_options)


def four_bar_part(part: str, gravity: tuple[float, float] = (0.0, 0.0),
                  start_time: float = 0.0, **linkage_options) -> Mechanism:
    """The :class:`Mechanism` of one four bar part (the same for both joint kinds),
    its initial state from the whole fixed-joint four bar initialized at
    ``start_time``."""
    mech = four_bar_mechanism("fixed", gravity=gravity)
    whole = _initialized_whole(mech, start_time, **linkage_options)
    ports = {"crank": [Port("A", "crank", (0.5, 0.0))],
             "coupler": [Port("A", "coupler", (-1.0, 0.0)), Port("B", "coupler", (1.0, 0.0))],
             "rocker": [Port("B", "rocker", (0.5, 0.0))]}
    if part not in ports:
        raise ValueError(f"four bar part must be whole or one of {FOUR_BAR_PARTS}")
    return _part(mech, part, ports[part], whole)


def crank_angle(t: float, params: CrankSliderParameters = CrankSliderParameters()) -> float:
    """The prescribed crank angle (rad) at time t (s)."""
    return CosineRampSpeed(0.0, params.speed, params.ramp_time)(t)[0]
