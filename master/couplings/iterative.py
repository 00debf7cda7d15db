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
steps, re-measured when the step size changes or the refresh policy asks;
W and d need no FMU call and follow a nonlinear joint law every iteration.
"""
from __future__ import annotations

import warnings
from collections import deque

import numpy as np
import scipy.sparse as sp
from scipy.linalg import LinAlgWarning, lu_factor, lu_solve
from scipy.sparse.linalg import splu

from master.couplings.base import Coupling, StepReport
from master.couplings.predictors import PREDICTORS
from master.couplings.refresh import REFRESH_POLICIES
from master.errors import SimulationError


#: gluing matrices of at most this many joint dofs are factored dense
DENSE_UP_TO = 64


class DenseFactor:
    """LU factors of a small dense matrix, with the ``solve`` of a sparse factor."""

    def __init__(self, matrix: np.ndarray):
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", LinAlgWarning)  # singular: said by .singular
            self.lu, self.pivots = lu_factor(matrix, check_finite=False)
        diagonal = np.abs(np.diag(self.lu))
        self.singular = bool(not np.all(np.isfinite(self.lu)) or np.any(diagonal == 0.0))

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        return lu_solve((self.lu, self.pivots), rhs, check_finite=False)


class IterativeCoupling(Coupling):
    """Newton iteration on the joint forces with step rollback."""

    name = "iterative"

    def __init__(self, backend, glued, layout, joints, settings, transfer=None):
        super().__init__(backend, glued, layout, joints, settings, transfer)
        self._history: deque = deque(maxlen=3)
        self._predict = PREDICTORS[settings.predictor]
        self._refresh_policy = REFRESH_POLICIES[settings.refresh]
        self._flexibility = None  # per glued subsystem [Gu, Gv, Ga]
        self._parts = None
        self._factor = None
        self._factored_with = None
        self._step_size = None
        self._tolerance = np.full(layout.size, settings.tolerance)
        joints.configure(layout.weights,
                         np.array([m == "displacement" for m in layout.measures], dtype=bool))

    # --- start -----------------------------------------------------------------------
    def start(self, kinematics=None, forces=None) -> None:
        """Initial joint extensions from the glued ports' kinematics at the start time;
        start forces that are known (not a guess) seed the predictor."""
        differences, _ = self.layout.differences(kinematics, magnitudes=False)
        self.joints.start(*differences)
        if forces is not None:
            self._history.append(np.array(forces, dtype=float))
        super().start(kinematics, forces)

    # --- assembly --------------------------------------------------------------------
    def residual(self, kinematics, forces, step_size):
        """Compatibility residual R (eqs. 4.13, 5.6) at ``forces``, its tolerance per
        dof, the Jacobian weights and joint diagonal, and the trial joint state."""
        relative = self.settings.relative_tolerance
        differences, magnitudes = self.layout.differences(kinematics, magnitudes=relative > 0)
        r, weights, diagonal, trial = self.joints.evaluate(forces, differences, step_size)
        tolerance = self._tolerance
        if relative > 0:
            tolerance = tolerance + relative * np.einsum("rk,kr->r", np.abs(weights),
                                                         magnitudes)
        return r, tolerance, weights, diagonal, trial

    def _factorize(self, weights, diagonal):
        if self.layout.size <= DENSE_UP_TO:
            # a few joint dofs: dense LU (scipy's sparse one costs ~100 us of set-up
            # however small the matrix, and a nonlinear joint refactors every iteration)
            jacobian = np.diag(diagonal)
            for kind, part in enumerate(self._dense_parts):
                if np.any(weights[:, kind]):
                    jacobian += weights[:, kind, None] * part
            factor = DenseFactor(jacobian)
            singular = factor.singular
        else:
            jacobian = sp.diags(diagonal)
            for kind, part in enumerate(self._parts):
                if np.any(weights[:, kind]):
                    jacobian = jacobian + sp.diags(weights[:, kind]) @ part
            try:
                factor, singular = splu(jacobian.tocsc()), False
            except RuntimeError:
                singular = True
        if singular:
            raise SimulationError(f"{self._singular_direction(jacobian)}: the gluing matrix "
                                  "is singular (a singular configuration of the mechanism, "
                                  "or a joint dof that no subsystem can move)")
        self._factor = factor
        self._factored_with = (weights, diagonal)
        self.factorizations += 1

    def _singular_direction(self, jacobian) -> str:
        """Name the joint dof that dominates the gluing matrix's null direction."""
        if self.layout.size > 2000:
            return "joints " + ", ".join(sorted(set(self.layout.joint_of)))
        dense = jacobian.toarray() if sp.issparse(jacobian) else np.array(jacobian)
        dense[~np.isfinite(dense)] = 0.0
        null = np.linalg.svd(dense)[2][-1]
        worst = int(np.argmax(np.abs(null)))
        return f"joint '{self.layout.joint_of[worst]}' ({self.layout.labels[worst]})"

    def _needs_refresh(self, iteration, history, refreshed, local) -> bool:
        """Re-measure the interface flexibility now?  Always when there is none, else
        as the refresh policy says; a refresh costs one trial per glued dof of the
        largest subsystem."""
        if self._flexibility is None:
            return True
        cost = max((len(f) for f in local), default=0)
        return self._refresh_policy(iteration, history, bool(refreshed), cost, self.settings)

    # --- the macro step --------------------------------------------------------------
    def predict(self) -> np.ndarray:
        """First guess for F from past converged forces (``settings.predictor``)."""
        return self._predict(self._history, self.layout.size)

    def _deltas(self, local_forces):
        return self.settings.perturbation * np.maximum(1.0, np.abs(local_forces))

    def _begin_step(self, step_size: float) -> None:
        """Save every glued subsystem's state; forget G when the step size changed (G
        is the response over one step)."""
        if self._step_size is not None and step_size != self._step_size:
            self._flexibility = None
        self._step_size = step_size
        self.glued.begin_step()

    def _refresh(self, local, time, step_size, kinematics) -> None:
        """Measure every glued subsystem's interface flexibility around ``local``."""
        self._use_flexibility(self._timed(
            "flexibility", self.glued.flexibility, local, time, step_size,
            [self._deltas(f) for f in local], kinematics))

    def _use_flexibility(self, flexibility) -> None:
        """Take [Gu, Gv, Ga] of every glued subsystem as the interface flexibility."""
        self._flexibility = flexibility
        self._parts = [self.layout.project([g[kind] for g in self._flexibility])
                       for kind in range(3)]
        if self.layout.size <= DENSE_UP_TO:
            self._dense_parts = [part.toarray() for part in self._parts]
        self.refreshes += 1
        self._factor = None

    def _ensure_factor(self, weights, diagonal, time: float, step_index: int) -> None:
        """Factor the gluing matrix unless the held factor has these weights."""
        if self._factor is not None:
            held_weights, held_diagonal = self._factored_with
            if (weights is held_weights or np.array_equal(weights, held_weights)) and (
                    diagonal is held_diagonal or np.array_equal(diagonal, held_diagonal)):
                return
        try:
            self._timed("factorization", self._factorize, weights, diagonal)
        except SimulationError as error:
            raise SimulationError(str(error), time=time, step=step_index) from None

    def _check_finite(self, r, time, step_index) -> None:
        if not np.all(np.isfinite(r)):
            worst = int(np.argmax(~np.isfinite(r)))
            raise SimulationError(
                f"joint '{self.layout.joint_of[worst]}' ({self.layout.labels[worst]}): "
                "residual is not finite, the iteration diverged", time=time, step=step_index)

    def _advance(self, time: float, step_size: float, step_index: int) -> StepReport:
        """Newton on the joint forces; raise SimulationError if it does not converge."""
        settings = self.settings
        forces = self.predict()
        self._begin_step(step_size)
        refreshed = 0
        history = []  # max |R| / tolerance per iteration
        for iteration in range(1, settings.max_iterations + 1):
            local = self.layout.local_forces(forces)
            kinematics = self.glued.trial_step(local, time, step_size)
            r, tolerance, weights, diagonal, trial = self.residual(kinematics, forces, step_size)
            self._check_finite(r, time + step_size, step_index)
            history.append(float(np.max(np.abs(r) / tolerance, initial=0.0)))
            if history[-1] <= 1.0:
                self.joints.accept(*trial)
                self.forces = forces
                self._history.append(forces.copy())
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
