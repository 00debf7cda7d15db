"""One FMU variable layout for every planar mechanism.

An FMU's variables are fixed by its modelDescription, while mechanisms have
different ports (the shipped parts: crank A; coupler A, B; slider P; rocker B) and
bodies.  :class:`PartCore` wraps the :class:`~dsim.fmus.linkage.core.Linkage` of one
mechanism behind the union of the ports, ``FIXED_PORTS`` = A, B, P with dofs x y,
and a fixed list of outputs (``PART_OUTPUTS``: its first body).  A port the
mechanism does not have takes no force and reports zero motion; a scene glues only
ports it has.

What the mechanism is comes from the parameter ``mechanism``: a description
(JSON text, :mod:`dsim.fmus.linkage.description`) or the name of a file holding one in
the FMU's resources folder.  dsim's scenes write their parts this way
(build_fmus/linkage_scenes.py); nothing in the FMU knows them.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..interface import InterfaceCore

from .core import Linkage
from .description import mechanism_from_text

FIXED_PORTS = ("A", "B", "P")
FIXED_INTERFACE = tuple((p, d) for p in FIXED_PORTS for d in ("x", "y"))
#: Outputs of a part: its body's CG pose (m, rad), rates and accelerations, the
#: driving torque on it (N.m, 0 without a driver), constraint drift, Newton count of the
#: last step and the steps whose Newton ended at the residual's round-off floor so far.
PART_OUTPUTS = ("x", "y", "theta", "vx", "vy", "omega", "ax", "ay", "alpha", "torque",
                "constraint_violation", "newton_iterations", "newton_roundoff_steps")


#: The FMU's default mechanism, so that it runs alone: a 1 m, 1 kg bar pinned to ground
#: at one end, released horizontal under gravity, port A at its free end.
PENDULUM = ('{"bodies":[{"name":"bar","mass":1.0,"inertia":0.08333333333333333,"x":0.5}],'
            '"revolutes":[{"name":"O","body_i":"bar","point_i":[-0.5,0.0],"body_j":null,'
            '"point_j":[0.0,0.0]}],"ports":[{"name":"A","body":"bar","point":[0.5,0.0]}],'
            '"gravity":[0.0,-9.81]}')


@dataclass
class PartParameters:
    """The mechanism (a description or a resources file), the constraint rows'
    stabilisation (w rad/s, xi) and the integrator's spectral radius rho_inf
    (1: the trapezoidal rule; below 1: generalized-alpha, fmus/generalized_alpha.py)."""

    mechanism: str = PENDULUM
    formulation: str = "baumgarte"
    baumgarte_frequency: float = 1000.0
    baumgarte_damping: float = 1.0
    spectral_radius: float = 1.0

    def check(self) -> None:
        """Raise ValueError naming the parameter that is wrong."""
        if self.formulation not in ("baumgarte", "index3"):
            raise ValueError("parameter 'formulation' must be baumgarte or index3")
        if not 0.0 <= self.spectral_radius <= 1.0:
            raise ValueError(f"parameter 'spectral_radius' must be in [0, 1] (1: the "
                             f"trapezoidal rule), not {self.spectral_radius:g}")
        if not self.mechanism.strip():
            raise ValueError("parameter 'mechanism' is empty: give a description (JSON "
                             "text) or a file of the FMU's resources folder")


def described(text: str, resources=None):
    """The mechanism of the parameter ``mechanism``: JSON text, or a file of the FMU's
    resources folder holding it; its ports must be among the FMU's A, B, P (x y)."""
    if not text.lstrip().startswith("{"):
        path = Path(resources or ".") / text
        try:
            text = path.read_text()
        except OSError as error:
            raise ValueError(f"parameter 'mechanism': cannot read {text!r} in the FMU's "
                             f"resources folder: {error.strerror or error}") from None
    mech = mechanism_from_text(text)
    for port in mech.ports:
        wrong = [d for d in port.dofs if (port.name, d) not in FIXED_INTERFACE]
        if wrong:
            raise ValueError(f"port {port.name} ({' '.join(port.dofs)}): the Linkage2D FMU "
                             f"glues ports {', '.join(FIXED_PORTS)} with dofs x y")
    return mech


def build_part(p: PartParameters, resources=None) -> Linkage:
    """The :class:`~dsim.fmus.linkage.core.Linkage` of the described mechanism."""
    p.check()
    return Linkage(described(p.mechanism, resources), formulation=p.formulation,
                   baumgarte_frequency=p.baumgarte_frequency,
                   baumgarte_damping=p.baumgarte_damping,
                   spectral_radius=p.spectral_radius)


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
        out["newton_roundoff_steps"] = inner["newton_roundoff_steps"]
        return out
