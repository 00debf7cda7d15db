"""Solving the scene's algebraic loops at a communication point.

After the subsystems have stepped, the outputs on a loop of direct feedthrough
(:mod:`dsim.master.planning.loops`) depend on the inputs the loop feeds back.  The
loop's inputs u are solved for R(u) = u - T(y(u)) = 0 by Newton, each evaluation a
write of the inputs and a read of the outputs (no step: FMI lets a master read the
outputs an input feeds directly after setting it), the Jacobian by perturbation,
measured once per solve (a loop of linear blocks converges in one correction).  A
loop that does not converge in ``max_iterations`` fails the step with one line
naming it.

A loop is found from what the FMUs declare, and an FMU that declares no output
dependencies counts as depending on every input.  At the first communication point
each loop is probed: when no output on it moves, bit for bit, as its inputs are
perturbed (a first-order lag that declares nothing; a co-simulation FMU that computes
its outputs only in its step), nothing can be solved there, and the loop is passed on
once per step as before, at no cost per step (the run says so once; the strong
coupling iterates such a loop with rollback instead).
"""
from __future__ import annotations

import numpy as np
from scipy.linalg import lu_factor, lu_solve

from dsim.master.errors import SimulationError


class LoopSolver:
    """Solves every loop of a plan (``loops``, ``positions`` in ``transfer``'s flat
    values) over a backend."""

    def __init__(self, transfer, loops, positions, settings):
        self.transfer = transfer
        self.loops = loops
        self.positions = [np.array(p, dtype=int) for p in positions]
        self.settings = settings
        #: loop solves that needed at least one Newton correction, and the corrections
        self.solves = 0
        self.corrections = 0
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
        fed, parts = self._fed_back(backend, values, where, u)
        return u - fed, parts

    def _solve_one(self, backend, outputs, where, loop, time):
        settings = self.settings
        values = self.transfer.values(outputs)
        u = values[where].copy()
        residual, parts = self._residual(backend, values, where, u)
        factor = None
        for _ in range(settings.max_iterations):
            limit = settings.tolerance + settings.relative_tolerance * np.abs(u)
            if np.all(np.abs(residual) <= limit):
                return parts
            if factor is None:
                jacobian = np.zeros((len(u), len(u)))
                for k in range(len(u)):
                    delta = settings.perturbation * max(1.0, abs(u[k]))
                    probe = u.copy()
                    probe[k] += delta
                    jacobian[:, k] = (self._residual(backend, values, where, probe)[0]
                                      - residual) / delta
                factor = lu_factor(jacobian, check_finite=False)
                self.solves += 1
            u = u - lu_solve(factor, residual, check_finite=False)
            self.corrections += 1
            residual, parts = self._residual(backend, values, where, u)
        raise SimulationError(f"algebraic loop {loop.label} did not converge in "
                              f"{settings.max_iterations} iterations at t = {time:g} s "
                              f"(largest residual {np.max(np.abs(residual)):.3g})", time=time)
