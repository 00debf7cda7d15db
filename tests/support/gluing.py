"""Marching in-process cores glued by the master's own T-T algorithm
(:func:`dsim.master.planning.assembly.glue_cores`), for tests that compare parts with a whole."""
from __future__ import annotations

import math

import numpy as np

from dsim.master.planning.assembly import glue_cores
from dsim.master.scene import Joint, MasterSettings


def penalized_joint(name, a, b, row_coefficients, dofs=("x", "y")) -> Joint:
    """A fixed joint on the penalized measure that matches a linkage core's own
    constraint row a + 2 xi w v + w^2 u (``row_coefficients`` = (1, 2 xi w, w^2))."""
    _, cv, cd = row_coefficients
    omega = math.sqrt(cd)
    return Joint(name, a, b, tuple(dofs), "fixed", "penalized", xi=cv / (2.0 * omega),
                 omega=omega)


def march(cores: dict, joints, step_size: float, steps: int, **settings):
    """Glue ``cores`` with a consistent start and take ``steps`` macro steps; the joint
    forces per communication point (rows: t0, t0 + h, ...) and iterations per step."""
    settings = MasterSettings(**{"step": step_size, "start": "consistent",
                                 "max_iterations": 30, **settings})
    coupling = glue_cores(cores, list(joints), settings)
    forces, iterations = [coupling.forces.copy()], []
    for n in range(steps):
        report = coupling.step(n * step_size, step_size, n + 1)
        forces.append(coupling.forces.copy())
        iterations.append(report.iterations)
    return np.array(forces), iterations


def crank_slider_reactions(steps: int, h: float = 1e-3) -> tuple:
    """The monolithic crank slider's joint forces A.f_x, A.f_y, B.f_x, B.f_y (N) at
    each of ``steps`` steps of ``h`` (s), zeros at the start (what glued parts of it
    are compared with), and the monolithic core at the end."""
    from dsim.fmus.linkage.scenes import crank_slider

    whole = crank_slider("whole")
    whole.initialize(0.0)
    reference = [np.zeros(4)]
    for n in range(steps):
        whole.step(n * h, h)
        r = whole.reactions()
        reference.append(np.array([r["A.f_x"], r["A.f_y"], r["B.f_x"], r["B.f_y"]]))
    return np.array(reference), whole
