"""Solving the scene's algebraic loops at a communication point.

After the subsystems have stepped, the outputs on a loop of direct feedthrough
(:mod:`dsim.master.planning.loops`) depend on the inputs the loop feeds back.  The
loop's inputs u are solved for R(u) = u - T(y(u)) = 0 by Newton, each evaluation a
write of the inputs and a read of the outputs (no step: FMI lets a master read the
outputs an input feeds directly after setting it), the Jacobian by perturbation.  The
Jacobian is measured at the first correction of a solve (a loop of linear blocks then
converges in one correction) and again whenever the residual stops falling fast: when
it grows, or when its last contraction predicts more iterations to the tolerance than
a new Jacobian costs (one evaluation per input), as the joints' Newton re-measures its
flexibility (:mod:`dsim.master.running.couplings.refresh`).  A correction that does not
reduce the residual is halved until it does (backtracking, at most
:data:`BACKTRACKS` times).  A loop that does not converge in ``max_iterations``
corrections fails the step with one line naming it.

A loop is found from what the FMUs declare, and an FMU that declares no output
dependencies counts as depending on every input.  At the first communication point
each loop is probed: when no output on it moves, bit for bit, as its inputs are
perturbed (a first-order lag that declares nothing; a co-simulation FMU that computes
its outputs only in its step), nothing can be solved there, and the loop is passed on
once per step as before, at no cost per step (the run says so once; the strong
coupling iterates such a loop with rollback instead).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.linalg import lu_factor, lu_solve

from dsim.master.errors import SimulationError

#: halvings of a correction that does not reduce the residual before it is taken as is
BACKTRACKS = 8
#: the sufficient decrease a (damped) correction must make: |R| falls below
#: (1 - DECREASE * its fraction of the full correction) |R| (Armijo's condition)
DECREASE = 1e-4


class LoopSolver:
    """Solves every loop of a plan (``loops``, ``positions`` in ``transfer``'s flat
    values) over a backend."""

    #: what a checkpoint keeps (:mod:`dsim.master.running.checkpointing`)
    CHECKPOINTED = ("solves", "corrections", "jacobians", "damped", "evaluations", "active",
                    "notes")

    def __init__(self, transfer, loops, positions, settings):
        self.transfer = transfer
        self.loops = loops
        self.positions = [np.array(p, dtype=int) for p in positions]
        self.settings = settings
        #: loop solves that needed at least one Newton correction, the corrections,
        #: the Jacobians measured, the corrections damped (halved at least once) and
        #: the residual evaluations (each a write of the inputs and a read of outputs)
        self.solves = 0
        self.corrections = 0
        self.jacobians = 0
        self.damped = 0
        self.evaluations = 0
        #: which loops are solved (a probe at the first point may find one that
        #: cannot be), and what the run should say about those that are not
        self.active = [None] * len(loops)
        self.notes: list[str] = []

    def solve(self, backend, outputs: np.ndarray, time: float) -> list[np.ndarray] | None:
        """Solve every loop at ``time`` from the flat ``outputs``; each subsystem's
        outputs after it (None: nothing moved)."""
        parts = None
        for number, (loop, where) in enumerate(zip(self.loops, self.positions)):
            if self.active[number] is None:
                self.active[number] = self._responds(backend, outputs, where)
                if not self.active[number]:
                    self.notes.append(
                        f"algebraic loop {loop.label}: its outputs do not move when its "
                        "inputs do between steps (the FMUs declare no output dependencies, "
                        "or compute outputs only in their step): passed on once per step")
            if not self.active[number]:
                continue
            moved = self._solve_one(backend, outputs, where, loop, time)
            if moved is not None:
                parts = moved
                outputs = np.concatenate(parts)
        return parts

    def _responds(self, backend, outputs, where) -> bool:
        """Whether any input of the loop moves an output on it (perturbation probe
        at the current point; the inputs are left as the connections give them)."""
        values = self.transfer.values(outputs)
        u = values[where].copy()
        base, _ = self._fed_back(backend, values, where, u)
        responds = False
        for k in range(len(u)):
            probe = u.copy()
            probe[k] += self.settings.perturbation * max(1.0, abs(u[k]))
            responds = responds or bool(np.any(
                self._fed_back(backend, values, where, probe)[0] != base))
        self._fed_back(backend, values, where, u)
        return responds

    def _fed_back(self, backend, values, where, u):
        """T(y(u)): the loop's inputs as the connections give them after its inputs
        are set to ``u``; and each subsystem's outputs."""
        values = values.copy()
        values[where] = u
        backend.write_inputs(self.transfer.split(values))
        parts = backend.read_outputs()
        return self.transfer.values(np.concatenate(parts))[where], parts

    def _residual(self, backend, values, where, u):
        """R(u) = u - T(y(u)) and each subsystem's outputs (one evaluation)."""
        self.evaluations += 1
        fed, parts = self._fed_back(backend, values, where, u)
        return u - fed, parts

    def counts(self) -> dict:
        """What the solver counted over the run, by the statistics' names."""
        return {"solves": self.solves, "corrections": self.corrections,
                "jacobians": self.jacobians, "damped_corrections": self.damped,
                "evaluations": self.evaluations}

    def _jacobian(self, backend, values, where, u, residual):
        """dR/du at ``u`` by forward differences (one evaluation per input), LU
        factored."""
        jacobian = np.zeros((len(u), len(u)))
        for k in range(len(u)):
            delta = self.settings.perturbation * max(1.0, abs(u[k]))
            probe = u.copy()
            probe[k] += delta
            jacobian[:, k] = (self._residual(backend, values, where, probe)[0]
                              - residual) / delta
        self.jacobians += 1
        return lu_factor(jacobian, check_finite=False)

    def _damped(self, backend, values, where, u, residual, step, limit):
        """The correction u - s step with the largest s of 1, 1/2, 1/4 ... that
        reduces the residual (its 2-norm in tolerances ``limit``) sufficiently; the
        smallest tried when none does.  Returns u, R(u), the outputs and whether the
        correction reduced the residual."""
        size = np.linalg.norm(residual / limit)
        fraction = 1.0
        for halving in range(BACKTRACKS + 1):
            trial = u - fraction * step
            trial_residual, parts = self._residual(backend, values, where, trial)
            if np.linalg.norm(trial_residual / limit) <= (1 - DECREASE * fraction) * size:
                self.damped += int(halving > 0)
                return trial, trial_residual, parts, True
            fraction /= 2
        self.damped += 1
        return trial, trial_residual, parts, False

    def _solve_one(self, backend, outputs, where, loop, time):
        """Newton on one loop (``where``: its inputs' positions) from the values the
        connections give at ``time``; each subsystem's outputs at the solution.
        Raises SimulationError when it does not converge."""
        settings = self.settings
        values = self.transfer.values(outputs)
        u = values[where].copy()
        residual, parts = self._residual(backend, values, where, u)
        factor, history, reduced = None, [], True
        for _ in range(settings.max_iterations):
            limit = settings.tolerance + settings.relative_tolerance * np.abs(u)
            history.append(float(np.max(np.abs(residual) / limit)))
            if history[-1] <= 1.0:
                return parts
            if factor is None or not reduced or stale(history, len(u)):
                factor = self._jacobian(backend, values, where, u, residual)
            self.solves += int(len(history) == 1)
            step = lu_solve(factor, residual, check_finite=False)
            u, residual, parts, reduced = self._damped(backend, values, where, u,
                                                       residual, step, limit)
            self.corrections += 1
        raise SimulationError(f"algebraic loop {loop.label} did not converge in "
                              f"{settings.max_iterations} iterations at t = {time:g} s "
                              f"(largest residual {np.max(np.abs(residual)):.3g})", time=time)


def stale(history, size: int) -> bool:
    """Whether a loop's held Jacobian should be measured again, from ``history`` (the
    largest residual in tolerances after each correction so far): the residual stopped
    falling fast, that is it grew, or its last contraction predicts more iterations to
    the tolerance than a new Jacobian costs (``size`` evaluations, one per input)."""
    if len(history) < 2:
        return False
    rate = history[-1] / history[-2]
    if rate >= 1.0:
        return True
    return math.log(history[-1]) / -math.log(max(rate, 1e-300)) > size
