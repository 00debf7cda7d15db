"""Planar Euler-Bernoulli beam matrices in the body frame (pure functions).

The beam lies on the body x axis from -L/2 to L/2 (origin at the centre of
gravity of the uniform beam).  Each node has three elastic coordinates
(u, v, phi): axial and transverse displacement (m) and section rotation (rad).
Within an element of length l_e the axial displacement is linear and the
transverse one is a Hermite cubic (seed eqs. 3.39-3.40, 4.27-4.30):

    N(s) = [[1 - s, 0, 0, s, 0, 0],
            [0, 1 - 3s^2 + 2s^3, l_e (s - 2s^2 + s^3), 0, 3s^2 - 2s^3, l_e (s^3 - s^2)]]

with s = xi / l_e.  Consistent matrices are integrated by 4-point Gauss
quadrature (exact for these polynomial degrees):

    M = int rho A N^T N,   K = int EA N_a'^T N_a' + EI N_b''^T N_b'',
    G = int rho A N^T J N  (J: rotation by +90 degrees; G is skew, gyroscopic)

and the body-frame mode vectors give the inertia integrals of the floating frame
exactly: translation t_x, t_y; rotation r (N r = J u0); position p (N p = u0).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(4)
_J = np.array([[0.0, -1.0], [1.0, 0.0]])


def shape(s: float, le: float) -> np.ndarray:
    """N(s), 2 x 6, at s = xi / l_e in [0, 1]."""
    return np.array([
        [1 - s, 0, 0, s, 0, 0],
        [0, 1 - 3 * s ** 2 + 2 * s ** 3, le * (s - 2 * s ** 2 + s ** 3),
         0, 3 * s ** 2 - 2 * s ** 3, le * (s ** 3 - s ** 2)]])


def _derivatives(s: float, le: float):
    """dN_a/dx (6,) and d2N_b/dx2 (6,) at s."""
    da = np.array([-1, 0, 0, 1, 0, 0]) / le
    db = np.array([0, -6 + 12 * s, le * (-4 + 6 * s), 0, 6 - 12 * s, le * (6 * s - 2)]) / le ** 2
    return da, db


def element_matrices(le: float, rho_a: float, ea: float, ei: float):
    """Element mass, stiffness and gyroscopic matrices (6 x 6) of length le (m),
    mass per length rho_a (kg/m), axial and bending stiffness ea (N), ei (N.m^2)."""
    M, K, G = np.zeros((6, 6)), np.zeros((6, 6)), np.zeros((6, 6))
    for x, w in zip(_GAUSS_X, _GAUSS_W):
        s, wt = 0.5 * (x + 1.0), 0.5 * w * le
        N = shape(s, le)
        M += wt * rho_a * N.T @ N
        G += wt * rho_a * N.T @ _J @ N
        da, db = _derivatives(s, le)
        K += wt * (ea * np.outer(da, da) + ei * np.outer(db, db))
    return M, K, G


@dataclass(frozen=True)
class BeamModel:
    """Assembled free-free beam: matrices (n x n, n = 3 (elements + 1)) and the
    body-frame vectors the floating frame needs (see module docstring)."""

    length: float
    elements: int
    x0: np.ndarray        # node positions on the body x axis (m)
    mass: np.ndarray
    stiffness: np.ndarray
    gyroscopic: np.ndarray
    modes: np.ndarray     # n x 4: t_x, t_y, r, p
    total_mass: float
    inertia: float        # int rho A x0^2 (kg.m^2) about the CG


def assemble(length: float, elements: int, rho: float, area: float, young: float,
             second_moment: float) -> BeamModel:
    """Assemble a uniform beam of ``elements`` equal elements (SI units)."""
    n = 3 * (elements + 1)
    le = length / elements
    Me, Ke, Ge = element_matrices(le, rho * area, young * area, young * second_moment)
    M, K, G = np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n))
    for e in range(elements):
        idx = slice(3 * e, 3 * e + 6)
        M[idx, idx] += Me
        K[idx, idx] += Ke
        G[idx, idx] += Ge
    x0 = np.linspace(-0.5 * length, 0.5 * length, elements + 1)
    modes = np.zeros((n, 4))
    modes[0::3, 0] = 1.0          # t_x: u = 1
    modes[1::3, 1] = 1.0          # t_y: v = 1
    modes[1::3, 2] = x0           # r: v = x0, phi = 1 (N r = J u0 = (0, x0))
    modes[2::3, 2] = 1.0
    modes[0::3, 3] = x0           # p: u = x0 (N p = u0 = (x0, 0))
    total_mass = float(modes[:, 0] @ M @ modes[:, 0])
    inertia = float(modes[:, 3] @ M @ modes[:, 3])
    return BeamModel(length, elements, x0, M, K, G, modes, total_mass, inertia)
