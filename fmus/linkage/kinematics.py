"""Pure kernels for points of planar rigid bodies (no state, no classes).

A body's coordinates are q_b = (x, y, theta): CG position (m) and angle (rad).
A point with local coordinates s (m) sits at p = R + A(theta) s.  With
w = A(theta) s (the world offset from the CG) and J the 90-degree rotation,

    p   = R + w
    dp  = dR + omega J w
    ddp = ddR + alpha J w - omega^2 w

and dp/dtheta = J w, d(J w)/dtheta = -w.  Every kernel is vectorised over k
points: ``theta`` has shape (k,), ``s`` shape (k, 2); results have shape (k, 2).
"""
from __future__ import annotations

import numpy as np


def world_offsets(theta: np.ndarray, s: np.ndarray) -> np.ndarray:
    """w = A(theta) s for k points: (k, 2) array in m."""
    c, sn = np.cos(theta), np.sin(theta)
    return np.stack((c * s[:, 0] - sn * s[:, 1], sn * s[:, 0] + c * s[:, 1]), axis=1)


def perp(w: np.ndarray) -> np.ndarray:
    """J w: each row rotated by +90 degrees."""
    return np.stack((-w[:, 1], w[:, 0]), axis=1)


def point_kinematics(q: np.ndarray, v: np.ndarray, a: np.ndarray,
                     body: np.ndarray, s: np.ndarray):
    """Global position (m), velocity (m/s), acceleration (m/s^2) of k body points.

    q, v, a: (nb, 3) coordinates, rates and accelerations of the bodies;
    body: (k,) body indices; s: (k, 2) local coordinates.
    """
    w = world_offsets(q[body, 2], s)
    jw = perp(w)
    om, al = v[body, 2:3], a[body, 2:3]
    pos = q[body, :2] + w
    vel = v[body, :2] + om * jw
    acc = a[body, :2] + al * jw - om * om * w
    return pos, vel, acc


def rotation(theta: float) -> np.ndarray:
    """The 2 x 2 rotation matrix A(theta)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])
