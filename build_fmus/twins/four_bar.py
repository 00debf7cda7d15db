"""The monolithic twins of seed section 5.3.2, the four_bar_singular_* scenes: the
whole parallelogram four bar in one :class:`~dsim.fmus.linkage.core.Linkage`.

One twin per scene (``TWINS``): ``fixed`` -- revolutes A and B as
position-level (index-3) rows, which is what fixed glue joints on the displacement
measure are, and the generalized-alpha rule of the scene's parts (spectral radius
``FOUR_BAR["spectral_radius"]``); ``penalized`` -- revolutes A and B as the parts'
own Baumgarte rows (the penalized measure), trapezoidal rule; ``flexible`` -- A and B
as Kelvin-Voigt bushings (k = 1e6 N/m, c = 2 0.707 1e3 N.s/m), the monolithic twin
of the flexible glue joints, started with the fixed mechanism's velocities (the
glued parts start from them too), trapezoidal rule.  H = 0.01 s.  Each twin solves
the discrete equations its glued scene solves, so glued minus twin is the gluing's
error.  Reactions / bushing forces on the coupler at A compare with a glued
run's ``A.f_x``, ``A.f_y`` (examples/four_bar.py compares).
"""
from __future__ import annotations

import copy
import time

import numpy as np

from dsim.build_fmus.linkage_scenes import FOUR_BAR
from dsim.fmus.linkage import Linkage
from dsim.fmus.linkage.kinematics import point_kinematics
from dsim.fmus.linkage.scenes import four_bar, four_bar_mechanism


#: scene (four_bar_singular_<scene>) -> its twin: the mechanism's joints, the joints whose
#: rows are position-level, the integrator's spectral radius (1: trapezoidal)
TWINS = {"fixed": dict(joints="fixed", index3_joints=("A", "B"),
                       spectral_radius=FOUR_BAR["spectral_radius"]),
         "penalized": dict(joints="fixed"),
         "flexible": dict(joints="flexible")}


def whole_model(joints: str, spectral_radius: float = 1.0, index3_joints=()) -> Linkage:
    """The initialized whole four bar with ``fixed`` or ``flexible`` joints, integrated
    with ``spectral_radius`` (1: the trapezoidal rule), the rows of ``index3_joints``
    (of the fixed joints A, B) at position level."""
    options = dict(spectral_radius=spectral_radius)
    fixed = four_bar("whole", index3_joints=tuple(index3_joints), **options)
    fixed.initialize(0.0)
    if joints == "fixed":
        return fixed
    mech = four_bar_mechanism("flexible", FOUR_BAR["k"], FOUR_BAR["c"])
    for body, q, v in zip(mech.bodies, fixed.q, fixed.v):
        body.x, body.y, body.theta = (float(x) for x in q)
        body.vx, body.vy, body.omega = (float(x) for x in v)
    whole = Linkage(copy.deepcopy(mech), **options)
    whole.initialize(0.0)
    return whole


def monolithic(scene: str, stop: float = FOUR_BAR["stop"], step: float = FOUR_BAR["step"],
               spectral_radius: float | None = None):
    """The twin of four_bar_singular_<scene> (``TWINS``; ``spectral_radius`` overrides
    its rule's): times, force on the coupler at A (N), crank and rocker angular
    velocities (rad/s), one row per step; ``seconds`` the integration's wall time."""
    twin = dict(TWINS[scene])
    if spectral_radius is not None:
        twin["spectral_radius"] = spectral_radius
    joints = twin.pop("joints")
    whole = whole_model(joints, **twin)
    count = round(stop / step)
    force, omega = np.zeros((count + 1, 2)), np.zeros((count + 1, 2))

    def force_at_a():
        out = whole.outputs()
        if joints == "fixed":
            return out["A.f_x"], out["A.f_y"]
        # bushing A: force on body_i (coupler) = -(k q + c q'), q = coupler.A - crank.A
        bodies = np.array([1, 0])
        points = np.array([[-1.0, 0.0], [0.5, 0.0]])
        pos, vel, _ = point_kinematics(whole.q, whole.v, whole.a, bodies, points)
        return tuple(-(FOUR_BAR["k"] * (pos[0] - pos[1]) + FOUR_BAR["c"] * (vel[0] - vel[1])))

    force[0] = force_at_a()
    omega[0] = whole.v[0, 2], whole.v[2, 2]
    start = time.perf_counter()
    for n in range(count):
        whole.step(n * step, step)
        force[n + 1] = force_at_a()
        omega[n + 1] = whole.v[0, 2], whole.v[2, 2]
    return {"times": np.arange(count + 1) * step, "force": force, "omega": omega,
            "seconds": time.perf_counter() - start}
