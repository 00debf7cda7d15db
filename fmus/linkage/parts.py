"""One FMU variable layout for every part of the shipped mechanisms.

An FMU's variables are fixed by its modelDescription, while the parts of
:mod:`fmus.linkage.scenes` have different ports (crank: A; coupler: A, B;
slider: P; rocker: B) and different bodies.  :class:`PartCore` wraps the
:class:`~fmus.linkage.core.Linkage` of one part behind the union of the ports,
``FIXED_PORTS`` = A, B, P with dofs x y, and a fixed list of outputs
(``PART_OUTPUTS``: the part's one body).  A port the part does not have takes
no force and reports zero motion; the scene glues only ports the part has.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fmus.interface import InterfaceCore

from .scenes import (CRANK_SLIDER_PARTS, FOUR_BAR_PARTS, CrankSliderParameters, crank_slider,
                     four_bar)

FIXED_PORTS = ("A", "B", "P")
FIXED_INTERFACE = tuple((p, d) for p in FIXED_PORTS for d in ("x", "y"))
#: Outputs of a part: its body's CG pose (m, rad), rates and accelerations, the
#: driving torque on it (N.m, 0 without a driver), constraint drift and Newton count.
PART_OUTPUTS = ("x", "y", "theta", "vx", "vy", "omega", "ax", "ay", "alpha", "torque",
                "constraint_violation", "newton_iterations")
SCENES = {"crank_slider": CRANK_SLIDER_PARTS, "four_bar": FOUR_BAR_PARTS}


@dataclass
class PartParameters:
    """Everything that selects and sizes a part (SI units; the seed's values)."""

    scene: str = "crank_slider"
    part: str = "crank"
    crank_mass: float = 50.0
    crank_length: float = 3.0
    coupler_length: float = 6.0
    coupler_section: float = 0.1
    coupler_density: float = 7850.0
    slider_mass: float = 20.0
    speed: float = 2.0 * np.pi
    ramp_time: float = 1.0
    gravity_x: float = 0.0
    gravity_y: float = 0.0
    formulation: str = "baumgarte"
    baumgarte_frequency: float = 1000.0
    baumgarte_damping: float = 1.0

    def check(self) -> None:
        """Raise ValueError naming the parameter that is wrong."""
        if self.scene not in SCENES:
            raise ValueError(f"parameter 'scene' must be one of {sorted(SCENES)}, "
                             f"not {self.scene!r}")
        if self.part not in SCENES[self.scene]:
            raise ValueError(f"parameter 'part' of scene {self.scene} must be one of "
                             f"{SCENES[self.scene]}, not {self.part!r}")
        if self.formulation not in ("baumgarte", "index3"):
            raise ValueError("parameter 'formulation' must be baumgarte or index3")


def build_part(p: PartParameters):
    """The :class:`~fmus.linkage.core.Linkage` of one part (initial state from the
    whole mechanism at t = 0, see :mod:`fmus.linkage.scenes`)."""
    p.check()
    options = dict(formulation=p.formulation, baumgarte_frequency=p.baumgarte_frequency,
                   baumgarte_damping=p.baumgarte_damping)
    gravity = (p.gravity_x, p.gravity_y)
    if p.scene == "crank_slider":
        params = CrankSliderParameters(
            crank_mass=p.crank_mass, crank_length=p.crank_length,
            coupler_length=p.coupler_length, coupler_section=p.coupler_section,
            coupler_density=p.coupler_density, slider_mass=p.slider_mass, speed=p.speed,
            ramp_time=p.ramp_time, gravity=gravity)
        return crank_slider(p.part, params, **options)
    return four_bar(p.part, gravity=gravity, **options)


class PartCore(InterfaceCore):
    """A one-body part behind the fixed ports A, B, P (x y) and ``PART_OUTPUTS``."""

    interface = FIXED_INTERFACE

    def __init__(self, linkage):
        self.linkage = linkage
        self._index = [FIXED_INTERFACE.index(pair) for pair in linkage.interface]
        self._forces = np.zeros(len(FIXED_INTERFACE))
        self.time = linkage.time

    def initialize(self, start_time: float) -> None:
        self.linkage.initialize(start_time)
        self.time = self.linkage.time

    def set_interface_forces(self, forces: np.ndarray) -> None:
        self._forces = np.asarray(forces, dtype=float).reshape(len(FIXED_INTERFACE)).copy()
        self.linkage.set_interface_forces(self._forces[self._index])

    def step(self, time: float, step_size: float) -> None:
        self.linkage.step(time, step_size)
        self.time = self.linkage.time

    def interface_kinematics(self):
        result = []
        for values in self.linkage.interface_kinematics():
            full = np.zeros(len(FIXED_INTERFACE))
            full[self._index] = values
            result.append(full)
        return tuple(result)

    def get_state(self) -> dict:
        return {"linkage": self.linkage.get_state(), "forces": self._forces.copy()}

    def set_state(self, state: dict) -> None:
        self.linkage.set_state(state["linkage"])
        self._forces = np.array(state["forces"], dtype=float)
        self.time = self.linkage.time

    def outputs(self) -> dict[str, float]:
        inner = self.linkage.outputs()
        body = self.linkage.body_names[0]
        out = {key: inner[f"{body}.{key}"] for key in PART_OUTPUTS[:9]}
        out["torque"] = inner.get("drive.torque", 0.0)
        out["constraint_violation"] = inner["constraint_violation"]
        out["newton_iterations"] = inner["newton_iterations"]
        return out
