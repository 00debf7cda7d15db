"""Holonomic constraints of a planar mechanism, compiled into flat arrays.

Every constraint row r supported here has the form

    Phi_r(q, t) = sum_terms c . p_b(s)  +  sum_angles d theta_b  -  const_r  -  f_r(t)

with p_b(s) the global position of local point s of body b, c a constant global
2-vector, d a constant and f_r a prescribed motion law.  That covers revolute
joints (rows c = e_x, e_y with +1 on body i and -1 on body j), prismatic joints on
ground (c = the line's normal, plus a locked angle) and angle drivers.

:meth:`ConstraintSet.evaluate` returns Phi, its Jacobian Phi_q, the rates
dPhi/dt and d2Phi/dt2 (exact, for given q, v, a) and the derivatives of those
with respect to q and v that Newton's method needs.
"""
from __future__ import annotations

import numpy as np

from .elements import Mechanism
from .kinematics import perp, world_offsets

_EX, _EY = np.array([1.0, 0.0]), np.array([0.0, 1.0])


class ConstraintSet:
    """The constraint rows of a :class:`Mechanism` (see module docstring)."""

    def __init__(self, mech: Mechanism, index: dict[str, int]):
        pt_row, pt_body, pt_s, pt_c = [], [], [], []
        an_row, an_body, an_coef = [], [], []
        const: list[float] = []
        laws: list[tuple[int, object]] = []
        #: (kind, name, first row) for reporting reactions.
        self.groups: list[tuple[str, str, int]] = []
        #: Unit normal (global) of each prismatic joint's line.
        self.prismatic_normals: dict[str, np.ndarray] = {}

        def point(row, body, s, c):
            pt_row.append(row)
            pt_body.append(index[body])
            pt_s.append(np.asarray(s, dtype=float))
            pt_c.append(np.asarray(c, dtype=float))

        for j in mech.revolutes:
            r0 = len(const)
            self.groups.append(("revolute", j.name, r0))
            for k, e in enumerate((_EX, _EY)):
                point(r0 + k, j.body_i, j.point_i, e)
                if j.body_j is None:
                    const.append(float(j.point_j[k]))
                else:
                    point(r0 + k, j.body_j, j.point_j, -e)
                    const.append(0.0)
        for p in mech.prismatics:
            r0 = len(const)
            self.groups.append(("prismatic", p.name, r0))
            axis = np.asarray(p.axis, dtype=float)
            axis = axis / np.linalg.norm(axis)
            normal = np.array([-axis[1], axis[0]])
            self.prismatic_normals[p.name] = normal
            point(r0, p.body, p.point, normal)
            const.append(float(normal @ np.asarray(p.origin, dtype=float)))
            body = next(b for b in mech.bodies if b.name == p.body)
            an_row.append(r0 + 1)
            an_body.append(index[p.body])
            an_coef.append(1.0)
            const.append(float(body.theta))
        for d in mech.drivers:
            r0 = len(const)
            self.groups.append(("driver", d.name, r0))
            an_row.append(r0)
            an_body.append(index[d.body_i])
            an_coef.append(1.0)
            if d.body_j is not None:
                an_row.append(r0)
                an_body.append(index[d.body_j])
                an_coef.append(-1.0)
            const.append(0.0)
            laws.append((r0, d.law))

        self.m = len(const)
        self.pt_row = np.array(pt_row, dtype=int)
        self.pt_body = np.array(pt_body, dtype=int)
        self.pt_s = np.array(pt_s, dtype=float).reshape(-1, 2)
        self.pt_c = np.array(pt_c, dtype=float).reshape(-1, 2)
        self.an_row = np.array(an_row, dtype=int)
        self.an_body = np.array(an_body, dtype=int)
        self.an_coef = np.array(an_coef, dtype=float)
        self.const = np.array(const, dtype=float)
        self.laws = laws

    def time_terms(self, t: float):
        """f(t), f'(t), f''(t) of every row (zero where no law), shape (m,) each."""
        f, fd, fdd = np.zeros(self.m), np.zeros(self.m), np.zeros(self.m)
        for row, law in self.laws:
            f[row], fd[row], fdd[row] = law(t)
        return f, fd, fdd

    def position(self, q: np.ndarray, t: float):
        """Phi (m, rad) and Phi_q, shapes (m,) and (m, 3 nb); q has shape (nb, 3)."""
        nq = q.size
        f, _, _ = self.time_terms(t)
        w = world_offsets(q[self.pt_body, 2], self.pt_s)
        jw = perp(w)
        phi = -self.const - f
        np.add.at(phi, self.pt_row, np.einsum("ij,ij->i", self.pt_c, q[self.pt_body, :2] + w))
        np.add.at(phi, self.an_row, self.an_coef * q[self.an_body, 2])
        jac = np.zeros((self.m, nq))
        b3 = 3 * self.pt_body
        np.add.at(jac, (self.pt_row, b3), self.pt_c[:, 0])
        np.add.at(jac, (self.pt_row, b3 + 1), self.pt_c[:, 1])
        np.add.at(jac, (self.pt_row, b3 + 2), np.einsum("ij,ij->i", self.pt_c, jw))
        np.add.at(jac, (self.an_row, 3 * self.an_body + 2), self.an_coef)
        return phi, jac

    def evaluate(self, q: np.ndarray, v: np.ndarray, a: np.ndarray,
                 lam: np.ndarray, t: float) -> dict:
        """Everything Newton needs at (q, v, a, lambda, t); arrays of shape (nb, 3).

        Returns a dict with ``phi`` (m,), ``phi_q`` (m, n), ``phi_d`` = dPhi/dt,
        ``phi_dd`` = d2Phi/dt2 (m,), ``phi_d_q`` = d(phi_d)/dq, ``phi_dd_q``,
        ``phi_dd_v`` (m, n), and ``k_lambda`` = d(Phi_q^T lambda)/dq (n, n).
        """
        nb = q.shape[0]
        n = 3 * nb
        _, fd, fdd = self.time_terms(t)
        phi, jac = self.position(q, t)
        vf, af = v.reshape(n), a.reshape(n)
        w = world_offsets(q[self.pt_body, 2], self.pt_s)
        jw = perp(w)
        om = v[self.pt_body, 2]
        al = a[self.pt_body, 2]
        c_w = np.einsum("ij,ij->i", self.pt_c, w)
        c_jw = np.einsum("ij,ij->i", self.pt_c, jw)
        phi_d = jac @ vf - fd
        phi_dd = jac @ af - fdd
        np.add.at(phi_dd, self.pt_row, -om * om * c_w)
        col = 3 * self.pt_body + 2
        phi_d_q = np.zeros((self.m, n))
        phi_dd_q = np.zeros((self.m, n))
        phi_dd_v = np.zeros((self.m, n))
        np.add.at(phi_d_q, (self.pt_row, col), -om * c_w)
        np.add.at(phi_dd_q, (self.pt_row, col), -al * c_w - om * om * c_jw)
        np.add.at(phi_dd_v, (self.pt_row, col), -2.0 * om * c_w)
        k_lambda = np.zeros((n, n))
        np.add.at(k_lambda, (col, col), -lam[self.pt_row] * c_w)
        return {"phi": phi, "phi_q": jac, "phi_d": phi_d, "phi_dd": phi_dd,
                "phi_d_q": phi_d_q, "phi_dd_q": phi_dd_q, "phi_dd_v": phi_dd_v,
                "k_lambda": k_lambda}
