"""Planar rigid multibody core: a glueable :class:`Linkage` of bodies, joints and drivers.

Equations (coordinates q = (x, y, theta) per body, SI units):

    M a + Phi_q(q)^T lambda = Q(q, v, t)         (M constant: mass, mass, inertia)
    c_a Phi'' + c_v Phi' + c_d Phi = 0           (constraints, stabilised)

integrated by the trapezoidal rule (Newmark average acceleration)

    q1 = q + h v + h^2/4 (a + a1),   v1 = v + h/2 (a + a1)

with Newton on (a1, lambda1) at t + h; or, with ``spectral_radius`` rho < 1, by the
generalized-alpha rule of which the trapezoidal rule is the rho = 1 member
(:mod:`dsim.fmus.generalized_alpha`: equilibrium and constraints still hold at t + h, a
pseudo-acceleration carries numerical damping of the modes above 1/h).  The default
constraint row is Baumgarte's (c_a, c_v, c_d) = (1, 2 xi w, w^2): the acceleration-level
constraint with position and velocity feedback.  ``formulation="index3"`` uses (0, 0, 1),
the position-level (index-3) form.  Why Baumgarte is the default (docs/linkage.md): the
trapezoidal rule on the index-3 form has an undamped period-2 mode (eigenvalue -1, twice)
that turns O(h^2) velocity defects into O(1) oscillation of accelerations and multipliers;
the stabilised form keeps positions, velocities and accelerations consistent.  The same
row is the seed's penalized gluing measure (eq. 5.28), so a mechanism cut into parts
and glued with that measure solves exactly the monolithic discrete equations.
``index3_joints`` names joints (revolutes, prismatics, drivers) whose rows are
position-level whatever the formulation: the whole-mechanism twin of parts glued by
fixed joints on the displacement measure, which are position-level rows.

Rows are divided by c_a + c_v g h + c_d b h^2 (their derivative with respect to a1, up
to Phi_q; g = dv1/da1 / h and b = dq1/da1 / h^2 are 1/2 and 1/4 under the trapezoidal
rule), which keeps Newton's matrix well scaled for any step size.
"""
from __future__ import annotations

import numpy as np

from ..generalized_alpha import TRAPEZOIDAL, GeneralizedAlpha
from ..interface import InterfaceCore
from ..newton import NewtonCount, at_roundoff, failure_message, roundoff_floor

from .constraints import ConstraintSet
from .elements import Mechanism
from .forces import ForceSet
from .kinematics import point_kinematics

_DOF_COLUMN = {"x": 0, "y": 1, "rz": 2}


class LinkageConvergenceError(ArithmeticError):
    """Newton's method did not converge within a step (the message names the time)."""


class Linkage(InterfaceCore):
    """A planar mechanism of rigid bodies (see module docstring).

    Parameters
    ----------
    mechanism:
        The parts list (:class:`~dsim.fmus.linkage.elements.Mechanism`).
    formulation:
        ``"baumgarte"`` (default) or ``"index3"``.
    baumgarte_frequency, baumgarte_damping:
        w (rad/s) and xi of the stabilised constraint row.
    newton_tolerance:
        Relative size of the last Newton increment that ends the iteration.
    spectral_radius:
        rho_inf of the generalized-alpha rule, 0..1; 1 (default) is the trapezoidal rule.
    index3_joints:
        Names of joints whose rows are position-level (index-3) whatever the formulation.
    """

    def __init__(self, mechanism: Mechanism, formulation: str = "baumgarte",
                 baumgarte_frequency: float = 1000.0, baumgarte_damping: float = 1.0,
                 newton_tolerance: float = 1e-11, max_newton: int = 30,
                 spectral_radius: float = TRAPEZOIDAL, index3_joints=()):
        mechanism.validate()
        self.mechanism = mechanism
        self.body_names = [b.name for b in mechanism.bodies]
        index = {name: i for i, name in enumerate(self.body_names)}
        self.nb = len(self.body_names)
        self.n = 3 * self.nb
        self.constraints = ConstraintSet(mechanism, index)
        self.forces = ForceSet(mechanism, index)
        self.mass = np.zeros(self.n)
        self.mass[0::3] = [b.mass for b in mechanism.bodies]
        self.mass[1::3] = self.mass[0::3]
        self.mass[2::3] = [b.inertia for b in mechanism.bodies]
        if formulation == "baumgarte":
            w, xi = float(baumgarte_frequency), float(baumgarte_damping)
            self.row_coefficients = (1.0, 2.0 * xi * w, w * w)
        elif formulation == "index3":
            self.row_coefficients = (0.0, 0.0, 1.0)
        else:
            raise ValueError(f"formulation must be 'baumgarte' or 'index3', not {formulation!r}")
        self.formulation = formulation
        self.rule = GeneralizedAlpha(spectral_radius)
        # per constraint row (c_a, c_v, c_d): the formulation's, or (0, 0, 1) on the rows
        # of the joints named index-3
        m = self.constraints.m
        self._row_ca, self._row_cv, self._row_cd = (np.full(m, c) for c in self.row_coefficients)
        named = {name for _, name, _ in self.constraints.groups}
        unknown = sorted(set(index3_joints) - named)
        if unknown:
            raise ValueError(f"index3_joints: no joint named {', '.join(unknown)}")
        self.index3_joints = tuple(index3_joints)
        bounds = [r0 for _, _, r0 in self.constraints.groups] + [m]
        for (_, name, r0), r1 in zip(self.constraints.groups, bounds[1:]):
            if name in self.index3_joints:
                self._row_ca[r0:r1], self._row_cv[r0:r1], self._row_cd[r0:r1] = 0.0, 0.0, 1.0
        self.newton_tolerance = float(newton_tolerance)
        self.max_newton = int(max_newton)
        ports = mechanism.ports
        self.port_names = [p.name for p in ports]
        self.interface = tuple((p.name, d) for p in ports for d in p.dofs)
        self._iface_port = np.array([i for i, p in enumerate(ports) for _ in p.dofs], dtype=int)
        self._iface_col = np.array([_DOF_COLUMN[d] for p in ports for d in p.dofs], dtype=int)
        self._port_body = np.array([index[p.body] for p in ports], dtype=int)
        self._port_s = np.array([p.point for p in ports], dtype=float).reshape(-1, 2)
        # State.
        self.time = 0.0
        self.q = np.array([[b.x, b.y, b.theta] for b in mechanism.bodies], dtype=float)
        self.v = np.array([[b.vx, b.vy, b.omega] for b in mechanism.bodies], dtype=float)
        self.a = np.zeros((self.nb, 3))
        #: the generalized-alpha pseudo-acceleration (= a under the trapezoidal rule)
        self.pseudo = np.zeros((self.nb, 3))
        self.lam = np.zeros(self.constraints.m)
        self.port_forces = np.zeros((len(ports), 3))
        self.newton_iterations = 0
        #: converged steps, and those that ended at the residual's round-off floor
        self.newton = NewtonCount()

    # --- equations ------------------------------------------------------------
    def _load(self, q, v, t, tangents=True):
        """Q (n,), dQ/dq, dQ/dv (n, n) at (q, v, t) with the held port forces."""
        Q = self.forces.gravity_force.copy()
        Qp, dtheta = self.forces.port_load(q, self.port_forces)
        Q += Qp
        Qe, Kq, Kv, _ = self.forces.elements_load(q, v, tangents)
        Q += Qe
        if tangents:
            Kq[np.diag_indices(self.n)] += dtheta
        return Q, Kq, Kv

    def _residual(self, q1, v1, a1, lam, t1, h):
        """Newton residual and matrix for unknowns (a1, lambda) at t1 = t + h, and the
        size of the terms each residual row sums (its round-off scale)."""
        ca, cv, cd = self._row_ca, self._row_cv, self._row_cd
        beta_h2 = self.rule.position_weight * h * h
        gamma_h = self.rule.velocity_weight * h
        scale = ca + cv * gamma_h + cd * beta_h2
        c = self.constraints.evaluate(q1, v1, a1, lam, t1)
        Q, Qq, Qv = self._load(q1, v1, t1)
        af = a1.reshape(-1)
        r_dyn = self.mass * af + c["phi_q"].T @ lam - Q
        r_con = (ca * c["phi_dd"] + cv * c["phi_d"] + cd * c["phi"]) / scale
        m = self.constraints.m
        jac = np.zeros((self.n + m, self.n + m))
        jac[: self.n, : self.n] = (np.diag(self.mass) + beta_h2 * (c["k_lambda"] - Qq)
                                   - gamma_h * Qv)
        jac[: self.n, self.n:] = c["phi_q"].T
        ca, cv, cd, scale = ca[:, None], cv[:, None], cd[:, None], scale[:, None]
        jac[self.n:, : self.n] = (ca * (c["phi_q"] + beta_h2 * c["phi_dd_q"]
                                        + gamma_h * c["phi_dd_v"])
                                  + cv * (gamma_h * c["phi_q"] + beta_h2 * c["phi_d_q"])
                                  + cd * beta_h2 * c["phi_q"]) / scale
        terms = np.concatenate((np.abs(self.mass * af) + np.abs(c["phi_q"].T) @ np.abs(lam)
                                + np.abs(Q), self._constraint_scale(q1, v1, a1, h)[:m]))
        return np.concatenate((r_dyn, r_con)), jac, terms

    def _constraint_scale(self, q1, v1, a1, h) -> np.ndarray:
        """Size of the terms of each scaled constraint row (m/s^2): positions, velocities
        and accelerations weighted as the row weighs them."""
        ca, cv, cd = self._row_ca, self._row_cv, self._row_cd
        if not ca.size:  # no constraint: the formulation's row sets the increments' floor
            ca, cv, cd = (np.array([c]) for c in self.row_coefficients)
        scale = ca + cv * self.rule.velocity_weight * h + cd * self.rule.position_weight * h * h
        return (cd * (1.0 + np.max(np.abs(q1))) + cv * (1.0 + np.max(np.abs(v1)))
                + ca * (1.0 + np.max(np.abs(a1)))) / scale

    def _tolerances(self, q1, v1, a1, lam):
        """Newton stopping sizes for the increments of a1 and lambda: the relative
        tolerance plus the round-off floor of the constraint rows (their position and
        velocity terms carry factors w^2 and 2 xi w, which amplify the last bit of
        q and v; without the floor Newton would stall just above the tolerance)."""
        floor = float(np.max(roundoff_floor(self._constraint_scale(q1, v1, a1, self._h)),
                             initial=0.0))
        tol_a = self.newton_tolerance * (1.0 + np.max(np.abs(a1))) + floor
        tol_l = (self.newton_tolerance * (1.0 + (np.max(np.abs(lam)) if lam.size else 0.0))
                 + floor * np.max(self.mass))
        return tol_a, tol_l

    # --- InterfaceCore ----------------------------------------------------------
    def initialize(self, start_time: float) -> None:
        """Set the time; project positions and velocities onto the constraints if
        they violate them; solve the consistent accelerations and multipliers."""
        t = self.time = float(start_time)
        m = self.constraints.m
        if m:
            for _ in range(50):
                phi, jac = self.constraints.position(self.q, t)
                if np.max(np.abs(phi)) < 1e-13:
                    break
                dq = np.linalg.lstsq(jac, phi, rcond=None)[0]
                self.q -= dq.reshape(self.nb, 3)
            else:
                raise LinkageConvergenceError(f"cannot assemble the mechanism at t = {t}")
            c = self.constraints.evaluate(self.q, self.v, self.a, self.lam, t)
            minv = 1.0 / self.mass
            g = c["phi_q"] * minv
            mu = np.linalg.lstsq(g @ c["phi_q"].T, c["phi_d"], rcond=None)[0]
            self.v -= (minv * (c["phi_q"].T @ mu)).reshape(self.nb, 3)
        zero = np.zeros((self.nb, 3))
        c = self.constraints.evaluate(self.q, self.v, zero, np.zeros(m), t)
        Q, _, _ = self._load(self.q, self.v, t, tangents=False)
        kkt = np.zeros((self.n + m, self.n + m))
        kkt[: self.n, : self.n] = np.diag(self.mass)
        kkt[: self.n, self.n:] = c["phi_q"].T
        kkt[self.n:, : self.n] = c["phi_q"]
        rhs = np.concatenate((Q, -c["phi_dd"]))
        sol = np.linalg.lstsq(kkt, rhs, rcond=None)[0]
        self.a = sol[: self.n].reshape(self.nb, 3)
        self.pseudo = self.a.copy()  # p = qdd at the start: second order (Arnold & Bruls)
        self.lam = sol[self.n:]

    def set_interface_forces(self, forces: np.ndarray) -> None:
        """Forces (N) and moments (N.m) at the ports, global frame, ``interface`` order."""
        f = np.asarray(forces, dtype=float).reshape(len(self.interface))
        self.port_forces = np.zeros((len(self.port_names), 3))
        self.port_forces[self._iface_port, self._iface_col] = f

    def step(self, time: float, step_size: float) -> None:
        """Advance from ``time`` to ``time + step_size`` (s) with port forces held."""
        h = self._h = float(step_size)
        t1 = float(time) + h
        q_pred, v_pred = self.rule.predict(self.q, self.v, self.a, self.pseudo, h)
        beta, gamma = self.rule.position_weight, self.rule.velocity_weight
        a1, lam = self.a.copy(), self.lam.copy()
        for iteration in range(1, self.max_newton + 1):
            q1 = q_pred + beta * h * h * a1
            v1 = v_pred + gamma * h * a1
            r, jac, terms = self._residual(q1, v1, a1, lam, t1, h)
            delta = np.linalg.solve(jac, r)
            da, dl = delta[: self.n].reshape(self.nb, 3), delta[self.n:]
            tol_a, tol_l = self._tolerances(q1, v1, a1 - da, lam - dl)
            if (np.max(np.abs(da)) <= tol_a
                    and (dl.size == 0 or np.max(np.abs(dl)) <= tol_l)):
                a1, lam = a1 - da, lam - dl
                how = "increment"
                break
            if at_roundoff(r, terms):
                # the residual can get no smaller: the increment is round-off amplified
                # by the Newton matrix (a singular configuration), not a correction
                how = "round-off"
                break
            a1, lam = a1 - da, lam - dl
        else:
            raise LinkageConvergenceError(failure_message(
                "linkage Newton", t1, self.max_newton, delta, jac, r, terms))
        self.newton.ended(how)
        self.newton_iterations = iteration
        self.q = q_pred + beta * h * h * a1
        self.v = v_pred + gamma * h * a1
        self.pseudo = self.rule.pseudo(self.a, self.pseudo, a1)
        self.a = a1
        self.lam = lam
        self.time = t1

    def port_kinematics(self):
        """Position (m), velocity, acceleration of every port point: (n_ports, 3) arrays
        with columns x, y, rz (rz: the body angle, rad, and its rates)."""
        pos, vel, acc = point_kinematics(self.q, self.v, self.a, self._port_body, self._port_s)
        b = self._port_body
        return (np.column_stack((pos, self.q[b, 2])), np.column_stack((vel, self.v[b, 2])),
                np.column_stack((acc, self.a[b, 2])))

    def interface_kinematics(self):
        pos, vel, acc = self.port_kinematics()
        i, j = self._iface_port, self._iface_col
        return pos[i, j].copy(), vel[i, j].copy(), acc[i, j].copy()

    def get_state(self) -> dict:
        return {"time": self.time, "q": self.q.copy(), "v": self.v.copy(), "a": self.a.copy(),
                "pseudo": self.pseudo.copy(), "lam": self.lam.copy(),
                "port_forces": self.port_forces.copy(),
                "newton_iterations": self.newton_iterations,
                "newton_roundoff_steps": self.newton.roundoff_steps}

    def set_state(self, state: dict) -> None:
        self.time = float(state["time"])
        self.q = np.array(state["q"], dtype=float)
        self.v = np.array(state["v"], dtype=float)
        self.a = np.array(state["a"], dtype=float)
        self.pseudo = np.array(state.get("pseudo", state["a"]), dtype=float)
        self.lam = np.array(state["lam"], dtype=float)
        self.port_forces = np.array(state["port_forces"], dtype=float)
        self.newton_iterations = int(state["newton_iterations"])
        # a restored step is not counted: the count is of the steps of the trajectory
        self.newton.roundoff_steps = int(state.get("newton_roundoff_steps", 0))

    # --- outputs -----------------------------------------------------------------
    def constraint_violation(self) -> float:
        """Largest |Phi| (m or rad) at the current state: position-level drift."""
        if self.constraints.m == 0:
            return 0.0
        phi, _ = self.constraints.position(self.q, self.time)
        return float(np.max(np.abs(phi)))

    def reactions(self) -> dict[str, float]:
        """Joint reactions: ``<revolute>.f_x/f_y`` force on body_i by body_j (N);
        ``<prismatic>.f_n`` normal force on the body along the line normal (N) and
        ``<prismatic>.m`` the locking moment (N.m); ``<driver>.torque`` the driving
        moment on body_i (N.m)."""
        out = {}
        lam = self.lam
        for kind, name, r0 in self.constraints.groups:
            if kind == "revolute":
                out[f"{name}.f_x"], out[f"{name}.f_y"] = -lam[r0], -lam[r0 + 1]
            elif kind == "prismatic":
                out[f"{name}.f_n"], out[f"{name}.m"] = -lam[r0], -lam[r0 + 1]
            else:
                out[f"{name}.torque"] = -lam[r0]
        return {k: float(v) for k, v in out.items()}

    def outputs(self) -> dict[str, float]:
        """Body poses and rates (``<body>.x y theta vx vy omega ax ay alpha``), joint
        reactions, element tensions (``<element>.force``), ``constraint_violation`` and
        ``newton_iterations`` (of the last step) and ``newton_roundoff_steps`` (steps so
        far whose Newton ended at the residual's round-off floor: fmus/newton.py)."""
        out = {}
        for i, name in enumerate(self.body_names):
            for k, key in enumerate(("x", "y", "theta")):
                out[f"{name}.{key}"] = float(self.q[i, k])
            for k, key in enumerate(("vx", "vy", "omega")):
                out[f"{name}.{key}"] = float(self.v[i, k])
            for k, key in enumerate(("ax", "ay", "alpha")):
                out[f"{name}.{key}"] = float(self.a[i, k])
        out.update(self.reactions())
        if self.forces.elements:
            _, _, _, tensions = self.forces.elements_load(self.q, self.v, tangents=False)
            names = [e.name for e in self.mechanism.springs + self.mechanism.bushings]
            out.update({f"{n}.force": float(t) for n, t in zip(names, tensions)})
        out["constraint_violation"] = self.constraint_violation()
        out["newton_iterations"] = float(self.newton_iterations)
        out["newton_roundoff_steps"] = float(self.newton.roundoff_steps)
        return out
