"""A minimal T-T gluing loop over in-process cores, to check parts against a whole.

This is a test instrument, not the master (``master/`` owns the real algorithm):
no predictor beyond constant extrapolation, no flexible joints, no observers.  It
follows DESIGN.md: joint j ties port a to port b, b receives +F_j and a receives
-F_j; the residual is the blend

    R_j = (c_a (a_b - a_a) + c_v (v_b - v_a) + c_d (u_b - u_a)) / (c_a + c_v h/2 + c_d h^2/4)

(c = (0, 0, 1): displacement; (1, 2 xi w, w^2): the seed's penalized measure, eq.
5.28).  Newton on F with dR/dF from one-column force perturbations, each
re-stepping every subsystem from its saved state (seed eqs. 4.45-4.46); the matrix
is kept across steps and refreshed when an iteration count exceeds ``refresh_after``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fmus.interface import InterfaceCore


@dataclass(frozen=True)
class Joint:
    """Port ``a`` = (component, port) glued to port ``b`` in the given global dofs."""

    name: str
    a: tuple[str, str]
    b: tuple[str, str]
    dofs: tuple[str, ...] = ("x", "y")


@dataclass
class GlueResult:
    """Joint forces per step (rows: t0, t0 + h, ...; columns: joint dofs in order),
    iterations per step and the number of Jacobian evaluations."""

    times: np.ndarray
    forces: np.ndarray
    iterations: list[int] = field(default_factory=list)
    jacobians: int = 0


class HandGlue:
    """Glue ``components`` (name -> :class:`InterfaceCore`) at ``joints``."""

    def __init__(self, components: dict[str, InterfaceCore], joints: list[Joint],
                 measure: tuple[float, float, float] = (0.0, 0.0, 1.0),
                 tolerance: float = 1e-10, max_iterations: int = 30,
                 refresh_after: int = 4, perturbation: float = 1.0):
        self.components = components
        self.joints = joints
        self.measure = measure
        self.tolerance = tolerance
        self.max_iterations = max_iterations
        self.refresh_after = refresh_after
        self.perturbation = perturbation
        # Which interface entry of which component each joint dof touches, with sign.
        self.links = []  # (unknown index, component, entry a, entry b)
        k = 0
        for j in joints:
            for d in j.dofs:
                ia = components[j.a[0]].interface.index((j.a[1], d))
                ib = components[j.b[0]].interface.index((j.b[1], d))
                self.links.append((k, j.a[0], ia, j.b[0], ib))
                k += 1
        self.n = k
        self.jacobian = None
        self.jacobian_count = 0

    def _apply(self, F):
        loads = {name: np.zeros(len(c.interface)) for name, c in self.components.items()}
        for k, ca, ia, cb, ib in self.links:
            loads[ca][ia] -= F[k]
            loads[cb][ib] += F[k]
        for name, c in self.components.items():
            c.set_interface_forces(loads[name])

    def _residual(self, kin, h):
        ca, cv, cd = self.measure
        scale = ca + cv * 0.5 * h + cd * 0.25 * h * h
        R = np.zeros(self.n)
        for k, comp_a, ia, comp_b, ib in self.links:
            ua, va, aa = (x[ia] for x in kin[comp_a])
            ub, vb, ab = (x[ib] for x in kin[comp_b])
            R[k] = (ca * (ab - aa) + cv * (vb - va) + cd * (ub - ua)) / scale
        return R

    def _evaluate(self, F, states, t, h):
        # Restore first: a saved state includes the inputs held when it was saved.
        for name, c in self.components.items():
            c.set_state(states[name])
        self._apply(F)
        kin = {}
        for name, c in self.components.items():
            c.step(t, h)
            kin[name] = c.interface_kinematics()
        return self._residual(kin, h)

    def _jacobian(self, F, R0, states, t, h):
        J = np.zeros((self.n, self.n))
        for k in range(self.n):
            dF = np.zeros(self.n)
            dF[k] = self.perturbation
            J[:, k] = (self._evaluate(F + dF, states, t, h) - R0) / self.perturbation
        self.jacobian_count += 1
        return J

    def initialize(self, start_time: float, F0: np.ndarray | None = None) -> np.ndarray:
        """Initialize every component and solve the forces that make the interface
        accelerations compatible at ``start_time``; returns them."""
        F = np.zeros(self.n) if F0 is None else np.array(F0, dtype=float)

        def residual(F):
            self._apply(F)
            kin = {}
            for name, c in self.components.items():
                c.initialize(start_time)
                kin[name] = c.interface_kinematics()
            R = np.zeros(self.n)
            for k, comp_a, ia, comp_b, ib in self.links:
                R[k] = kin[comp_b][2][ib] - kin[comp_a][2][ia]
            return R

        R = residual(F)
        for _ in range(self.max_iterations):
            if np.max(np.abs(R), initial=0.0) <= self.tolerance:
                break
            J = np.zeros((self.n, self.n))
            for k in range(self.n):
                dF = np.zeros(self.n)
                dF[k] = self.perturbation
                J[:, k] = (residual(F + dF) - R) / self.perturbation
            F = F - np.linalg.solve(J, R)
            R = residual(F)
        else:
            raise ArithmeticError("hand glue: no compatible initial forces")
        return F

    def run(self, start_time: float, step_size: float, steps: int) -> GlueResult:
        """Initialize, then glue ``steps`` macro steps of ``step_size`` (s)."""
        F = self.initialize(start_time)
        h = step_size
        forces, iterations = [F.copy()], []
        for n in range(steps):
            t = start_time + n * h
            states = {name: c.get_state() for name, c in self.components.items()}
            R = self._evaluate(F, states, t, h)
            for it in range(1, self.max_iterations + 1):
                if self.jacobian is None or it > self.refresh_after:
                    self.jacobian = self._jacobian(F, R, states, t, h)
                    R = self._evaluate(F, states, t, h)
                F = F - np.linalg.solve(self.jacobian, R)
                R = self._evaluate(F, states, t, h)
                if np.max(np.abs(R)) <= self.tolerance:
                    break
            else:
                raise ArithmeticError(f"hand glue did not converge at t = {t + h:.6g} s")
            forces.append(F.copy())
            iterations.append(it)
        times = start_time + h * np.arange(steps + 1)
        return GlueResult(times, np.array(forces), iterations, self.jacobian_count)
