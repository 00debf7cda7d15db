"""Two SpringMass FMUs glued at one joint, every parameter a knob: the testbed of the
stability table (benchmarks/stability.py) and its tests (tests/running/test_stability.py).

``left`` is m1 on a spring kg to ground; ``right`` is m2 joined to m3 by a spring k
and damper c, m3 loaded by F0 + Fa sin(omega t).  The joint ``j`` glues m1 to m2 on
x: fixed, or flexible with a spring k0 and damper c0 (linear).  m1 starts displaced
by x0 (and m2 with it when the joint is fixed), everything else at rest.

The monolithic twin is the same chain in one :class:`SpringMassChain` (m1 + m2 one
mass when the joint is fixed) with the same trapezoidal rule and step, so a glued
run that converges every step tightly equals it to the tolerance.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from dsim.build_fmus.build import pack_scene
from dsim.build_fmus.scenes import SceneWriter
from dsim.fmus.spring_mass.core import ChainParameters, SpringMassChain

ROOT = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class Testbed:
    """The testbed's parameters (SI units); ``joint`` is ``fixed`` or ``flexible``."""

    m1: float = 10.0
    m2: float = 10.0
    m3: float = 10.0
    kg: float = 100.0
    k: float = 100.0
    c: float = 0.0
    joint: str = "flexible"
    k0: float = 100.0
    c0: float = 14.14
    F0: float = 10.0
    Fa: float = 0.0
    omega: float = 0.0
    x0: float = 0.0

    def highest_period(self) -> float:
        """The shortest natural period of the glued system (s), undamped."""
        mass = np.diag([self.m1, self.m2, self.m3])
        stiffness = np.array([[self.kg, 0.0, 0.0], [0.0, self.k, -self.k],
                              [0.0, -self.k, self.k]])
        if self.joint == "flexible":
            stiffness[:2, :2] += self.k0 * np.array([[1.0, -1.0], [-1.0, 1.0]])
        else:  # m1 and m2 move as one: the fixed joint's constraint
            basis = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
            mass, stiffness = basis.T @ mass @ basis, basis.T @ stiffness @ basis
        omega2 = np.linalg.eigvals(np.linalg.solve(mass, stiffness)).real
        return float(2.0 * np.pi / np.sqrt(omega2.max()))


def write_scene(bed: Testbed, out: Path, name: str, step: float, stop: float,
                **master) -> Path:
    """The testbed as ``out/name.ssp`` (with dsim's SpringMass FMU from build/fmus)."""
    scene = SceneWriter(name, "stability testbed: " + ", ".join(
        f"{k}={v}" for k, v in asdict(bed).items()))
    scene.component("left", "SpringMass", {"n": 1, "m[1]": bed.m1, "k_ground[1]": bed.kg,
                                           "x0[1]": bed.x0, "P.mass": 1, "Q.mass": 1},
                    outputs=["x[1]", "v[1]"], inline=True)
    scene.component("right", "SpringMass", {
        "n": 2, "m[1]": bed.m2, "m[2]": bed.m3, "k[1]": bed.k, "c[1]": bed.c,
        "x0[1]": bed.x0 if bed.joint == "fixed" else 0.0, "F0[2]": bed.F0,
        "Fa[2]": bed.Fa, "omega[2]": bed.omega, "P.mass": 1, "Q.mass": 1},
        outputs=["x[1]", "x[2]", "v[1]", "v[2]"], inline=True)
    if bed.joint == "fixed":
        scene.joint("j", "left.P", "right.Q", "x")
    else:
        scene.joint("j", "left.P", "right.Q", "x", "flexible", "displacement",
                    {"k0": bed.k0, "k1": 0.0}, {"c0": bed.c0, "c1": 0.0})
    folder = out / name
    scene.write(folder, 0.0, stop, step=step, **master)
    return pack_scene(folder, ROOT / "build" / "fmus", out)


def monolithic(bed: Testbed, step: float, stop: float) -> dict:
    """The twin, one row per step: ``time``, and the glued run's columns
    (``left.x[1]``, ``right.x[1]``, ``right.x[2]`` and the velocities)."""
    params = ChainParameters(n=3 if bed.joint == "flexible" else 2)
    if bed.joint == "flexible":
        params.m[:3] = bed.m1, bed.m2, bed.m3
        params.k[:2], params.c[:2] = (bed.k0, bed.k), (bed.c0, bed.c)
        last = 2
    else:
        params.m[:2] = bed.m1 + bed.m2, bed.m3
        params.k[0], params.c[0] = bed.k, bed.c
        last = 1
    params.k_ground[0], params.x0[0] = bed.kg, bed.x0
    params.F0[last], params.Fa[last], params.omega[last] = bed.F0, bed.Fa, bed.omega
    chain = SpringMassChain(params)
    chain.initialize(0.0)
    count = round(stop / step)
    x, v = np.zeros((count + 1, params.n)), np.zeros((count + 1, params.n))
    x[0], v[0] = chain.x[:params.n], chain.v[:params.n]
    for n in range(count):
        chain.step(n * step, step)
        x[n + 1], v[n + 1] = chain.x[:params.n], chain.v[:params.n]
    second = 1 if bed.joint == "flexible" else 0  # m2's row
    return {"time": np.arange(count + 1) * step,
            "left.x[1]": x[:, 0], "right.x[1]": x[:, second], "right.x[2]": x[:, last],
            "left.v[1]": v[:, 0], "right.v[1]": v[:, second], "right.v[2]": v[:, last]}


def energy(bed: Testbed, columns: dict) -> np.ndarray:
    """Kinetic plus spring energy (J) at every row of a run or of the twin."""
    x1, x2, x3 = columns["left.x[1]"], columns["right.x[1]"], columns["right.x[2]"]
    v1, v2, v3 = columns["left.v[1]"], columns["right.v[1]"], columns["right.v[2]"]
    result = 0.5 * (bed.m1 * v1 ** 2 + bed.m2 * v2 ** 2 + bed.m3 * v3 ** 2
                    + bed.kg * x1 ** 2 + bed.k * (x3 - x2) ** 2)
    if bed.joint == "flexible":
        result = result + 0.5 * bed.k0 * (x2 - x1) ** 2
    return result
