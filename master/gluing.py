"""The T-T gluing algorithm (seed eqs. 4.13-4.27, 5.6-5.18, 5.28-5.29).

Unknowns per macro step: the joint forces F, one entry per glued dof.  The
subsystem glued at a dof on side b receives +F, on side a -F (eqs. 4.9/4.10:
equilibrium is built in); the residual is the compatibility of the chosen
kinematic measure (master.joints: fixed joints, flexible joints in force form
on the displacement measure, the seed's integrated joint extension otherwise).
Newton: F <- F - Lambda R with

    Lambda^-1 = dR/dF = sum_k diag(W_k) sum_i C_i^T G_ik C_i  +  diag(d)

where C_i maps joint forces onto subsystem i's glued dofs (entries +-1, or
moving-least-squares weights on non-matching node sets), G_ik = d(u, v, a)_i / d f_i
its interface flexibility (by perturbation and rollback), W the rows' weights
per kinematic kind and d the joints' own term (eq. 5.18).  G is kept across
steps and re-measured when a step needs ``refresh_after`` iterations or, by
default, when Newton has slowed to a linear rate that a refresh would beat;
W and d need no FMU call and follow a nonlinear joint law every iteration.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from master.errors import SimulationError
from master.joints import JointStates
from master.scene import MasterSettings


@dataclass
class StepReport:
    """What one macro step took."""

    iterations: int
    refreshed: int
    residual: float


class GluingLayout:
    """The topology of the glued problem: which subsystem dof feels which force.

    ``incidence[i]`` is C_i (n_i x n_F, +1 for side b, -1 for side a);
    ``weights`` is n_F x 3 (w_u, w_v, w_a) and ``measures`` the measure's name per
    dof; ``labels[r]`` names force entry r as ``joint.f_dof`` (the CSV column);
    ``joint_of[r]`` the joint name.
    """

    def __init__(self, incidence, weights, labels, joint_of, measures=None):
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
        #: the measure's name per dof ("displacement", "velocity", ...)
        self.measures = list(measures or ["displacement"] * len(self.labels))
        self.size = len(self.labels)

    def differences(self, kinematics, magnitudes: bool = True):
        """Per kind (u, v, a): sum_i C_i^T x_i (= x_b - x_a per joint dof) and the
        matching magnitude sum |C_i|^T |x_i| used by the relative tolerance (None
        unless asked); both 3 x n_F."""
        stacked = np.zeros((self.stacked.shape[0], 3))
        for values, start, stop in zip(kinematics, np.r_[0, self.offsets],
                                       np.r_[self.offsets, self.stacked.shape[0]]):
            for kind, x in enumerate(values):
                if x is not None:
                    stacked[start:stop, kind] = x
        differences = (self.stacked_t @ stacked).T
        if not magnitudes:
            return differences, None
        return differences, (self.stacked_abs_t @ np.abs(stacked)).T

    def local_forces(self, forces):
        """Split the joint forces F into each subsystem's glued-dof forces C_i F."""
        return np.split(self.stacked @ forces, self.offsets)


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
        self._parts = None
        self._factor = None
        self._factored_with = None
        joints.configure(layout.weights,
                         np.array([m == "displacement" for m in layout.measures], dtype=bool))
        self.refreshes = 0
        self._step_size = None
        self.iterations = 0
        self.step_count = 0

    # --- assembly --------------------------------------------------------------------
    def residual(self, kinematics, forces, step_size):
        """Compatibility residual R (eqs. 4.13, 5.6) at ``forces``, its tolerance per
        dof, the Jacobian weights and joint diagonal, and the trial joint state."""
        relative = self.settings.relative_tolerance
        differences, magnitudes = self.layout.differences(kinematics, magnitudes=relative > 0)
        r, weights, diagonal, trial = self.joints.evaluate(forces, differences, step_size)
        tolerance = np.full(len(r), self.settings.tolerance)
        if relative > 0:
            tolerance += relative * np.einsum("rk,kr->r", np.abs(weights), magnitudes)
        return r, tolerance, weights, diagonal, trial

    def _assemble_subsystem_parts(self):
        """A_k = sum_i C_i^T G_ik C_i for k = u, v, a (eq. 5.14 before weighting)."""
        n = self.layout.size
        parts = [sp.csr_matrix((n, n)) for _ in range(3)]
        for c, flexibility in zip(self.layout.incidence, self._flexibility):
            if not c.shape[0]:
                continue
            for kind, g in enumerate(flexibility):
                if np.any(g):
                    parts[kind] = parts[kind] + c.T @ sp.csr_matrix(g) @ c
        self._parts = parts

    def _factorize(self, weights, diagonal):
        jacobian = sp.diags(diagonal)
        for kind, part in enumerate(self._parts):
            if np.any(weights[:, kind]):
                jacobian = jacobian + sp.diags(weights[:, kind]) @ part
        try:
            self._factor = splu(jacobian.tocsc())
        except RuntimeError:
            raise SimulationError(f"{self._singular_direction(jacobian)}: the gluing matrix "
                                  "is singular (a singular configuration of the mechanism, "
                                  "or a joint dof that no subsystem can move)") from None
        self._factored_with = (weights, diagonal)

    def _singular_direction(self, jacobian) -> str:
        """Name the joint dof that dominates the gluing matrix's null direction."""
        if self.layout.size > 2000:
            return "joints " + ", ".join(sorted(set(self.layout.joint_of)))
        dense = jacobian.toarray()
        dense[~np.isfinite(dense)] = 0.0
        null = np.linalg.svd(dense)[2][-1]
        worst = int(np.argmax(np.abs(null)))
        return f"joint '{self.layout.joint_of[worst]}' ({self.layout.labels[worst]})"

    def _needs_refresh(self, iteration, history, refreshed, local) -> bool:
        """Re-measure the interface flexibility now?  Always when there is none;
        after every ``refresh_after`` iterations of one step (the seed's rule); and,
        with ``refresh = adaptive``, once per step when Newton has slowed to linear
        convergence (two successive contraction rates alike: a stale Lambda, not
        the superlinear approach of a good one) at a rate that predicts more
        iterations to the tolerance than a refresh costs (one trial step per glued
        dof of the largest subsystem), or when the residual grows."""
        settings = self.settings
        if self._flexibility is None:
            return True
        if iteration > 1 and (iteration - 1) % settings.refresh_after == 0:
            return True
        if settings.refresh != "adaptive" or refreshed or len(history) < 3 or history[-1] == 0:
            return False
        rate, previous = history[-1] / history[-2], history[-2] / history[-3]
        if rate >= 1.0:
            return True
        if rate < 0.5 * previous:
            return False  # still speeding up
        remaining = np.log(history[-1]) / -np.log(max(rate, 1e-300))
        return remaining > max((len(f) for f in local), default=0) + 1

    # --- the macro step --------------------------------------------------------------
    def start(self, kinematics, forces=None) -> None:
        """Initial joint extensions from the ports' kinematics at the start time, and
        the start forces (zero unless a consistent start found others)."""
        differences, _ = self.layout.differences(kinematics, magnitudes=False)
        self.joints.start(*differences)
        if forces is not None:
            self.forces = np.array(forces, dtype=float)
            self._history.append(self.forces.copy())

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

    def _begin_step(self, step_size: float) -> None:
        """Save every subsystem's state; forget G when the step size changed (G is
        the response over one step)."""
        previous = self._step_size or step_size
        if abs(step_size - previous) > 1e-9 * previous:
            self._flexibility = None
        if self._flexibility is None:
            self._step_size = step_size
        self.backend.begin_step()

    def _refresh(self, local, time, step_size, kinematics) -> None:
        """Measure every subsystem's interface flexibility around ``local`` forces."""
        self._flexibility = self.backend.flexibility(
            local, time, step_size, [self._deltas(f) for f in local], kinematics)
        self._assemble_subsystem_parts()
        self.refreshes += 1
        self._factor = None

    def _ensure_factor(self, weights, diagonal, time: float, step_index: int) -> None:
        """Factor the gluing matrix unless the held factor has these weights."""
        if self._factor is not None and np.array_equal(weights, self._factored_with[0]) \
                and np.array_equal(diagonal, self._factored_with[1]):
            return
        try:
            self._factorize(weights, diagonal)
        except SimulationError as error:
            raise SimulationError(str(error), time=time, step=step_index) from None

    def step(self, time: float, step_size: float, step_index: int) -> StepReport:
        """Advance every subsystem from ``time`` by ``step_size`` with compatible
        interface forces; raise SimulationError if Newton does not converge."""
        settings = self.settings
        forces = self.predict()
        self._begin_step(step_size)
        refreshed = 0
        history = []  # max |R| / tolerance per iteration
        for iteration in range(1, settings.max_iterations + 1):
            local = self.layout.local_forces(forces)
            kinematics = self.backend.trial_step(local, time, step_size)
            r, tolerance, weights, diagonal, trial = self.residual(kinematics, forces, step_size)
            if not np.all(np.isfinite(r)):
                worst = int(np.argmax(~np.isfinite(r)))
                raise SimulationError(
                    f"joint '{self.layout.joint_of[worst]}' ({self.layout.labels[worst]}): "
                    "residual is not finite, the iteration diverged",
                    time=time + step_size, step=step_index)
            history.append(float(np.max(np.abs(r) / tolerance, initial=0.0)))
            if history[-1] <= 1.0:
                self.joints.accept(*trial)
                self.forces = forces
                self._history.append(forces.copy())
                self.iterations += iteration
                self.step_count += 1
                return StepReport(iteration, refreshed, float(np.max(np.abs(r), initial=0.0)))
            if self._needs_refresh(iteration, history, refreshed, local):
                self._refresh(local, time, step_size, kinematics)
                refreshed += 1
            self._ensure_factor(weights, diagonal, time + step_size, step_index)
            forces = forces - self._factor.solve(r)
        worst = int(np.argmax(np.abs(r) - tolerance))
        raise SimulationError(
            f"joint '{self.layout.joint_of[worst]}' ({self.layout.labels[worst]}) did not "
            f"converge in {settings.max_iterations} iterations: residual "
            f"{abs(r[worst]):.3e} > tolerance {tolerance[worst]:.3e}",
            time=time + step_size, step=step_index)
