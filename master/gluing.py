"""The T-T gluing algorithm (seed eqs. 4.13-4.27, 5.6-5.18, 5.28-5.29).

Unknowns per macro step: the joint forces F, one entry per glued dof.  The
subsystem glued at a dof on side b receives +F, on side a -F (eqs. 4.9/4.10:
equilibrium is built in); the residual is the compatibility of the chosen
kinematic measure, R = (m_b - m_a) - m(q) with q the joint extension
(zero for fixed joints).  Newton: F <- F - Lambda R with

    Lambda^-1 = dR/dF = sum_i C_i^T W G_i C_i  +  diag(blend / k_joint)

where C_i (n_i x n_F, entries +-1) maps joint forces onto subsystem i's glued
dofs, G_i = d(u, v, a)_i / d f_i its interface flexibility (by perturbation
and rollback), W the measure weights, and the last term -dq/dF of the flexible
joints (eq. 5.18).  G is kept across steps and refreshed only when a step
needs ``refresh_after`` iterations; the joint term is refreshed every iteration
when a joint law is nonlinear (no FMU call needed).
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from master.errors import SimulationError
from master.joints import JointStates
from master.ssp import MasterSettings


@dataclass
class StepReport:
    """What one macro step took."""

    iterations: int
    refreshed: int
    residual: float


class GluingLayout:
    """The topology of the glued problem: which subsystem dof feels which force.

    ``incidence[i]`` is C_i (n_i x n_F, +1 for side b, -1 for side a);
    ``weights`` is n_F x 3 (w_u, w_v, w_a); ``labels[r]`` names force entry r
    as ``joint.f_dof`` (the CSV column); ``joint_of[r]`` the joint name.
    """

    def __init__(self, incidence, weights, labels, joint_of):
        self.incidence = [sp.csr_matrix(c) for c in incidence]
        # one stacked C (all subsystem dofs x n_F) so that an iteration costs a
        # handful of sparse products, not a few per subsystem
        self.offsets = np.cumsum([c.shape[0] for c in self.incidence])[:-1]
        self.stacked = sp.vstack(self.incidence).tocsr() if self.incidence else None
        self.stacked_t = self.stacked.T.tocsr() if self.incidence else None
        self.stacked_abs_t = abs(self.stacked_t)
        self.weights = np.asarray(weights, dtype=float).reshape(-1, 3)
        self.labels = list(labels)
        self.joint_of = list(joint_of)
        self.size = len(self.labels)


class TTGluing:
    """Newton iteration on the joint forces with step rollback."""

    def __init__(self, backend, layout: GluingLayout, joints: JointStates,
                 settings: MasterSettings):
        self.backend = backend
        self.layout = layout
        self.joints = joints
        self.settings = settings
        self.forces = np.zeros(layout.size)
        self._history: deque = deque(maxlen=3)
        self._flexibility = None  # per subsystem [Gu, Gv, Ga]
        self._subsystem_jacobian = None
        self._factor = None
        self.refreshes = 0
        self._step_size = None
        self.iterations = 0
        self.step_count = 0

    # --- assembly --------------------------------------------------------------------
    def _gather(self, kinematics):
        """Per kind (u, v, a): sum_i C_i^T x_i (= x_b - x_a per joint dof) and the
        matching magnitude sum |C_i|^T |x_i| used by the relative tolerance."""
        layout = self.layout
        stacked = np.zeros((layout.stacked.shape[0], 3))
        for values, start, stop in zip(kinematics, np.r_[0, layout.offsets],
                                       np.r_[layout.offsets, layout.stacked.shape[0]]):
            for kind, x in enumerate(values):
                if x is not None:
                    stacked[start:stop, kind] = x
        differences = (layout.stacked_t @ stacked).T
        magnitudes = (layout.stacked_abs_t @ np.abs(stacked)).T
        return differences, magnitudes

    def residual(self, kinematics, joint_trial):
        """Compatibility residual R (eq. 5.6) and its tolerance per dof."""
        differences, magnitudes = self._gather(kinematics)
        w = self.layout.weights
        q, qd, qdd, _ = joint_trial
        joint = np.vstack((q, qd, qdd))
        r = np.einsum("rk,kr->r", w, differences - joint)
        scale = np.einsum("rk,kr->r", w, magnitudes)
        return r, self.settings.tolerance + self.settings.relative_tolerance * scale

    def _assemble_subsystem_jacobian(self):
        w = self.layout.weights
        total = sp.csr_matrix((self.layout.size, self.layout.size))
        for c, flexibility in zip(self.layout.incidence, self._flexibility):
            if not c.shape[0]:
                continue
            for kind, g in enumerate(flexibility):
                weighted = sp.diags(w[:, kind]) @ c.T
                total = total + weighted @ sp.csr_matrix(g) @ c
        self._subsystem_jacobian = total

    def _factorize(self, tangent, step_size):
        w = self.layout.weights
        blend = w[:, 0] + w[:, 1] * 2.0 / step_size + w[:, 2] * 4.0 / step_size ** 2
        joint_part = blend / tangent  # zero for fixed joints (tangent = inf)
        jacobian = (self._subsystem_jacobian + sp.diags(joint_part)).tocsc()
        try:
            self._factor = splu(jacobian)
        except RuntimeError:
            raise SimulationError("the gluing matrix is singular: a joint constrains "
                                  "a dof that no subsystem can move (check joint dofs)")

    # --- the macro step --------------------------------------------------------------
    def start(self, kinematics) -> None:
        """Initial joint extensions from the ports' kinematics at the start time."""
        differences, _ = self._gather(kinematics)
        self.joints.start(*differences)

    def predict(self) -> np.ndarray:
        """First guess for F from past converged forces (``settings.predictor``)."""
        h = self._history
        kind = self.settings.predictor
        if kind == "none" or not h:
            return np.zeros(self.layout.size) if kind == "none" else self.forces.copy()
        if kind == "constant" or len(h) == 1:
            return h[-1].copy()
        if kind == "linear" or len(h) == 2:
            return 2.0 * h[-1] - h[-2]
        return 3.0 * h[-1] - 3.0 * h[-2] + h[-3]

    def _deltas(self, local_forces):
        return self.settings.perturbation * np.maximum(1.0, np.abs(local_forces))

    def step(self, time: float, step_size: float, step_index: int) -> StepReport:
        """Advance every subsystem from ``time`` by ``step_size`` with compatible
        interface forces; raise SimulationError if Newton does not converge."""
        settings = self.settings
        forces = self.predict()
        previous = self._step_size or step_size
        if abs(step_size - previous) > 1e-9 * previous:
            self._flexibility = None  # G is the response over one step: H matters
        if self._flexibility is None:
            self._step_size = step_size
        self.backend.begin_step()
        refreshed = 0
        last_tangent = None
        for iteration in range(1, settings.max_iterations + 1):
            local = np.split(self.layout.stacked @ forces, self.layout.offsets)
            kinematics = self.backend.trial_step(local, time, step_size)
            trial = self.joints.trial(forces, step_size)
            r, tolerance = self.residual(kinematics, trial)
            if not np.all(np.isfinite(r)):
                worst = int(np.argmax(~np.isfinite(r)))
                raise SimulationError(
                    f"joint '{self.layout.joint_of[worst]}' ({self.layout.labels[worst]}): "
                    "residual is not finite, the iteration diverged",
                    time=time + step_size, step=step_index)
            if np.all(np.abs(r) <= tolerance):
                self.joints.accept(*trial[:3])
                self.forces = forces
                self._history.append(forces.copy())
                self.iterations += iteration
                self.step_count += 1
                return StepReport(iteration, refreshed, float(np.max(np.abs(r), initial=0.0)))
            slow = iteration > 1 and (iteration - 1) % settings.refresh_after == 0
            if self._flexibility is None or slow:
                self._flexibility = self.backend.flexibility(
                    local, time, step_size, [self._deltas(f) for f in local], kinematics)
                self._assemble_subsystem_jacobian()
                self.refreshes += 1
                refreshed += 1
                self._factor = None
            tangent = trial[3]
            if self._factor is None or (self.joints.nonlinear and not np.array_equal(
                    tangent, last_tangent)):
                self._factorize(tangent, step_size)
                last_tangent = tangent
            forces = forces - self._factor.solve(r)
        worst = int(np.argmax(np.abs(r) - tolerance))
        raise SimulationError(
            f"joint '{self.layout.joint_of[worst]}' ({self.layout.labels[worst]}) did not "
            f"converge in {settings.max_iterations} iterations: residual "
            f"{abs(r[worst]):.3e} > tolerance {tolerance[worst]:.3e}",
            time=time + step_size, step=step_index)
