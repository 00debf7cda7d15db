"""Monolithic planar mechanism with flexible links: rigid bodies (a :class:`Linkage`)
and floating-frame beams (:class:`FlexibleLink`) joined by revolute joints, all in
one model solved by one Newton iteration per step.  No FMI, no gluing, no PIM.

This is the monolithic reference of the glued flexible crank slider (SCENES.md
crank_slider_flexible): the *same discrete equations* the glued scene solves,
assembled into one system.

Unknowns at t1 = t + h (trapezoidal rule / Newmark average acceleration for every
coordinate, x1 = x_pred + h^2/4 a1, v1 = v_pred + h/2 a1):

* rigid bodies: accelerations a1 and the multipliers of their own constraints
  (ground revolutes, prismatic rails, drivers), the rows of :class:`Linkage`
  (Baumgarte (1, 2 xi w, w^2), scaled as there);
* each flexible link: reference acceleration R'' (2), angular acceleration alpha
  (1) and elastic accelerations q_f'' (n);
* each revolute joint j between port a and port b: the force F_j (2, global) on
  port b (port a takes -F_j), the convention of the master's glue joints.

Equations (all at t1):

* rigid: ``M a + Phi_q^T lambda = Q(port forces)`` and the Baumgarte rows, exactly
  :meth:`Linkage._residual` with the port forces set to the joint forces;
* flexible link, exactly the equations whose fixed point :meth:`FlexibleLink.step`
  (PIM) iterates to, with the same CG-following reference and the same projected
  elastic load (approximated multipliers of the mean-axis conditions, seed
  eqs. 3.33-3.38)::

      m R'' = sum_p f_p + m g
      (I0 + p.M q_f) alpha + 2 omega p.M q_f' - omega^2 r.M q_f = sum_p (A u0_p) x f_p
      M q_f'' + K (q_f + beta q_f') = P F_elastic(theta, omega, alpha, R'', q_f, q_f', f)

  (the moment uses the undeformed arms u0_p, as the PIM core does; the elastic load
  puts f_p on the end node's u, v);
* joint rows, the master's penalized measure of the same xi, w as the Linkage
  rows: ``w^2 (u_b - u_a) + 2 xi w (v_b - v_a) + (a_b - a_a) = 0`` per dof (divided
  by 1 + xi w h + w^2 h^2 / 4 like the Linkage rows), with the flexible ports'
  exact kinematics ``r = R + A (u0 + d)`` and its rates.

Why one Newton on everything (and not PIM with the joints inside): the glued run,
converged, satisfies each part's step equations with the converged joint forces
and the joint rows; the coupler's part of that is the PIM fixed point.  A single
Newton solves that same union of equations with no partitioned iteration at all
(neither the master's nor the PIM's), to round-off, so glued minus monolithic is
the glued run's iteration error alone (master tolerance, PIM tolerance, parts'
Newton tolerances).  Keeping PIM inside the reference would put a second
partitioned iteration, with its own tolerance, into the yardstick.

The Jacobian is analytic and dense (39 unknowns for the crank slider with a
6-element coupler); ``initialize`` solves the same system with h = 0 (consistent
accelerations and forces at the start).
"""
from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from ..linkage.core import Linkage, LinkageConvergenceError
from ..newton import NewtonCount, at_roundoff, failure_message, roundoff_floor
from ..linkage.elements import AngleDriver, Body, Mechanism, Port, Prismatic, Revolute
from ..linkage.laws import CosineRampSpeed
from ..linkage.scenes import CrankSliderParameters

from .core import FlexibleLink

_J = np.array([[0.0, -1.0], [1.0, 0.0]])


def _rot(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


@dataclass(frozen=True)
class GlueJoint:
    """A revolute joint (dofs x y) between port ``a`` and port ``b``, each
    ``(owner, port)``: owner ``"rigid"`` (a port of the Linkage) or a link's name."""

    name: str
    a: tuple[str, str]
    b: tuple[str, str]


class FlexibleMechanism:
    """Rigid bodies + flexible links + revolute joints, one Newton per step.

    Parameters
    ----------
    rigid:
        A :class:`Linkage` of the rigid bodies with their ground joints and drivers;
        its ports are where the joints attach.
    links:
        Flexible links by name (their parameters, initial state and port names are
        used; their own ``step`` is never called).
    joints:
        :class:`GlueJoint` list.
    newton_tolerance, max_newton:
        Relative size of the last Newton increment that ends a step, and the cap.
    """

    def __init__(self, rigid: Linkage, links: dict[str, FlexibleLink], joints: list[GlueJoint],
                 newton_tolerance: float = 1e-12, max_newton: int = 30):
        self.rigid = rigid
        self.links = dict(links)
        self.joints = list(joints)
        self.row_coefficients = rigid.row_coefficients
        self.newton_tolerance = float(newton_tolerance)
        self.max_newton = int(max_newton)
        # Layout of the unknown vector.
        self.n_rigid, self.m_rigid = rigid.n, rigid.constraints.m
        offset = self.n_rigid + self.m_rigid
        self.link_offset = {}
        for name, link in self.links.items():
            self.link_offset[name] = offset
            offset += 3 + link.beam.mass.shape[0]
        self.force_offset = offset
        self.size = offset + 2 * len(self.joints)
        # Where each joint end acts: (owner, port index).
        self._ends = []
        for j in self.joints:
            ends = []
            for owner, port in (j.a, j.b):
                if owner == "rigid":
                    ends.append(("rigid", rigid.port_names.index(port)))
                else:
                    ends.append((owner, self.links[owner].port_names.index(port)))
            self._ends.append(ends)
        self.forces = np.zeros((len(self.joints), 2))
        self.time = 0.0
        self.newton_iterations = 0
        #: converged steps, and those that ended at the residual's round-off floor
        self.newton = NewtonCount()
        self._h = 0.0

    # --- state helpers ---------------------------------------------------------
    def _port_forces(self, forces):
        """Force (global, N) on every port of every owner from the joint forces."""
        rigid = np.zeros((len(self.rigid.port_names), 3))
        links = {name: np.zeros((2, 2)) for name in self.links}
        for (a, b), f in zip(self._ends, forces):
            for (owner, k), sign in ((a, -1.0), (b, 1.0)):
                if owner == "rigid":
                    rigid[k, :2] += sign * f
                else:
                    links[owner][k] += sign * f
        return rigid, links

    # --- kinematics of ports and their derivatives ------------------------------
    def _rigid_port_row(self, k, q1, v1, a1, h):
        """Measure row c_d u + c_v v + c_a a (2,) of rigid port k at t1 and its
        derivative with respect to the rigid accelerations (2, n_rigid)."""
        ca, cv, cd = self.row_coefficients
        bh2, gh = 0.25 * h * h, 0.5 * h
        b = self.rigid._port_body[k]
        s = self.rigid._port_s[k]
        th, om, al = q1[b, 2], v1[b, 2], a1[b, 2]
        w = _rot(th) @ s
        jw = _J @ w
        pos = q1[b, :2] + w
        vel = v1[b, :2] + om * jw
        acc = a1[b, :2] + al * jw - om * om * w
        value = cd * pos + cv * vel + ca * acc
        d = np.zeros((2, self.n_rigid))
        c = 3 * b
        eye = np.eye(2)
        # translation: pos, vel, acc all have identity in their own coordinate
        d[:, c:c + 2] = (cd * bh2 + cv * gh + ca) * eye
        # angle: d/dtheta, d/domega, d/dalpha
        dpos_th, dvel_th, dacc_th = jw, -om * w, -al * w - om * om * jw
        dvel_om, dacc_om = jw, -2.0 * om * w
        dacc_al = jw
        d[:, c + 2] = (cd * bh2 * dpos_th + cv * (bh2 * dvel_th + gh * dvel_om)
                       + ca * (bh2 * dacc_th + gh * dacc_om + dacc_al))
        return value, d

    @staticmethod
    def _link_state(pred, x, h):
        """End-of-step coordinates of a link from its unknowns x = (R'', alpha, q_f'')."""
        bh2, gh = 0.25 * h * h, 0.5 * h
        Rdd, al, qfdd = x[:2], x[2], x[3:]
        R = pred["R"] + bh2 * Rdd
        Rd = pred["Rd"] + gh * Rdd
        th = pred["theta"] + bh2 * al
        om = pred["omega"] + gh * al
        qf = pred["qf"] + bh2 * qfdd
        qfd = pred["qfd"] + gh * qfdd
        return R, Rd, Rdd, th, om, al, qf, qfd, qfdd

    def _link_port_row(self, link, k, state, h):
        """Measure row (2,) of port k of a flexible link and its derivative with respect
        to the link's unknowns (R'', alpha, q_f'') (2, 3 + n)."""
        ca, cv, cd = self.row_coefficients
        bh2, gh = 0.25 * h * h, 0.5 * h
        R, Rd, Rdd, th, om, al, qf, qfd, qfdd = state
        iu, iv = link._port_dofs[k]
        u0 = link._port_u0[k]
        A = _rot(th)
        d, dd, ddd = qf[[iu, iv]], qfd[[iu, iv]], qfdd[[iu, iv]]
        arm = A @ (u0 + d)
        jarm = _J @ arm
        Add, Addd = A @ dd, A @ ddd
        pos = R + arm
        vel = Rd + om * jarm + Add
        acc = Rdd + al * jarm - om * om * arm + 2.0 * om * (_J @ Add) + Addd
        value = cd * pos + cv * vel + ca * acc
        n = qf.size
        out = np.zeros((2, 3 + n))
        out[:, :2] = (cd * bh2 + cv * gh + ca) * np.eye(2)
        # theta, omega, alpha (all driven by alpha)
        dpos_th = jarm
        dvel_th = -om * arm + _J @ Add
        dacc_th = -al * arm - om * om * jarm - 2.0 * om * Add + _J @ Addd
        dvel_om = jarm
        dacc_om = -2.0 * om * arm + 2.0 * (_J @ Add)
        dacc_al = jarm
        out[:, 2] = (cd * bh2 * dpos_th + cv * (bh2 * dvel_th + gh * dvel_om)
                     + ca * (bh2 * dacc_th + gh * dacc_om + dacc_al))
        # the port node's elastic u, v (d), their rates and accelerations
        JA = _J @ A
        dpos_d = A
        dvel_d, dvel_dd = om * JA, A
        dacc_d, dacc_dd, dacc_ddd = al * JA - om * om * A, 2.0 * om * JA, A
        block = (cd * bh2 * dpos_d + cv * (bh2 * dvel_d + gh * dvel_dd)
                 + ca * (bh2 * dacc_d + gh * dacc_dd + dacc_ddd))
        out[:, 3 + iu] += block[:, 0]
        out[:, 3 + iv] += block[:, 1]
        return value, out

    # --- flexible link equations ---------------------------------------------------
    @staticmethod
    def _link_equations(link, state, forces, h):
        """Residual (3 + n) of a link's equations at t1, its derivatives with respect
        to the link's unknowns (3 + n, 3 + n) and to its two port forces (3 + n, 4), and
        the size of the terms each residual row sums (3 + n: its round-off scale)."""
        b = link.beam
        bh2, gh = 0.25 * h * h, 0.5 * h
        beta_k = link.stiffness_damping
        R, Rd, Rdd, th, om, al, qf, qfd, qfdd = state
        n = qf.size
        A = _rot(th)
        At = A.T
        P = link._projector
        Mt, Mr, Mp, M, K, G = link._Mt, link._Mr, link._Mp, b.mass, b.stiffness, b.gyroscopic
        res = np.zeros(3 + n)
        jac = np.zeros((3 + n, 3 + n))
        jf = np.zeros((3 + n, 4))
        m = link.mass_total
        # translation
        res[:2] = m * Rdd - forces.sum(axis=0) - m * link.gravity
        jac[:2, :2] = m * np.eye(2)
        jf[:2, 0:2] = -np.eye(2)
        jf[:2, 2:4] = -np.eye(2)
        # rotation (moment with undeformed arms, as the PIM core)
        arms = [A @ u0 for u0 in link._port_u0]
        T = sum(float(w[0] * f[1] - w[1] * f[0]) for w, f in zip(arms, forces))
        dT = sum(float((_J @ w)[0] * f[1] - (_J @ w)[1] * f[0]) for w, f in zip(arms, forces))
        inertia = b.inertia + Mp @ qf
        gyro, centri = Mp @ qfd, Mr @ qf
        res[2] = inertia * al + 2.0 * om * gyro - om * om * centri - T
        jac[2, 2] = inertia + 2.0 * gh * gyro - 2.0 * om * gh * centri - bh2 * dT
        jac[2, 3:] = al * bh2 * Mp + 2.0 * om * gh * Mp - om * om * bh2 * Mr
        for k, w in enumerate(arms):
            jf[2, 2 * k:2 * k + 2] = -(_J @ w)
        # elastic: M q_f'' + K (q_f + beta q_f') - P load = 0
        node_force = np.zeros(n)
        d_node_force_th = np.zeros(n)
        dAt = -At @ _J                     # d(A^T)/dtheta
        for k, ((iu, iv), f) in enumerate(zip(link._port_dofs, forces)):
            node_force[[iu, iv]] += At @ f
            d_node_force_th[[iu, iv]] += dAt @ f
        acc_frame = Rdd - link.gravity
        load = (node_force - Mt @ (At @ acc_frame) - al * (Mr + G @ qf) - 2.0 * om * (G @ qfd)
                + om * om * (Mp + M @ qf))
        res[3:] = M @ qfdd + K @ (qf + beta_k * qfd) - P @ load
        terms = np.concatenate((
            m * (np.abs(Rdd) + np.abs(link.gravity)) + np.abs(forces).sum(axis=0),
            [abs(inertia * al) + 2.0 * abs(om * gyro) + om * om * abs(centri)
             + sum(float(np.abs(w) @ np.abs(f[::-1])) for w, f in zip(arms, forces))],
            np.abs(M) @ np.abs(qfdd) + np.abs(K) @ np.abs(qf + beta_k * qfd)
            + np.abs(P) @ np.abs(load)))
        dload_th = d_node_force_th - Mt @ (dAt @ acc_frame)
        dload_om = -2.0 * (G @ qfd) + 2.0 * om * (Mp + M @ qf)
        dload_al = -(Mr + G @ qf)
        dload_qfdd = -al * bh2 * G - 2.0 * om * gh * G + om * om * bh2 * M
        jac[3:, 3:] = M + (bh2 + beta_k * gh) * K - P @ dload_qfdd
        jac[3:, 2] = -P @ (bh2 * dload_th + gh * dload_om + dload_al)
        jac[3:, :2] = P @ (Mt @ At)
        for k, (iu, iv) in enumerate(link._port_dofs):
            E = np.zeros((n, 2))
            E[[iu, iv], :] = At
            jf[3:, 2 * k:2 * k + 2] = -P @ E
        return res, jac, jf, terms

    # --- the monolithic system ------------------------------------------------------
    def _system(self, x, preds, t1, h):
        """Residual and Jacobian of every equation at t1 for unknowns x."""
        ca, cv, cd = self.row_coefficients
        scale = ca + cv * 0.5 * h + cd * 0.25 * h * h
        rig = self.rigid
        nr, mr = self.n_rigid, self.m_rigid
        forces = x[self.force_offset:].reshape(-1, 2)
        rigid_forces, link_forces = self._port_forces(forces)
        res = np.zeros(self.size)
        jac = np.zeros((self.size, self.size))
        # rigid bodies
        a1 = x[:nr].reshape(rig.nb, 3)
        lam = x[nr:nr + mr]
        q1 = preds["rigid"]["q"] + 0.25 * h * h * a1
        v1 = preds["rigid"]["v"] + 0.5 * h * a1
        rig.port_forces = rigid_forces
        r, jr, rigid_terms = rig._residual(q1, v1, a1, lam, t1, h)
        res[:nr + mr] = r
        terms = np.zeros(self.size)
        terms[:nr] = rigid_terms[:nr]
        jac[:nr + mr, :nr + mr] = jr
        # dQ/dF: a port force f on body b enters Q as (f, (J w) . f)
        port_d = {}
        for k in range(len(rig.port_names)):
            body = rig._port_body[k]
            w = _rot(q1[body, 2]) @ rig._port_s[k]
            B = np.zeros((nr, 2))
            B[3 * body:3 * body + 2] = np.eye(2)
            B[3 * body + 2] = _J @ w
            port_d[k] = -B                         # d r_dyn / d f_port
        states = {}
        link_jf = {}
        for name, link in self.links.items():
            o = self.link_offset[name]
            nl = 3 + link.beam.mass.shape[0]
            state = self._link_state(preds[name], x[o:o + nl], h)
            states[name] = state
            r, jl, jf, terms[o:o + nl] = self._link_equations(link, state, link_forces[name], h)
            res[o:o + nl] = r
            jac[o:o + nl, o:o + nl] = jl
            link_jf[name] = jf
        # joint forces in the part equations, and the joint rows
        for j, (ea, eb) in enumerate(self._ends):
            col = row = self.force_offset + 2 * j     # F_j's columns, joint j's rows
            value = np.zeros(2)
            for (owner, k), sign in ((ea, -1.0), (eb, 1.0)):
                if owner == "rigid":
                    jac[:nr, col:col + 2] += sign * port_d[k]
                    v, d = self._rigid_port_row(k, q1, v1, a1, h)
                    jac[row:row + 2, :nr] += sign * d / scale
                else:
                    o = self.link_offset[owner]
                    link = self.links[owner]
                    nl = 3 + link.beam.mass.shape[0]
                    jac[o:o + nl, col:col + 2] += sign * link_jf[owner][:, 2 * k:2 * k + 2]
                    v, d = self._link_port_row(link, k, states[owner], h)
                    jac[row:row + 2, o:o + nl] += sign * d / scale
                value += sign * v
            res[row:row + 2] = value / scale
        return res, jac, q1, v1, states, terms

    def _predictors(self, h):
        rig = self.rigid
        preds = {"rigid": {"q": rig.q + h * rig.v + 0.25 * h * h * rig.a,
                           "v": rig.v + 0.5 * h * rig.a}}
        for name, link in self.links.items():
            preds[name] = {"R": link.R + h * link.Rd + 0.25 * h * h * link.Rdd,
                           "Rd": link.Rd + 0.5 * h * link.Rdd,
                           "theta": link.theta + h * link.omega + 0.25 * h * h * link.alpha,
                           "omega": link.omega + 0.5 * h * link.alpha,
                           "qf": link.qf + h * link.qfd + 0.25 * h * h * link.qfdd,
                           "qfd": link.qfd + 0.5 * h * link.qfdd}
        return preds

    def _unknowns(self):
        x = np.zeros(self.size)
        nr, mr = self.n_rigid, self.m_rigid
        x[:nr] = self.rigid.a.reshape(-1)
        x[nr:nr + mr] = self.rigid.lam
        for name, link in self.links.items():
            o = self.link_offset[name]
            x[o:o + 2] = link.Rdd
            x[o + 2] = link.alpha
            x[o + 3:o + 3 + link.qf.size] = link.qfdd
        x[self.force_offset:] = self.forces.reshape(-1)
        return x

    def _solve(self, t1, h):
        """Newton on all unknowns at t1; stores the converged state."""
        preds = self._predictors(h)
        x = self._unknowns()
        nr, mr = self.n_rigid, self.m_rigid
        acc = np.ones(self.size, dtype=bool)
        acc[nr:nr + mr] = False
        acc[self.force_offset:] = False
        ca, cv, cd = self.row_coefficients
        scale = ca + cv * 0.5 * h + cd * 0.25 * h * h
        for iteration in range(1, self.max_newton + 1):
            res, jac, q1, v1, states, terms = self._system(x, preds, t1, h)
            delta = np.linalg.solve(jac, res)
            # Stopping sizes: relative tolerance plus the round-off floor of the
            # joint and constraint rows (w^2 and 2 xi w amplify the positions' and
            # velocities' last bits; see Linkage._tolerances).
            big_q = max([1.0 + np.max(np.abs(q1))]
                        + [1.0 + np.max(np.abs(s[0])) + np.max(np.abs(s[6])) for s in
                           states.values()])
            big_v = max([1.0 + np.max(np.abs(v1))]
                        + [1.0 + np.max(np.abs(s[1])) + abs(s[4]) * (1.0 + np.max(np.abs(s[0])))
                           for s in states.values()])
            x_new = x - delta
            constraint_scale = (cd * big_q + cv * big_v
                                + ca * (1.0 + np.max(np.abs(x_new[acc])))) / scale
            floor = float(roundoff_floor(constraint_scale))
            tol_a = self.newton_tolerance * (1.0 + np.max(np.abs(x_new[acc]))) + floor
            lam = x_new[~acc]
            big_m = max(np.max(self.rigid.mass), *(l.mass_total for l in self.links.values()))
            tol_l = self.newton_tolerance * (1.0 + np.max(np.abs(lam))) + floor * big_m
            if np.max(np.abs(delta[acc])) <= tol_a and np.max(np.abs(delta[~acc])) <= tol_l:
                x, how = x_new, "increment"
                break
            # the constraint and joint rows (positions, velocities and accelerations
            # weighted as the rows weigh them) at their round-off floor too
            terms[~acc] = np.maximum(terms[~acc], constraint_scale)
            if at_roundoff(res, terms):
                how = "round-off"  # the increment is amplified round-off (Linkage.step)
                break
            x = x_new
        else:
            raise LinkageConvergenceError(failure_message(
                "flexible mechanism Newton", t1, self.max_newton, delta, jac, res, terms))
        self.newton.ended(how)
        self.newton_iterations = iteration
        # store
        rig = self.rigid
        a1 = x[:nr].reshape(rig.nb, 3)
        rig.q = preds["rigid"]["q"] + 0.25 * h * h * a1
        rig.v = preds["rigid"]["v"] + 0.5 * h * a1
        rig.a = a1.copy()
        rig.lam = x[nr:nr + mr].copy()
        rig.time = t1
        for name, link in self.links.items():
            o = self.link_offset[name]
            R, Rd, Rdd, th, om, al, qf, qfd, qfdd = self._link_state(
                preds[name], x[o:o + 3 + link.qf.size], h)
            link.R, link.Rd, link.Rdd = R, Rd, Rdd.copy()
            link.theta, link.omega, link.alpha = float(th), float(om), float(al)
            link.qf, link.qfd, link.qfdd = qf, qfd, qfdd.copy()
            link.time = t1
        self.forces = x[self.force_offset:].reshape(-1, 2).copy()
        rigid_forces, link_forces = self._port_forces(self.forces)
        rig.port_forces = rigid_forces
        for name, link in self.links.items():
            link.port_forces = link_forces[name]
        self.time = t1

    # --- public -----------------------------------------------------------------------
    def initialize(self, start_time: float) -> None:
        """Consistent accelerations, multipliers and joint forces at ``start_time``
        for the current positions and velocities (assumed to satisfy the joints):
        the step equations with h = 0."""
        self._h = 0.0
        self._solve(float(start_time), 0.0)

    def step(self, time: float, step_size: float) -> None:
        """Advance from ``time`` to ``time + step_size`` (s)."""
        self._h = float(step_size)
        self._solve(float(time) + self._h, self._h)

    def joint_forces(self) -> dict[str, np.ndarray]:
        """Force (N, global) on port b of every joint, the master's ``<joint>.f_x/f_y``."""
        return {j.name: self.forces[i].copy() for i, j in enumerate(self.joints)}

    def joint_violation(self) -> float:
        """Largest |u_b - u_a| (m) over the joints at the current state."""
        worst = 0.0
        for ea, eb in self._ends:
            pos = []
            for owner, k in (ea, eb):
                if owner == "rigid":
                    pos.append(self.rigid.port_kinematics()[0][k, :2])
                else:
                    pos.append(self.links[owner].port_kinematics()[0][k])
            worst = max(worst, float(np.max(np.abs(pos[1] - pos[0]))))
        return worst


#: The coupler's beam parameters besides those of CrankSliderParameters (length,
#: density, square section): steel, 6 elements, no damping, as FlexibleLink2D's defaults.
COUPLER_BEAM = dict(young=210e9, elements=6, stiffness_damping=0.0)


def crank_slider_flexible(params: CrankSliderParameters = CrankSliderParameters(),
                          coupler: dict | None = None, baumgarte_frequency: float = 1000.0,
                          baumgarte_damping: float = 1.0, **options) -> FlexibleMechanism:
    """The crank slider of seed section 4.2.1 with a flexible coupler, whole.

    Crank (rigid, revolute O to ground, driven by the cosine ramp speed law) and slider
    (rigid, on y = 0, angle locked) are one :class:`Linkage` with ports ``A`` (crank
    tip) and ``P`` (slider); the coupler is a :class:`FlexibleLink` (length, density
    and square section from ``params``; ``coupler`` overrides those and
    :data:`COUPLER_BEAM`) on the x
    axis from the crank tip; joints ``A`` = (rigid.A, coupler.A) and ``B`` =
    (coupler.B, rigid.P), as the glued scene's joints A = (crank.A, coupler.A),
    B = (coupler.B, slider.P).  Everything starts at rest.  ``options`` go to
    :class:`FlexibleMechanism`."""
    l1, l2 = params.crank_length, params.coupler_length
    m1 = params.crank_mass
    mech = Mechanism(
        bodies=[Body("crank", m1, m1 * l1 ** 2 / 12.0, x=l1 / 2.0),
                Body("slider", params.slider_mass, 1.0, x=l1 + l2)],
        revolutes=[Revolute("O", "crank", (-l1 / 2.0, 0.0), None, (0.0, 0.0))],
        prismatics=[Prismatic("rail", "slider")],
        drivers=[AngleDriver("drive", "crank",
                             CosineRampSpeed(0.0, params.speed, params.ramp_time))],
        ports=[Port("A", "crank", (l1 / 2.0, 0.0)), Port("P", "slider", (0.0, 0.0))],
        gravity=params.gravity)
    rigid = Linkage(copy.deepcopy(mech), baumgarte_frequency=baumgarte_frequency,
                    baumgarte_damping=baumgarte_damping)
    side = params.coupler_section
    beam = {"density": params.coupler_density, "area": side ** 2,
            "second_moment": side ** 4 / 12.0, **COUPLER_BEAM, **(coupler or {})}
    link = FlexibleLink(length=l2, x=l1 + l2 / 2.0, gravity=params.gravity, **beam)
    joints = [GlueJoint("A", ("rigid", "A"), ("coupler", "A")),
              GlueJoint("B", ("coupler", "B"), ("rigid", "P"))]
    return FlexibleMechanism(rigid, {"coupler": link}, joints, **options)
