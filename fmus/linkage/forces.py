"""Applied generalized forces of a planar mechanism and their tangents.

Q (N for x, y; N.m for theta) collects gravity, port forces, spring-dampers and
bushings.  A force F applied at world offset w from a body's CG contributes
(F, (J w) . F) to the body's (x, y, theta) entries, and d/dtheta of the moment
is -w . F (the force is held fixed in the global frame).  Two-point force
elements (spring-dampers, bushings) come with exact tangents dQ/dq, dQ/dv.
"""
from __future__ import annotations

import numpy as np

from .elements import Mechanism
from .kinematics import perp, world_offsets


class ForceSet:
    """Gravity, port loads and force elements of a :class:`Mechanism`."""

    def __init__(self, mech: Mechanism, index: dict[str, int]):
        nb = len(mech.bodies)
        masses = np.array([b.mass for b in mech.bodies])
        self.n = 3 * nb
        self.gravity_force = np.zeros(self.n)
        g = np.asarray(mech.gravity, dtype=float)
        self.gravity_force[0::3] = masses * g[0]
        self.gravity_force[1::3] = masses * g[1]
        # Ports: body index and local point of each; the force layout per port is
        # (fx, fy, mz) with zeros for dofs the port does not have.
        self.port_body = np.array([index[p.body] for p in mech.ports], dtype=int)
        self.port_s = np.array([p.point for p in mech.ports], dtype=float).reshape(-1, 2)
        # Two-point elements: (kind, body_i, s_i, body_j or -1, s_j, k, c, L0).
        self.elements = []
        for e in mech.springs:
            self.elements.append(("spring", index[e.body_i], np.asarray(e.point_i, float),
                                  -1 if e.body_j is None else index[e.body_j],
                                  np.asarray(e.point_j, float), e.stiffness, e.damping,
                                  e.length0))
        for e in mech.bushings:
            self.elements.append(("bushing", index[e.body_i], np.asarray(e.point_i, float),
                                  -1 if e.body_j is None else index[e.body_j],
                                  np.asarray(e.point_j, float), e.stiffness, e.damping, 0.0))

    # --- port loads ---------------------------------------------------------
    def port_load(self, q: np.ndarray, port_forces: np.ndarray):
        """Generalized force of port loads and its theta-tangent.

        port_forces: (n_ports, 3) global fx, fy (N) and mz (N.m).
        Returns Q (n,) and the diagonal of dQ/dq at theta entries (n,).
        """
        Q = np.zeros(self.n)
        dq = np.zeros(self.n)
        if len(self.port_body) == 0:
            return Q, dq
        w = world_offsets(q[self.port_body, 2], self.port_s)
        jw = perp(w)
        b3 = 3 * self.port_body
        np.add.at(Q, b3, port_forces[:, 0])
        np.add.at(Q, b3 + 1, port_forces[:, 1])
        np.add.at(Q, b3 + 2, np.einsum("ij,ij->i", jw, port_forces[:, :2]) + port_forces[:, 2])
        np.add.at(dq, b3 + 2, -np.einsum("ij,ij->i", w, port_forces[:, :2]))
        return Q, dq

    # --- two-point elements ---------------------------------------------------
    @staticmethod
    def _element_force(kind, k, c, L0, d, dd):
        """Force f (N, global) on point i of an element from the separation
        d = p_i - p_j (m) and its rate dd (m/s), its tangents D = df/dd and
        E = df/d(dd) (2 x 2), and the tension (N) reported as output."""
        if kind == "bushing":
            f = -(k * d + c * dd)
            return f, -k * np.eye(2), -c * np.eye(2), float(np.linalg.norm(f))
        length = float(np.hypot(d[0], d[1]))
        if length == 0.0:  # direction undefined: no force, no tangent
            return np.zeros(2), np.zeros((2, 2)), np.zeros((2, 2)), 0.0
        e = d / length
        proj = (np.eye(2) - np.outer(e, e)) / length      # de/dd
        tension = k * (length - L0) + c * float(e @ dd)
        dT = k * e + c * (proj @ dd)
        D = -(np.outer(e, dT) + tension * proj)
        E = -c * np.outer(e, e)
        return -tension * e, D, E, tension

    def elements_load(self, q: np.ndarray, v: np.ndarray, tangents: bool = True):
        """Generalized force of all two-point elements (n,), with dQ/dq and dQ/dv
        (n, n) when ``tangents``, and each element's tension (N).

        With B_b = [[1, 0], [0, 1], (J w_b)^T] (3 x 2) the force-to-body map, body i
        gets B_i f and body j gets -B_j f; d(d)/dq_b = s_b B_b^T, d(dd)/dq_b =
        s_b [0, 0, -omega_b w_b], d(dd)/dv_b = s_b B_b^T (s_i = 1, s_j = -1), and the
        moment arm turning with the body adds -s_b w_b . f on the theta diagonal.
        """
        Q = np.zeros(self.n)
        Kq = np.zeros((self.n, self.n)) if tangents else None
        Kv = np.zeros((self.n, self.n)) if tangents else None
        tensions = []
        for kind, bi, si, bj, sj, k, c, L0 in self.elements:
            ends = [(bi, si, 1.0)] + ([] if bj < 0 else [(bj, sj, -1.0)])
            pos, vel, B, Vq = [], [], [], []
            for b, s, _ in ends:
                w = world_offsets(q[b:b + 1, 2], s[None, :])[0]
                jw = np.array([-w[1], w[0]])
                pos.append(q[b, :2] + w)
                vel.append(v[b, :2] + v[b, 2] * jw)
                B.append(np.array([[1.0, 0.0], [0.0, 1.0], jw]))
                Vq.append(np.column_stack((np.zeros(2), np.zeros(2), -v[b, 2] * w)))
            if bj < 0:  # ground point: s_j is global and fixed
                pos.append(sj)
                vel.append(np.zeros(2))
            f, D, E, tension = self._element_force(kind, k, c, L0, pos[0] - pos[1],
                                                   vel[0] - vel[1])
            tensions.append(tension)
            for (b, s, sign), Bb in zip(ends, B):
                Q[3 * b:3 * b + 3] += sign * (Bb @ f)
            if not tangents:
                continue
            for ia, (a, _, sa) in enumerate(ends):
                for ib, (b, _, sb) in enumerate(ends):
                    rows, cols = slice(3 * a, 3 * a + 3), slice(3 * b, 3 * b + 3)
                    df_dq = sb * (D @ B[ib].T + E @ Vq[ib])
                    Kq[rows, cols] += sa * (B[ia] @ df_dq)
                    Kv[rows, cols] += sa * sb * (B[ia] @ E @ B[ib].T)
                jw = B[ia][2]
                w = np.array([jw[1], -jw[0]])  # w = -J (J w)
                Kq[3 * a + 2, 3 * a + 2] += -sa * (w @ f)
        return Q, Kq, Kv, tensions
