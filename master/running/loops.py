"""Solving the scene's algebraic loops at a communication point.

After the subsystems have stepped, the outputs on a loop of direct feedthrough
(:mod:`dsim.master.planning.loops`) depend on the inputs the loop feeds back.  The
loop's inputs u are solved for R(u) = u - T(y(u)) = 0 by Newton, each evaluation a
write of the inputs and a read of the outputs (no step: FMI lets a master read the
outputs an input feeds directly after setting it), the Jacobian by perturbation,
measured once per solve (a loop of linear blocks converges in one correction).  A
loop that does not converge in ``max_iterations`` fails the step with one line
naming it.
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

    def solve(self, backend, outputs: np.ndarray, time: float) -> list[np.ndarray] | None:
        """Solve every loop at ``time`` from the flat ``outputs``; each subsystem's
        outputs after it (None: nothing moved)."""
        parts = None
        for loop, where in zip(self.loops, self.positions):
            moved = self._solve_one(backend, outputs, where, loop, time)
            if moved is not None:
                parts = moved
                outputs = np.concatenate(parts)
        return parts

    def _residual(self, backend, values, where, u):
        values = values.copy()
        values[where] = u
        backend.write_inputs(self.transfer.split(values))
        parts = backend.read_outputs()
        return u - self.transfer.values(np.concatenate(parts))[where], parts

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
