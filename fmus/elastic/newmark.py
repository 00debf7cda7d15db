"""Newmark average acceleration (trapezoidal rule) for M a + C v + K u = f(t).

A pure kernel on an already constrained system (free or generalized coordinates):
the effective stiffness ``K + 2/h C + 4/h^2 M`` is factored once per step size with
scipy.sparse.linalg.splu and reused every step. Units follow the matrices (SI).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse import _sparsetools
from scipy.sparse.linalg import splu


def _product(matrix, x: np.ndarray) -> np.ndarray:
    """``matrix @ x`` for a CSC matrix and one float vector, by scipy's own kernel
    (csc_matvec, into zeros: what ``@`` runs, so the same bits) without the several
    microseconds of dispatch that ``@`` spends first, twice in every step."""
    if (matrix.format != "csc" or x.dtype != np.float64 or matrix.dtype != np.float64
            or x.ndim != 1):
        return matrix @ x
    rows, columns = matrix.shape
    result = np.zeros(rows)
    _sparsetools.csc_matvec(rows, columns, matrix.indptr, matrix.indices, matrix.data, x,
                            result)
    return result


class NewmarkAverageAcceleration:
    """beta = 1/4, gamma = 1/2: unconditionally stable, second order, no numerical damping.

    ``stiffness``, ``mass`` and ``damping`` (or None) are square matrices, sparse or dense.
    """

    def __init__(self, stiffness, mass, damping=None):
        self.stiffness = sp.csc_matrix(stiffness)
        self.mass = sp.csc_matrix(mass)
        self.damping = None if damping is None else sp.csc_matrix(damping)
        self.step_size: float | None = None
        self._effective = None
        self._mass_lu = None

    #: Step sizes this close (relative) to the factored one reuse its factor and are
    #: replaced by it: a master's communication steps t_{n+1} - t_n differ in the last bits.
    SAME_STEP = 1e-9

    def same_step(self, step_size: float, reference: float | None) -> bool:
        """Whether ``step_size`` is ``reference`` up to :data:`SAME_STEP` (s)."""
        return reference is not None and abs(step_size - reference) <= (
            self.SAME_STEP * reference)

    def factor(self, step_size: float) -> None:
        """Factor K + 2/h C + 4/h^2 M, unless already factored for this ``step_size``."""
        if self.same_step(step_size, self.step_size):
            return
        if not step_size > 0:
            raise ValueError(f"step size must be positive, got {step_size}")
        effective = self.stiffness + (4.0 / step_size ** 2) * self.mass
        if self.damping is not None:
            effective = effective + (2.0 / step_size) * self.damping
        # the pattern is symmetric: minimum degree on A^T + A keeps the fill lowest
        self._effective = splu(sp.csc_matrix(effective), permc_spec="MMD_AT_PLUS_A")
        self.step_size = step_size

    def step(self, u: np.ndarray, v: np.ndarray, a: np.ndarray, force_next: np.ndarray,
             step_size: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Displacement, velocity, acceleration at t + h from those at t and f(t + h)."""
        self.factor(step_size)
        h = self.step_size  # the factored step (equal to step_size up to SAME_STEP)
        # in place where it is safe: these arrays are a step's temporaries
        predictor = (4.0 / h ** 2) * u
        predictor += (4.0 / h) * v
        predictor += a
        rhs = _product(self.mass, predictor)
        rhs += force_next
        if self.damping is not None:
            rhs += _product(self.damping, (2.0 / h) * u + v)
        u_next = self._effective.solve(rhs)
        du = u_next - u
        v_next = (2.0 / h) * du
        v_next -= v
        a_next = (4.0 / h ** 2) * du
        a_next -= (4.0 / h) * v
        a_next -= a
        return u_next, v_next, a_next

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """K_eff^-1 rhs with the factor of the last :meth:`factor` (rhs: a vector, or
        one column per vector)."""
        return self._effective.solve(np.asarray(rhs, dtype=float))

    def acceleration(self, u: np.ndarray, v: np.ndarray, force: np.ndarray) -> np.ndarray:
        """Acceleration consistent with equilibrium: M a = f - K u - C v."""
        if self._mass_lu is None:  # factored on first use only (initialization)
            self._mass_lu = splu(self.mass)
        rhs = force - self.stiffness @ u
        if self.damping is not None:
            rhs = rhs - self.damping @ v
        return self._mass_lu.solve(rhs)

    def static(self, force: np.ndarray) -> np.ndarray:
        """Static displacement K u = f (needs a stiffness without rigid-body modes)."""
        return splu(self.stiffness).solve(force)
