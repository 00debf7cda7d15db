"""Connections coupled as strongly as joints: the values that SSP connections carry
between FMUs that can roll back are iterated to convergence at every macro step.

The once-per-step exchange (the causal coupling) hands each FMU its inputs as the
sources had them at the step's start and holds them over the step: two FMUs that
pass position one way and force the other then carry an O(h) coupling error that
no tolerance removes.  Here the unknowns are the connected inputs at the step's
end, u; one trial steps every iterated FMU from its saved state with its inputs
moving linearly from their values at the step's start to u (a Model Exchange FMU:
dsim's integrator takes the ramp; a co-simulation FMU that can interpolate inputs:
``SetRealInputDerivatives``; any other: u held over the step), and the residual is

    R(u) = u - T(y(u))

with y the outputs at the step's end and T the connections (gather, units, linear
transformations).  Newton on R, with the Jacobian I - T' dy/du measured by
perturbation and rollback (one extra trial per connected input: the same machinery
as a joint's flexibility), kept across steps and measured anew when the step size
changes or convergence slows (``refresh_after`` iterations).  The step is accepted
when every |R_k| <= tolerance + relative_tolerance |u_k|.

FMUs that cannot roll back (FMI 1.0, no FMU state) take one step per macro step,
first, with their inputs from the outputs at the step's start; their outputs at the
step's end then feed the iterated FMUs as known values.  A scene with joints is the
iterative coupling's (it glues joints; this coupling iterates connections only).
"""
from __future__ import annotations

import numpy as np
from scipy.linalg import lu_factor, lu_solve

from dsim.master.errors import SimulationError
from dsim.master.running.couplings.base import Coupling, StepReport


class StrongCoupling(Coupling):
    """Newton iteration on the connected inputs of the FMUs that can roll back."""

    name = "strong"

    def __init__(self, backend, glued, layout, joints, settings, transfer=None):
        super().__init__(backend, glued, layout, joints, settings, transfer)
        self.cuts = 0
        self.least_squares_steps = 0
        self.roundoff_steps = 0
        self._jacobian = None
        self._measured_for = None
        self._previous = None  # u of the last accepted step (for the predictor)

    # --- the flat vector of the iterated group's connected inputs ---------------------
    def _split(self, values: np.ndarray) -> list[tuple[int, np.ndarray]]:
        return [(index, values[start:stop]) for index, start, stop in
                self._glued_inputs.targets]

    def _group_inputs(self, outputs: np.ndarray) -> np.ndarray:
        """T(y): the iterated group's inputs from a flat output vector."""
        parts = self._glued_inputs.inputs(outputs)
        return np.concatenate([values for _, values in parts]) if parts else np.zeros(0)

    def _trial(self, time, step_size, start, end) -> np.ndarray:
        """Every iterated FMU stepped from its saved state with inputs ramping from
        ``start`` to ``end``; the flat output vector at the step's end."""
        starts, ends = dict(self._split(start)), dict(self._split(end))
        ramps = [(starts.get(i), ends.get(i)) for i in range(len(self.glued))]
        self._assemble(0, self.glued.trial_exchange(time, step_size, ramps))
        return np.concatenate(self._outputs_by_subsystem)

    def _residual(self, time, step_size, start, u) -> np.ndarray:
        return u - self._group_inputs(self._trial(time, step_size, start, u))

    def _measure(self, time, step_size, start, u, base: np.ndarray) -> None:
        """J = dR/du by perturbing one connected input at a time (rollback each
        time; only its own FMU's outputs move, but every FMU is stepped so that
        all end where the next trial starts)."""
        n = len(u)
        jacobian = np.zeros((n, n))
        for k in range(n):
            delta = self.settings.perturbation * max(1.0, abs(u[k]))
            probe = u.copy()
            probe[k] += delta
            jacobian[:, k] = (self._residual(time, step_size, start, probe) - base) / delta
        self._jacobian = lu_factor(jacobian, check_finite=False)
        self._measured_for = step_size
        self.refreshes += 1
        self.factorizations += 1

    def step(self, time: float, step_size: float, step_index: int) -> StepReport:
        glued, free = self._order
        outputs_now = self.outputs
        if free:  # what cannot roll back: one step, inputs from the step's start
            inputs = self._free_inputs.inputs(outputs_now) if self._free_inputs.size else ()
            self._assemble(1, self.free.step(time, step_size, inputs))
        if not glued:
            self.outputs = np.concatenate(self._outputs_by_subsystem)
            return StepReport(0, 0, 0.0)
        start = self._group_inputs(outputs_now)
        # the outputs of the FMUs that stepped already are their values at the step's
        # end; the iterated ones' are replaced by each trial
        u = start.copy() if self._previous is None or self.settings.predictor == "none" \
            else start + (start - self._previous) if self.settings.predictor != "constant" \
            else start.copy()
        self.glued.begin_step()
        refreshed = 0
        residual = self._residual(time, step_size, start, u)
        iterations = 1
        limit = self.settings.tolerance + self.settings.relative_tolerance * np.abs(u)
        while np.any(np.abs(residual) > limit):
            if iterations >= self.settings.max_iterations:
                worst = int(np.argmax(np.abs(residual) - limit))
                raise SimulationError(
                    f"connections did not converge in {iterations} iterations at "
                    f"t = {time + step_size:g} s: input {self._label(worst)} is "
                    f"{abs(residual[worst]):.3g} from its source's value (tolerance "
                    f"{limit[worst]:.3g})", time=time + step_size)
            if self._jacobian is None or self._measured_for != step_size or (
                    iterations % self.settings.refresh_after == 0):
                self._measure(time, step_size, start, u, residual)
                refreshed += 1
            u = u - lu_solve(self._jacobian, residual, check_finite=False)
            residual = self._residual(time, step_size, start, u)
            iterations += 1
            limit = self.settings.tolerance + self.settings.relative_tolerance * np.abs(u)
        self._previous = start
        self.outputs = np.concatenate(self._outputs_by_subsystem)
        return StepReport(iterations, refreshed, float(np.max(np.abs(residual), initial=0.0)))

    def _label(self, position: int) -> str:
        """'component.variable' of the connected input at ``position``."""
        return self.labels[position] if position < len(self.labels) else f"#{position}"

    #: the iterated inputs' names (component.variable), set by the execution
    labels: tuple = ()

    def _advance(self, time, step_size, step_index) -> StepReport:  # pragma: no cover
        raise NotImplementedError("the strong coupling overrides step")
