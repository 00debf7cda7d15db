"""Flexible planar link: Euler-Bernoulli beam in a floating frame, Partitioned Iteration.

Coordinates (seed chapter 3, planar): reference position R (m, the centre of
gravity) and angle theta (rad) of the body frame, and elastic nodal coordinates
q_f (:mod:`.beam`) relative to that frame.  A material point sits at
r = R + A(theta) (u0 + N q_f).

Reference motion with the CG-following reference condition (seed eqs. 3.36-3.38):

    m R''  = sum F_p + m g
    (I0 + p.M q_f) alpha + 2 omega p.M q_f' - omega^2 r.M q_f = sum u_p0 x A^T F_p

Deformation relative to the frame (eq. 3.36, second row):

    M q_f'' + K q_f = F_f - M T A^T R'' - alpha (M r + G q_f) - 2 omega G q_f'
                      + omega^2 (M p + M q_f)          with F_f = N_p^T A^T F_p

(T = [t_x t_y], r, p the mode vectors of :mod:`.beam`; the gravity part of R''
cancels the distributed weight).  Before solving, the right-hand side is made
M-orthogonal to the rigid modes (t_x, t_y, r): these are the seed's approximated
multipliers (eqs. 3.33-3.34), which keep the elastic field free of rigid motion
(mean-axis conditions, eqs. 3.23-3.24, in linearised form) to round-off.

Both parts are integrated by the trapezoidal rule (Newmark average acceleration)
at t + h with the port forces held, and iterated (PIM, Fig. 3.4): the reference
step uses the latest elastic coordinates (its quadratic velocity terms), the
elastic step the latest reference motion, until both stop changing.  The elastic
step factors M + h^2/4 K (+ h/2 C) once: it is a linear FE solve.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ..interface import InterfaceCore
from ..newton import NewtonCount, at_roundoff, failure_message

from .beam import assemble


def _cross(a: np.ndarray, b: np.ndarray) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def _rot(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


_J = np.array([[0.0, -1.0], [1.0, 0.0]])


class PIMConvergenceError(ArithmeticError):
    """The partitioned iteration did not converge within a step."""


class FlexibleLink(InterfaceCore):
    """A uniform flexible link with ports at both ends (global x y forces in).

    Parameters (SI): ``length``, ``density`` (kg/m^3), ``area`` (m^2), ``young``
    (Pa), ``second_moment`` (m^4), ``elements``; initial CG position ``x``, ``y``,
    angle ``theta``, rates ``vx``, ``vy``, ``omega`` (rigid: no initial deformation);
    ``ports`` names the ends at -L/2 and +L/2; ``gravity`` (m/s^2);
    ``stiffness_damping`` beta (s) of Rayleigh damping C = beta K.
    """

    def __init__(self, length: float = 6.0, density: float = 7850.0, area: float = 0.01,
                 young: float = 210e9, second_moment: float = 0.1 ** 4 / 12.0,
                 elements: int = 6, x: float = 0.0, y: float = 0.0, theta: float = 0.0,
                 vx: float = 0.0, vy: float = 0.0, omega: float = 0.0,
                 ports: tuple[str, str] = ("A", "B"), gravity=(0.0, 0.0),
                 stiffness_damping: float = 0.0, tolerance: float = 1e-10,
                 max_iterations: int = 50):
        if elements < 1 or length <= 0:
            raise ValueError("a flexible link needs a positive length and >= 1 element")
        self.beam = b = assemble(length, elements, density, area, young, second_moment)
        self.mass_total = b.total_mass
        self.stiffness_damping = float(stiffness_damping)
        self.gravity = np.asarray(gravity, dtype=float)
        self.tolerance = float(tolerance)
        self.max_iterations = int(max_iterations)
        M = b.mass
        self._Mt = M @ b.modes[:, :2]          # M [t_x t_y]
        self._Mr = M @ b.modes[:, 2]           # M r
        self._Mp = M @ b.modes[:, 3]           # M p
        # Rigid-mode projector P = I - M R (R^T M R)^-1 R^T, R = [t_x t_y r]: P f has
        # no work on rigid motions (loads), P^T x has no rigid content (R^T M P^T x = 0).
        rigid = b.modes[:, :3]
        self._projector = np.eye(M.shape[0]) - (M @ rigid) @ np.linalg.solve(
            rigid.T @ M @ rigid, rigid.T)
        n_nodes = elements + 1
        self._port_dofs = [(0, 1), (3 * (n_nodes - 1), 3 * (n_nodes - 1) + 1)]
        self._port_u0 = [np.array([b.x0[0], 0.0]), np.array([b.x0[-1], 0.0])]
        self.port_names = tuple(ports)
        self.interface = tuple((p, d) for p in self.port_names for d in ("x", "y"))
        self._factor_h = None
        self._factor = None
        # State.
        n = M.shape[0]
        self.time = 0.0
        self.R, self.Rd, self.Rdd = np.array([x, y], float), np.array([vx, vy], float), np.zeros(2)
        self.theta, self.omega, self.alpha = float(theta), float(omega), 0.0
        self.qf, self.qfd, self.qfdd = np.zeros(n), np.zeros(n), np.zeros(n)
        self.port_forces = np.zeros((2, 2))
        self.iterations = 0
        #: converged steps, and those that ended at the round-off floor (dsim.fmus.newton)
        self.newton = NewtonCount()

    # --- pieces ---------------------------------------------------------------
    def natural_frequencies(self, count: int = 6) -> np.ndarray:
        """The first ``count`` free-free elastic natural frequencies (Hz), rigid modes
        (three zero eigenvalues) removed."""
        w2 = sla.eigh(self.beam.stiffness, self.beam.mass, eigvals_only=True)
        return np.sqrt(np.abs(w2[3:3 + count])) / (2.0 * np.pi)

    def _torque(self, theta: float):
        """Moment of the port forces about the CG (N.m) with undeformed arms (eq. 3.38)
        and its derivative with respect to theta."""
        A = _rot(theta)
        T = sum(_cross(A @ u0, f) for u0, f in zip(self._port_u0, self.port_forces))
        dT = sum(_cross(_J @ A @ u0, f) for u0, f in zip(self._port_u0, self.port_forces))
        return T, dT

    def _angular_acceleration(self, theta, omega, qf, qfd):
        """alpha from the reference rotation equation at given theta, omega, q_f, q_f'."""
        inertia = self.beam.inertia + self._Mp @ qf
        T, _ = self._torque(theta)
        return (T - 2.0 * omega * (self._Mp @ qfd) + omega ** 2 * (self._Mr @ qf)) / inertia

    def _elastic_load(self, theta, omega, alpha, Rdd, qf, qfd):
        """Projected right-hand side of the elastic equation (N, body-frame nodal)."""
        b, A = self.beam, _rot(theta)
        rhs = np.zeros(b.mass.shape[0])
        for (iu, iv), f in zip(self._port_dofs, self.port_forces):
            rhs[[iu, iv]] += A.T @ f
        rhs -= self._Mt @ (A.T @ (Rdd - self.gravity))
        rhs -= alpha * (self._Mr + b.gyroscopic @ qf)
        rhs -= 2.0 * omega * (b.gyroscopic @ qfd)
        rhs += omega ** 2 * (self._Mp + b.mass @ qf)
        return self._projector @ rhs

    def _factorization(self, h):
        if self._factor_h != h:
            b = self.beam
            # M + h/2 C + h^2/4 K with C = beta K: SPD although K is singular.
            self._factor = sla.cho_factor(
                b.mass + (0.25 * h * h + 0.5 * h * self.stiffness_damping) * b.stiffness)
            self._factor_h = h
        return self._factor

    # --- InterfaceCore ----------------------------------------------------------
    def initialize(self, start_time: float) -> None:
        """Consistent accelerations at ``start_time`` for the state and port forces."""
        self.time = float(start_time)
        self.Rdd = self.port_forces.sum(axis=0) / self.mass_total + self.gravity
        self.alpha = self._angular_acceleration(self.theta, self.omega, self.qf, self.qfd)
        b = self.beam
        rhs = self._elastic_load(self.theta, self.omega, self.alpha, self.Rdd, self.qf, self.qfd)
        rhs -= b.stiffness @ (self.qf + self.stiffness_damping * self.qfd)
        self.qfdd = self._projector.T @ np.linalg.solve(b.mass, rhs)

    def set_interface_forces(self, forces: np.ndarray) -> None:
        """Forces (N, global) at the ports: (A.x, A.y, B.x, B.y)."""
        self.port_forces = np.asarray(forces, dtype=float).reshape(2, 2).copy()

    def step(self, time: float, step_size: float) -> None:
        """PIM step from ``time`` to ``time + step_size`` (s), port forces held."""
        h = float(step_size)
        t1 = float(time) + h
        b, beta_k = self.beam, self.stiffness_damping
        # Translation of the CG is exact under held forces.
        Rdd1 = self.port_forces.sum(axis=0) / self.mass_total + self.gravity
        Rd1 = self.Rd + 0.5 * h * (self.Rdd + Rdd1)
        R1 = self.R + h * self.Rd + 0.25 * h * h * (self.Rdd + Rdd1)
        th_pred = self.theta + h * self.omega + 0.25 * h * h * self.alpha
        om_pred = self.omega + 0.5 * h * self.alpha
        qf_pred = self.qf + h * self.qfd + 0.25 * h * h * self.qfdd
        qfd_pred = self.qfd + 0.5 * h * self.qfdd
        factor = self._factorization(h)
        alpha1, qfdd1 = self.alpha, self.qfdd.copy()
        qf1, qfd1 = qf_pred + 0.25 * h * h * qfdd1, qfd_pred + 0.5 * h * qfdd1
        for iteration in range(1, self.max_iterations + 1):
            # Reference rotation: scalar Newton for alpha1 with q_f frozen.
            inertia = b.inertia + self._Mp @ qf1
            gyro, centri = self._Mp @ qfd1, self._Mr @ qf1
            alpha_prev = alpha1
            for _ in range(20):
                th1 = th_pred + 0.25 * h * h * alpha1
                om1 = om_pred + 0.5 * h * alpha1
                T, dT = self._torque(th1)
                g = inertia * alpha1 + 2.0 * om1 * gyro - om1 ** 2 * centri - T
                dg = inertia + h * gyro - h * om1 * centri - 0.25 * h * h * dT
                step = g / dg
                alpha1 -= step
                if abs(step) <= 1e-14 * (1.0 + abs(alpha1)):
                    break
            th1 = th_pred + 0.25 * h * h * alpha1
            om1 = om_pred + 0.5 * h * alpha1
            # Elastic step: linear FE solve with the reference motion frozen.
            rhs = self._elastic_load(th1, om1, alpha1, Rdd1, qf1, qfd1)
            rhs -= b.stiffness @ (qf_pred + beta_k * qfd_pred)
            qfdd_new = self._projector.T @ sla.cho_solve(factor, rhs)
            change = np.max(np.abs(qfdd_new - qfdd1))
            qfdd1 = qfdd_new
            qf1, qfd1 = qf_pred + 0.25 * h * h * qfdd1, qfd_pred + 0.5 * h * qfdd1
            scale = 1.0 + np.max(np.abs(qfdd1))
            turn = abs(alpha1 - alpha_prev)
            if change <= self.tolerance * scale and turn <= self.tolerance * (1.0 + abs(alpha1)):
                self.newton.ended("increment")
                break
            if at_roundoff(change, scale) and at_roundoff(turn, 1.0 + abs(alpha1)):
                # both partitions move by round-off only: the iteration can do no better
                self.newton.ended("round-off")
                break
        else:
            raise PIMConvergenceError(failure_message(
                "flexible link PIM", t1, self.max_iterations, [change, turn]))
        self.iterations = iteration
        self.R, self.Rd, self.Rdd = R1, Rd1, Rdd1
        self.theta, self.omega, self.alpha = th1, om1, alpha1
        self.qf, self.qfd, self.qfdd = qf1, qfd1, qfdd1
        self.time = t1

    def port_kinematics(self):
        """Global position (m), velocity, acceleration of both ends: (2, 2) arrays."""
        A = _rot(self.theta)
        pos, vel, acc = np.zeros((2, 2)), np.zeros((2, 2)), np.zeros((2, 2))
        for k, ((iu, iv), u0) in enumerate(zip(self._port_dofs, self._port_u0)):
            d, dd, ddd = self.qf[[iu, iv]], self.qfd[[iu, iv]], self.qfdd[[iu, iv]]
            arm = A @ (u0 + d)
            pos[k] = self.R + arm
            vel[k] = self.Rd + self.omega * (_J @ arm) + A @ dd
            acc[k] = (self.Rdd + self.alpha * (_J @ arm) - self.omega ** 2 * arm
                      + 2.0 * self.omega * (_J @ (A @ dd)) + A @ ddd)
        return pos, vel, acc

    def interface_kinematics(self):
        pos, vel, acc = self.port_kinematics()
        return pos.reshape(-1), vel.reshape(-1), acc.reshape(-1)

    def get_state(self) -> dict:
        return {"time": self.time, "R": self.R.copy(), "Rd": self.Rd.copy(),
                "Rdd": self.Rdd.copy(), "theta": self.theta, "omega": self.omega,
                "alpha": self.alpha, "qf": self.qf.copy(), "qfd": self.qfd.copy(),
                "qfdd": self.qfdd.copy(), "port_forces": self.port_forces.copy(),
                "iterations": self.iterations}

    def set_state(self, state: dict) -> None:
        self.time = float(state["time"])
        for key in ("R", "Rd", "Rdd", "qf", "qfd", "qfdd", "port_forces"):
            setattr(self, key, np.array(state[key], dtype=float))
        self.theta, self.omega = float(state["theta"]), float(state["omega"])
        self.alpha = float(state["alpha"])
        self.iterations = int(state["iterations"])

    def outputs(self) -> dict[str, float]:
        """Reference pose and rates (``reference.x y theta vx vy omega alpha``),
        ``deflection`` (largest transverse nodal displacement, m), ``stretch``
        (change of length, m), ``mean_axis_violation`` (|R^T M q_f|, kg.m) and
        ``pim_iterations``."""
        b = self.beam
        v = self.qf[1::3]
        rigid = b.modes[:, :3].T @ b.mass @ self.qf
        return {"reference.x": float(self.R[0]), "reference.y": float(self.R[1]),
                "reference.theta": self.theta, "reference.vx": float(self.Rd[0]),
                "reference.vy": float(self.Rd[1]), "reference.omega": self.omega,
                "reference.alpha": self.alpha,
                "deflection": float(np.max(np.abs(v))),
                "stretch": float(self.qf[-3] - self.qf[0]),
                "mean_axis_violation": float(np.max(np.abs(rigid))),
                "pim_iterations": float(self.iterations)}
