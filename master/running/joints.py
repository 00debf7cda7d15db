"""Joint laws, the joint state the master integrates, and each glued dof's row
of the Newton system (seed chapter 5).

Every glued degree of freedom r of every joint is one unknown force F_r and one
compatibility residual.  Three kinds of rows:

* fixed joints: R = m_b - m_a, with m the joint's kinematic measure, a blend
  w_u u + w_v v + w_a a (the penalized measure of eq. 5.28 is
  w = (omega^2, 2 xi omega, 1));
* flexible joints on the displacement measure, in force form: the joint force
  follows from the ports' relative motion, R = (F + law(u_b - u_a, v_b - v_a)) / k_ref
  (m, like a displacement residual).  It is the seed's eq. 5.3 with the joint's
  extension and rate taken from the ports, so a glued flexible joint is exactly a
  spring-damper between the two points of one model, whatever rule the
  subsystems integrate with;
* flexible joints on another measure: the seed's form (eqs. 5.2-5.18): the
  master integrates the joint's extension q with the trapezoidal rule under the
  law and R = m_b - m_a - m(q).

The law is Kelvin-Voigt (eq. 5.3/5.36), made odd-symmetric so that it is monotone
(see docs/method.md), with the seed's sign (eq. 5.32):

    (k0 + k1 |q|) q + (c0 + c1 |qd|) qd = -F      (F: force on port b)
"""
from __future__ import annotations

import numpy as np

from dsim.master.errors import SimulationError

EPS = float(np.finfo(float).eps)
#: a law residual within this many ulps of its terms is round-off (fmus/newton.py)
ROUNDOFF_ULPS = 64.0


def measure_weights(measure: str, xi: float = 1.0, omega: float = 0.0):
    """(w_u, w_v, w_a) of a kinematic measure."""
    return {"displacement": (1.0, 0.0, 0.0), "velocity": (0.0, 1.0, 0.0),
            "acceleration": (0.0, 0.0, 1.0),
            "penalized": (omega * omega, 2.0 * xi * omega, 1.0)}[measure]


class JointStates:
    """Extensions q (m, rad), rates qd and accelerations qdd of every glued dof.

    ``flexible`` marks the dofs that follow a law; the others are fixed.
    Arrays hold one entry per glued dof (the order of the force vector F).
    """

    #: what a checkpoint keeps: the state; the laws come from the plan (a run started
    #: from a checkpoint may change them)
    CHECKPOINTED = ("q", "qd", "qdd")

    def __init__(self, flexible, k0, k1, c0, c1, newton_tolerance=1e-14, max_newton=50):
        self.flexible = np.asarray(flexible, dtype=bool)
        self.k0, self.k1 = np.asarray(k0, float), np.asarray(k1, float)
        self.c0, self.c1 = np.asarray(c0, float), np.asarray(c1, float)
        self.nonlinear = bool(np.any(self.k1[self.flexible]) or np.any(self.c1[self.flexible]))
        n = len(self.flexible)
        self.force_form = np.zeros(n, dtype=bool)  # set by configure()
        self.weights = np.zeros((n, 3))
        self.q, self.qd, self.qdd = np.zeros(n), np.zeros(n), np.zeros(n)
        self.newton_tolerance = newton_tolerance
        self.max_newton = max_newton

    def configure(self, weights: np.ndarray, displacement: np.ndarray) -> None:
        """Measure weights (n x 3) of every dof, and which dofs are on the
        displacement measure (flexible ones there are solved in force form)."""
        self.weights = np.asarray(weights, float)
        self.force_form = self.flexible & np.asarray(displacement, bool)
        n = len(self.flexible)
        # fixed joints only (a frame, a chain): a residual needs nothing but the measure
        self._all_fixed = not self.flexible.any()
        self._zeros = np.zeros(n)
        self._zero_state = (self._zeros, self._zeros, self._zeros)

    def reference_stiffness(self, step_size):
        """k0 + 2 c0 / H: scales a force-form row to metres (1 where it is zero)."""
        k = self.k0 + 2.0 / step_size * self.c0
        return np.where(k > 0, k, 1.0)

    def evaluate(self, forces, differences, step_size):
        """Residual r, Jacobian weights W (n x 3: d r / d(u, v, a) of the ports),
        joint diagonal d (d r / d F through the joint itself) and the trial joint
        state (q, qd, qdd) for forces F and port differences (3 x n: u, v, a of
        b minus a)."""
        w = self.weights
        r = np.einsum("rk,kr->r", w, differences)
        if self._all_fixed:  # shared, never written: W, the zero diagonal, a zero state
            return r, w, self._zeros, self._zero_state
        W = w.copy()
        diagonal = np.zeros(len(r))
        q, qd, qdd = differences.copy()
        integrated = self.flexible & ~self.force_form
        if integrated.any():
            tq, tqd, tqdd, tangent = self.trial(forces, step_size)
            joint = np.vstack((tq, tqd, tqdd))
            r[integrated] -= np.einsum("rk,kr->r", w, joint)[integrated]
            blend = w[:, 0] + w[:, 1] * 2.0 / step_size + w[:, 2] * 4.0 / step_size ** 2
            diagonal[integrated] = (blend / tangent)[integrated]
            q[integrated], qd[integrated], qdd[integrated] = (
                tq[integrated], tqd[integrated], tqdd[integrated])
        fixed = ~self.flexible
        q[fixed], qd[fixed], qdd[fixed] = 0.0, 0.0, 0.0
        law = self.force_form
        if law.any():
            force, dk, dc = self.law(differences[0], differences[1])
            k_ref = self.reference_stiffness(step_size)
            r[law] = ((forces + force) / k_ref)[law]
            W[law] = np.column_stack((dk / k_ref, dc / k_ref, np.zeros(len(r))))[law]
            diagonal[law] = (1.0 / k_ref)[law]
        return r, W, diagonal, (q, qd, qdd)

    def start(self, q, qd, qdd) -> None:
        """Initial extension, rate and acceleration (from the ports at t0)."""
        mask = self.flexible
        self.q = np.where(mask, q, 0.0)
        self.qd = np.where(mask, qd, 0.0)
        self.qdd = np.where(mask, qdd, 0.0)

    def law(self, q, qd):
        """Joint force -F for extension q and rate qd, with tangents dk, dc."""
        aq, aqd = np.abs(q), np.abs(qd)
        force = (self.k0 + self.k1 * aq) * q + (self.c0 + self.c1 * aqd) * qd
        return force, self.k0 + 2.0 * self.k1 * aq, self.c0 + 2.0 * self.c1 * aqd

    def trial(self, forces: np.ndarray, step_size: float):
        """End-of-step (q, qd, qdd) that balance ``forces`` under the law, and the
        stiffness d(-F)/dq of each dof (inf for fixed dofs: no extension)."""
        h = step_size
        mask = self.flexible
        q = self.q.copy()
        tangent = np.full(len(q), np.inf)
        if not mask.any():
            zero = np.zeros(len(q))
            return zero, zero, zero, tangent
        for _ in range(self.max_newton):
            qd, _ = trapezoidal_rates(q, self.q, self.qd, self.qdd, h)
            force, dk, dc = self.law(q, qd)
            stiffness = dk + 2.0 / h * dc
            residual = np.where(mask, force + forces, 0.0)
            with np.errstate(divide="ignore", invalid="ignore"):
                delta = np.where(mask, residual / stiffness, 0.0)
            updated = q - delta
            if not np.all(np.isfinite(updated)):
                q = updated
                break
            scale = np.maximum(np.abs(updated), 1e-12)
            if not self.nonlinear or np.all(np.abs(delta) <= self.newton_tolerance * scale
                                            + 1e-300):
                q = updated
                break
            # the law's residual at the round-off of its terms (spring, damper and the
            # joint force): no better q exists
            damping = (self.c0 + self.c1 * np.abs(qd)) * qd
            terms = np.abs(force - damping) + np.abs(damping) + np.abs(forces)
            if np.all(np.abs(residual) <= ROUNDOFF_ULPS * EPS * terms):
                break
            q = updated
        else:
            raise SimulationError("a flexible joint law has no solution for the "
                                  "current force (Newton on the law did not converge)")
        qd, qdd = trapezoidal_rates(q, self.q, self.qd, self.qdd, h)
        _, dk, dc = self.law(q, qd)
        tangent = np.where(mask, dk + 2.0 / h * dc, np.inf)
        return (np.where(mask, q, 0.0), np.where(mask, qd, 0.0),
                np.where(mask, qdd, 0.0), tangent)

    def accept(self, q, qd, qdd) -> None:
        """Make a converged trial the joint state."""
        self.q, self.qd, self.qdd = q, qd, qdd

    def set_law(self, rows, name: str, values) -> None:
        """A scenario's change of a joint's law between steps (running/scenario.py):
        coefficient ``name`` (k0, k1, c0, c1: one value per dof of ``rows``; ``weights``:
        the measure's (w_u, w_v, w_a) of a penalized joint, from its xi and omega) of the
        dofs ``rows``.  New arrays, never written in place: a coupling compares the
        weights it factored its gluing matrix with to the ones a trial gives, and a
        change must show there (it refactors)."""
        rows = np.asarray(rows, dtype=int)
        if name == "weights":
            weights = self.weights.copy()
            weights[rows] = values
            self.weights = weights
            return
        changed = getattr(self, name).copy()
        changed[rows] = values
        setattr(self, name, changed)
        self.nonlinear = bool(np.any(self.k1[self.flexible]) or np.any(self.c1[self.flexible]))


def trapezoidal_rates(q, q0, qd0, qdd0, step_size: float):
    """Rate and acceleration at the step's end by the trapezoidal rule, from the
    end position ``q`` and the start state (``q0``, ``qd0``, ``qdd0``); any units."""
    qd = 2.0 / step_size * (q - q0) - qd0
    return qd, 2.0 / step_size * (qd - qd0) - qdd0
