"""A repeated step of a linear body, as a master's Newton iteration makes it.

A gluing master restores a body to the state at the start of a macro step and steps it
again with other interface forces F (the correction, the flexibility perturbations).
Newmark's step is linear in the forces, so from the same start state and step size the
new end state is the last one plus the response to the force change:

    q2 = q1 + Z (F2 - F1),   v2 = v1 + (2/h) Z dF,   a2 = a1 + (4/h^2) Z dF,

with Z = K_eff^-1 B^T (generalized coordinates x interface dofs), one dense product
instead of a sparse solve and the right-hand side.  Z costs one solve per interface dof,
so it is built only once a step size has seen as many repeated steps as it has columns
(a run with a steady step; never for a step size met once), and only while it is small
(:data:`MAX_ENTRIES`).  The result equals the full step to round-off; a repeat with the
same forces gives the remembered end state bit for bit.
"""
from __future__ import annotations

import numpy as np

try:  # what np.einsum calls (optimize off), without its argument handling in Python
    from numpy._core.multiarray import c_einsum as _einsum
except ImportError:  # another numpy layout: the public function, the same result
    _einsum = np.einsum

#: the largest Z kept (entries, 8 bytes each: 8 MB): larger bodies always take the full solve
MAX_ENTRIES = 1_000_000


class RepeatedStep:
    """Remembers a body's first Newmark step from a start state (start, step size,
    interface forces, end state) and answers a repeat of it with other forces."""

    def __init__(self, integrator, interface_map):
        self.integrator = integrator
        self.interface_map = interface_map
        self._last = None
        self._response = None  # (step size, Z^T: one row per interface dof)
        self._counted, self._repeats = None, 0  # repeats seen at a step size without Z

    def step(self, time: float, step_size: float, start: tuple, forces: np.ndarray,
             full_step) -> tuple:
        """(q, v, a) at time + step_size from ``start`` (q, v, a at ``time``) under
        interface ``forces`` (N): by the remembered step's response when this repeats
        it and Z is built, else ``full_step()``.  Only a first step from a start is
        remembered, so a repeat with its forces gives its end state bit for bit."""
        repeating = self._last is not None and self._same_start(time, step_size, start)
        if repeating:
            h = self._last[1]
            response = self._response_for(h)
            if response is not None:
                q1, v1, a1 = self._last[4]
                change = forces - self._last[3]
                # einsum's own loop, not BLAS: a threaded BLAS may sum in another order
                # in another process, and a run must give the same bits wherever its
                # FMUs live
                dq = _einsum("ji,j->i", response, change)
                return q1 + dq, v1 + (2.0 / h) * dq, a1 + (4.0 / h ** 2) * dq
        end = full_step()
        if not repeating:
            self._last = (time, self.integrator.step_size, start, forces.copy(), end)
        return end

    def snapshot(self) -> dict:
        """What decides this object's next answers (references, no copies): the
        remembered step, the repeats counted and the step size of Z (Z itself is
        built again from it, to the same bits)."""
        return {"last": self._last, "counted": self._counted, "repeats": self._repeats,
                "response": None if self._response is None else self._response[0]}

    def resume(self, snapshot: dict) -> None:
        """Take over a :meth:`snapshot` of the same body's object in another process."""
        self._last, self._counted = snapshot["last"], snapshot["counted"]
        self._repeats = snapshot["repeats"]
        self._response = None
        if snapshot["response"] is not None:
            self._build(snapshot["response"])

    def _same_start(self, time: float, step_size: float, start: tuple) -> bool:
        last_time, h, last_start, _, _ = self._last
        return (time == last_time and self.integrator.same_step(step_size, h)
                and all(x is y or (x.shape == y.shape and bool((x == y).all()))
                        for x, y in zip(start, last_start)))  # np.array_equal, less dispatch

    def _response_for(self, h: float):
        """Z^T for step size ``h`` (single-vector solves, as a step's: the same bits in
        any process), built on the repeat that makes its cost worth it."""
        if self._response is not None and self._response[0] == h:
            return self._response[1]
        n, m = self.integrator.stiffness.shape[0], self.interface_map.rows
        if m == 0 or n * m > MAX_ENTRIES:
            return None
        if self._counted != h:
            self._counted, self._repeats = h, 0
        self._repeats += 1
        if self._repeats < m:
            return None
        return self._build(h)

    def _build(self, h: float):
        """Z^T for step size ``h``, kept."""
        self.integrator.factor(h)
        columns = self.interface_map.transpose.toarray().T  # one per interface dof
        z = np.array([self.integrator.solve(column) for column in columns])  # Z^T, m x n
        self._response = (h, z)
        return z
