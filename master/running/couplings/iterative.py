"""The T-T gluing algorithm (seed eqs. 4.13-4.27, 5.6-5.18, 5.28-5.29).

Unknowns per macro step: the joint forces F, one entry per glued dof.  The
subsystem glued at a dof on side b receives +F, on side a -F (eqs. 4.9/4.10:
equilibrium is built in); the residual is the compatibility of the chosen
kinematic measure (dsim.master.running.joints: fixed joints, flexible joints in force form
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
from dataclasses import replace

import numpy as np
import scipy.sparse as sp
from scipy.linalg import LinAlgWarning, get_lapack_funcs, lu_factor, lu_solve
from scipy.linalg.lapack import dgecon
from scipy.sparse.linalg import splu

from dsim.master.errors import SimulationError, StepFailure
from dsim.master.running.couplings.base import Coupling, StepReport
from dsim.master.running.couplings.convergence import CONVERGENCE_TESTS, what_is_left
from dsim.master.running.couplings.divergence import newton_diverging
from dsim.master.running.couplings.predictors import PREDICTORS
from dsim.master.running.couplings.refresh import REFRESH_POLICIES
from dsim.master.running.joints import EPS, ROUNDOFF_ULPS
from dsim.master.running.timeline import halves, same_size


#: gluing matrices of at most this many joint dofs are factored dense
DENSE_UP_TO = 64


#: reciprocal condition number (1-norm) below which a dense gluing matrix is solved in
#: the least-squares sense, its near-null directions dropped (RCOND_MIN relative to
#: its largest singular value)
RCOND_MIN = 1e-8
#: a step whose residual left along the lost directions is at most this fraction of
#: the residual it started with is accepted in the least-squares sense
LOST_SLACK = 1e-3
#: the round-off floor is looked at once Newton contracts by less than this per iteration
STALLING = 0.5


class DenseFactor:
    """LU factors of a small dense matrix, with the ``solve`` of a sparse factor, and
    its reciprocal condition number (LAPACK gecon)."""

    regularized = False

    def __init__(self, matrix: np.ndarray):
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", LinAlgWarning)  # singular: said by .singular
            self.lu, self.pivots = lu_factor(matrix, check_finite=False)
        diagonal = np.abs(np.diag(self.lu))
        self.singular = bool(not np.all(np.isfinite(self.lu)) or np.any(diagonal == 0.0))
        self.rcond = 0.0
        if not self.singular:
            self.rcond = float(dgecon(self.lu, np.linalg.norm(matrix, 1), norm="1")[0])
        # the LAPACK routine lu_solve calls, found once (lu_solve looks it up and checks
        # for batches on every call, several times the cost of the solve itself)
        self._getrs = get_lapack_funcs(("getrs",), (self.lu,))[0]

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        if (isinstance(rhs, np.ndarray) and rhs.dtype == self.lu.dtype and rhs.size
                and rhs.ndim in (1, 2) and rhs.shape[0] == self.lu.shape[0]):
            x, info = self._getrs(self.lu, self.pivots, rhs, trans=0, overwrite_b=False)
            if info == 0:
                return x
        return lu_solve((self.lu, self.pivots), rhs, check_finite=False)


class LeastSquaresFactor:
    """The minimum-norm least-squares solve of a rank-deficient (or nearly so) matrix:
    its singular directions below ``RCOND_MIN`` of the largest are dropped.  Where the
    constraint Jacobian of a mechanism loses rank (a four bar's links collinear), the
    joint forces along the lost direction do not change the compatibility: Newton
    leaves them as the predictor had them instead of dividing by a vanishing pivot."""

    regularized = True
    singular = False

    def __init__(self, matrix: np.ndarray):
        u, sigma, vt = np.linalg.svd(matrix)
        keep = sigma > RCOND_MIN * sigma[0] if sigma[0] > 0 else sigma > 0
        self.dropped = int(np.count_nonzero(~keep))
        self._left, self._sigma, self._right = u[:, keep], sigma[keep], vt[keep]

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        return self._right.T @ ((self._left.T @ rhs) / self._sigma)

    def reachable(self, residual: np.ndarray) -> np.ndarray:
        """The part of a residual that the joint forces can change (its projection on
        the kept directions); the rest lies along the lost ones."""
        return self._left @ (self._left.T @ residual)


class IterativeCoupling(Coupling):
    """Newton iteration on the joint forces with step rollback."""

    name = "iterative"
    CHECKPOINTED = ("cuts", "regularized", "least_squares_steps", "roundoff_steps",
                    "_history", "_measured", "_flexibility", "_step_size", "_factored_with",
                    "joints")
    #: how many times a failed macro step may be halved (the execution sets it to
    #: ``settings.step_cuts`` when every glued FMU accepts variable step sizes)
    cut_limit = 0

    def __init__(self, backend, glued, layout, joints, settings, transfer=None):
        super().__init__(backend, glued, layout, joints, settings, transfer)
        #: macro steps that were cut; gluing matrices solved in the least-squares sense
        self.cuts = 0
        self.regularized = 0
        #: steps accepted with a residual left along directions the forces cannot change
        self.least_squares_steps = 0
        #: steps accepted with the residual at its round-off floor, above the tolerance
        self.roundoff_steps = 0
        self._history: deque = deque(maxlen=3)
        self._measured: dict = {}  # step size -> the flexibility measured for it
        self._predict = PREDICTORS[settings.predictor]
        self._refresh_policy = REFRESH_POLICIES[settings.refresh]
        self._converged = CONVERGENCE_TESTS[settings.convergence]
        self._compliance = None  # the diagonal of the factored gluing matrix
        self._flexibility = None  # per glued subsystem [Gu, Gv, Ga]
        self._parts = None
        self._factor = None
        self._factored_with = None
        self._step_size = None
        self._tolerance = np.full(layout.size, settings.tolerance)
        joints.configure(layout.weights,
                         np.array([m == "displacement" for m in layout.measures], dtype=bool))

    def configure(self, plan, sensitivity=None) -> None:
        """A failed step may be cut where every glued FMU takes steps of any size."""
        super().configure(plan, sensitivity)
        if plan.variable_steps:
            self.cut_limit = self.settings.step_cuts

    # --- start -----------------------------------------------------------------------
    def start(self, kinematics=None, forces=None) -> None:
        """Initial joint extensions from the glued ports' kinematics at the start time;
        start forces that are known (not a guess) seed the predictor."""
        differences, _ = self.layout.differences(kinematics, magnitudes=False)
        self.joints.start(*differences)
        if forces is not None:
            self._history.append(np.array(forces, dtype=float))
        super().start(kinematics, forces)

    def counts(self) -> dict:
        return {**super().counts(), "step_cuts": self.cuts,
                "least_squares_factorizations": self.regularized,
                "least_squares_steps": self.least_squares_steps,
                "roundoff_steps": self.roundoff_steps}

    def state(self) -> dict:
        joints = self.joints
        return {**super().state(), "joints": (joints.q.copy(), joints.qd.copy(),
                                              joints.qdd.copy()),
                "history": [f.copy() for f in self._history]}

    def set_state(self, state: dict) -> None:
        super().set_state(state)
        q, qd, qdd = state["joints"]
        self.joints.q, self.joints.qd, self.joints.qdd = q.copy(), qd.copy(), qdd.copy()
        self._history = deque((f.copy() for f in state["history"]),
                              maxlen=self._history.maxlen)

    def resumed(self) -> None:
        """The interface flexibility's projections and the gluing matrix's factor made
        again from a checkpoint's flexibility and the weights it was factored with
        (the same bits as the run that wrote it; not counted again)."""
        super().resumed()
        if self._flexibility is None:
            return
        held = self._factored_with
        counts = (self.refreshes, self.factorizations, self.regularized)
        self._use_flexibility(self._flexibility, measured=False)
        if held is not None:
            self._factorize(*held)
        self.refreshes, self.factorizations, self.regularized = counts

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
            compliance = np.diag(jacobian).copy()
            factor = DenseFactor(jacobian)
            if factor.rcond < RCOND_MIN and np.all(np.isfinite(jacobian)):
                factor = LeastSquaresFactor(jacobian)
                self.regularized += 1
            singular = factor.singular
        else:
            jacobian = sp.diags(diagonal)
            for kind, part in enumerate(self._parts):
                if np.any(weights[:, kind]):
                    jacobian = jacobian + sp.diags(weights[:, kind]) @ part
            compliance = jacobian.diagonal()
            try:
                factor, singular = splu(jacobian.tocsc()), False
            except RuntimeError:
                singular = True
        if singular:
            raise SimulationError(f"{self._singular_direction(jacobian)}: the gluing matrix "
                                  "is singular (a singular configuration of the mechanism, "
                                  "or a joint dof that no subsystem can move)")
        self._factor = factor
        self._compliance = compliance
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

    def _begin_step(self, step_size: float, save: bool = True) -> None:
        """Save every glued subsystem's state (unless ``save`` is False: a cut step's
        first half starts from the state its whole step saved); when the step size
        changed, take the flexibility measured for the new one, if any (G is the
        response over one step)."""
        # a size that differs by round-off only (a last step fitted to the stop time)
        # has the same response
        if self._step_size is not None and not same_size(step_size, self._step_size):
            self._measured[self._step_size] = self._flexibility
            held = self._measured.get(step_size)
            self._flexibility = None
            if held is not None:
                self._use_flexibility(held, measured=False)
        self._step_size = step_size
        if save:
            self.glued.begin_step()

    def _refresh(self, local, time, step_size, kinematics) -> None:
        """Measure every glued subsystem's interface flexibility around ``local``."""
        self._use_flexibility(self._timed(
            "flexibility", self.glued.flexibility, local, time, step_size,
            [self._deltas(f) for f in local], kinematics))

    def _use_flexibility(self, flexibility, measured: bool = True) -> None:
        """Take [Gu, Gv, Ga] of every glued subsystem as the interface flexibility
        (``measured``: just measured, counted as a refresh)."""
        self._flexibility = flexibility
        self._parts = [self.layout.project([g[kind] for g in self._flexibility])
                       for kind in range(3)]
        if self.layout.size <= DENSE_UP_TO:
            self._dense_parts = [part.toarray() for part in self._parts]
        self.refreshes += int(measured)
        self._factor = self._factored_with = None

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

    def _check_finite(self, r, time, step_index, iterations: int = 0) -> None:
        if not np.all(np.isfinite(r)):
            worst = int(np.argmax(~np.isfinite(r)))
            raise StepFailure(
                f"joint '{self.layout.joint_of[worst]}' ({self.layout.labels[worst]}): "
                "residual is not finite, the iteration diverged", time=time, step=step_index,
                iterations=iterations)

    def _advance(self, time: float, step_size: float, step_index: int) -> StepReport:
        """Newton on the joint forces; a step that fails is cut in halves (at most
        ``cut_limit`` times) before the run fails."""
        try:
            report = self._cut_or_fail(time, step_size, step_index, 0, True)
        except StepFailure as failure:
            part = getattr(failure, "part", None)
            if part is None:
                raise
            raise StepFailure(f"{failure.message} (the step was cut: a part of {part:g} s "
                              f"from t = {failure.part_start:.9g} s failed too)",
                              time + step_size, step_index, failure.iterations) from None
        if report.cuts:  # the predictor extrapolates over whole steps: start it afresh
            self._history.clear()
            self._history.append(self.forces.copy())
        return report

    def _cut_or_fail(self, time, step_size, step_index, depth, save) -> StepReport:
        """One Newton solve over ``step_size``; if it fails and a cut is left, the two
        halves in turn (each may be cut again)."""
        try:
            return self._newton(time, step_size, step_index, save)
        except StepFailure as failure:
            if depth and not hasattr(failure, "part"):  # where a cut part failed
                failure.part, failure.part_start = step_size, time
            if depth >= self.cut_limit:
                raise
            spent = failure.iterations
        self.cuts += depth == 0
        (start, half), (middle, rest) = halves(time, step_size)  # never past the step's end
        first = self._cut_or_fail(start, half, step_index, depth + 1, False)
        second = self._cut_or_fail(middle, rest, step_index, depth + 1, True)
        both = StepReport.of_parts((first, second))
        return replace(both, iterations=spent + both.iterations,
                       cuts=max(both.cuts, depth + 1))

    def _lost_residual(self, r, tolerance, first: float) -> float:
        """Where the gluing matrix has lost rank (solved in the least-squares sense):
        the residual left along the lost directions when the rest is within the
        tolerance and it is small against the step's first residual (a mechanism at
        its singular configuration: no joint force changes it there, and the joints'
        own stabilisation takes it back on the next steps), else 0."""
        factor = self._factor
        if not getattr(factor, "regularized", False):  # LU factors: full rank
            return 0.0
        reachable = factor.reachable(r)
        lost = float(np.max(np.abs(r - reachable), initial=0.0))
        if np.all(np.abs(reachable) <= tolerance) and lost <= LOST_SLACK * first:
            return lost
        return 0.0

    def _roundoff_floor(self, kinematics, forces, weights, step_size) -> np.ndarray:
        """Per joint dof, the round-off floor of its residual (the residual's units):
        ``ROUNDOFF_ULPS`` ulps of the terms it is the difference of, the ports'
        kinematics weighted as the row weighs them and, in force form, the force over
        the joint's reference stiffness.  A residual there cannot be made smaller by any
        joint force, whatever tolerance was asked."""
        _, magnitudes = self.layout.differences(kinematics, magnitudes=True)
        terms = np.einsum("rk,kr->r", np.abs(weights), magnitudes)
        law = self.joints.force_form
        if law.any():
            terms = terms + np.where(
                law, np.abs(forces) / self.joints.reference_stiffness(step_size), 0.0)
        return ROUNDOFF_ULPS * EPS * terms

    def _at_floor(self, r, residual, tolerance, kinematics, forces, weights,
                  step_size) -> bool:
        """Whether a stalled step's residual can get no smaller: above the tolerance, each
        dof within its round-off floor or tolerance; within the tolerance (the forces test
        is what stalled), each dof at its round-off floor, so that the correction still
        to come is round-off amplified by a near-singular gluing matrix, not a force error
        a fresher Lambda would remove."""
        floor = self._roundoff_floor(kinematics, forces, weights, step_size)
        if residual > 1.0:
            floor = np.maximum(tolerance, floor)
        return bool(np.all(np.abs(r) <= floor))

    def _newton(self, time, step_size, step_index, save: bool = True) -> StepReport:
        """Newton on the joint forces over one step; StepFailure if it does not
        converge (iteration limit, non-finite or diverging residual)."""
        settings = self.settings
        forces = self.predict()
        self._begin_step(step_size, save)
        refreshed = 0
        history = []  # max |R| / tolerance per iteration (the convergence test's measure)
        end = time + step_size
        for iteration in range(1, settings.max_iterations + 1):
            local = self.layout.local_forces(forces)
            kinematics = self.glued.trial_step(local, time, step_size)
            r, tolerance, weights, diagonal, trial = self.residual(kinematics, forces, step_size)
            self._check_finite(r, end, step_index, iteration)
            residual = float(np.max(np.abs(r) / tolerance, initial=0.0))
            # the convergence test's measure: the residual's, or more (convergence.py)
            history.append(self._converged(r, tolerance, self._factor, self._compliance))
            if iteration == 1:
                first = float(np.max(np.abs(r), initial=0.0))
            lost = self._lost_residual(r, tolerance, first) if residual > 1.0 else 0.0
            floor = (iteration > 1 and history[-1] > 1.0 and not lost
                     and history[-1] > STALLING * history[-2]
                     and self._at_floor(r, residual, tolerance, kinematics, forces, weights,
                                        step_size))
            if history[-1] <= 1.0 or lost or floor:
                self.least_squares_steps += lost > 0
                self.roundoff_steps += bool(floor)
                self.joints.accept(*trial)
                self.forces = forces
                self._history.append(forces.copy())
                return StepReport(iteration, refreshed, float(np.max(np.abs(r), initial=0.0)),
                                  lost=lost)
            if newton_diverging(history, refreshed):
                worst = int(np.argmax(np.abs(r) / tolerance))
                raise StepFailure(
                    f"joint '{self.layout.joint_of[worst]}' ({self.layout.labels[worst]}): "
                    f"Newton diverged, the residual grew to {history[-1]:.3e} times the "
                    f"tolerance from {min(history):.3e} in {iteration} iterations",
                    time=end, step=step_index, iterations=iteration)
            if self._needs_refresh(iteration, history, refreshed, local):
                self._refresh(local, time, step_size, kinematics)
                refreshed += 1
            self._ensure_factor(weights, diagonal, end, step_index)
            forces = forces - self._factor.solve(r)
        worst, what = what_is_left(r, tolerance, self._factor, self._compliance)
        raise StepFailure(
            f"joint '{self.layout.joint_of[worst]}' ({self.layout.labels[worst]}) did not "
            f"converge in {settings.max_iterations} iterations: {what}{self._ill_posed()}",
            time=end, step=step_index, iterations=settings.max_iterations)

    def _ill_posed(self) -> str:
        """What to add to a failure's message when the gluing matrix was near-singular:
        the step is ill-posed there (a singular configuration), not merely slow."""
        factor = self._factor
        if getattr(factor, "regularized", False) or getattr(factor, "rcond", 1.0) < RCOND_MIN:
            return ("; the gluing matrix is near-singular: a singular configuration of the "
                    "mechanism makes this step ill-posed")
        return ""
