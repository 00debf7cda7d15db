"""The explicit (non-iterative) coupling: the baseline that iteration is measured against.

Every macro step takes one trial per subsystem with the predicted joint forces
and accepts it, compatible or not; the Newton correction that step's residual
asks for, F - Lambda R, is not applied to the step but fed to the predictor of
the next one.  It costs one doStep per FMU per step (the iterative master takes
two on linear problems) and leaves the interface incompatible by what the
predictor misses.  Lambda is measured once, at the first step, by the same
perturbation and rollback as the iterative master's.
"""
from __future__ import annotations

import numpy as np

from master.errors import SimulationError
from master.gluing import StepReport, TTGluing


class ExplicitGluing(TTGluing):
    """One trial per macro step; the correction goes to the next step's predictor."""

    def step(self, time: float, step_size: float, step_index: int) -> StepReport:
        """Advance every subsystem once with predicted forces (no rollback after the
        first step); record the residual left at the interface."""
        forces = self.predict()
        self._begin_step(step_size)
        local = self.layout.local_forces(forces)
        kinematics = self.backend.trial_step(local, time, step_size)
        r, _, weights, diagonal, trial = self.residual(kinematics, forces, step_size)
        if not np.all(np.isfinite(r)):
            raise SimulationError("the explicit coupling diverged (non-finite interface "
                                  "residual): use a smaller step or the iterative coupling",
                                  time=time + step_size, step=step_index)
        refreshed = 0
        if self._flexibility is None:
            self._refresh(local, time, step_size, kinematics)
            refreshed = 1
            # the perturbations moved the subsystems: step once more with the forces
            # this step is accepted with, so that the state matches the record
            self.backend.trial_step(local, time, step_size)
        self._ensure_factor(weights, diagonal, time + step_size, step_index)
        self.joints.accept(*trial)
        self.forces = forces
        self._history.append(forces - self._factor.solve(r))
        self.iterations += 1
        self.step_count += 1
        return StepReport(1, refreshed, float(np.max(np.abs(r), initial=0.0)))
