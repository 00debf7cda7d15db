"""The explicit (non-iterative) coupling: the baseline that iteration is measured against.

Every macro step takes one trial per glued subsystem with the predicted joint
forces and accepts it, compatible or not; the Newton correction that step's
residual asks for, F - Lambda R, is not applied to the step but fed to the
predictor of the next one.  It costs one doStep per FMU per step (the iterative
master takes two on linear problems) and leaves the interface incompatible by
what the predictor misses.  Lambda is measured at the first step (and again when
the step size changes) by the same perturbation and rollback as the iterative
master's: only those steps save and restore state.
"""
from __future__ import annotations

import numpy as np

from dsim.master.errors import SimulationError
from dsim.master.running.couplings.base import StepReport
from dsim.master.running.couplings.divergence import BLOCKS, GROWTH, EnvelopeWatch
from dsim.master.running.couplings.iterative import IterativeCoupling
from dsim.master.running.timeline import same_size


class ExplicitCoupling(IterativeCoupling):
    """One trial per macro step; the correction goes to the next step's predictor."""

    name = "explicit"
    CHECKPOINTED = ("_envelope",)
    #: d a / d f of every glued subsystem at the start time, when some cannot save
    #: their state: the flexibility then comes from it, with no rollback ever
    start_sensitivity = None

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._envelope = EnvelopeWatch()

    def configure(self, plan, sensitivity=None) -> None:
        """The start sensitivity, where a glued FMU cannot save its state."""
        super().configure(plan, sensitivity)
        if sensitivity is not None:
            self.start_sensitivity = sensitivity

    def _advance(self, time: float, step_size: float, step_index: int) -> StepReport:
        """Advance every glued subsystem once with predicted forces; record the
        residual left at the interface."""
        forces = self.predict()
        # a size that differs by round-off only (a last step fitted to the stop time)
        # keeps the flexibility
        if self._step_size is not None and not same_size(step_size, self._step_size):
            self._flexibility = None
        self._step_size = step_size
        if self._flexibility is None and self.start_sensitivity is not None:
            # a force held over a step moves the end of the step as the trapezoidal rule
            # says: u by h^2/4 a, v by h/2 a (exact as h -> 0)
            h = step_size
            self._use_flexibility([[h * h / 4.0 * a, h / 2.0 * a, a]
                                   for a in self.start_sensitivity])
            self.refreshes += 1
        measuring = self._flexibility is None
        if measuring:  # the perturbations roll back: save the step's start
            self.glued.begin_step()
        local = self.layout.local_forces(forces)
        if measuring:
            kinematics = self.glued.trial_step(local, time, step_size)
        else:
            kinematics = self.glued.advance(local, time, step_size)
        r, _, weights, diagonal, trial = self.residual(kinematics, forces, step_size)
        try:
            self._check_finite(r, time + step_size, step_index)
        except SimulationError:
            raise SimulationError("the explicit coupling diverged (non-finite interface "
                                  "residual): use a smaller step or the iterative coupling",
                                  time=time + step_size, step=step_index) from None
        residual = float(np.max(np.abs(r), initial=0.0))
        growth = self._envelope.add(residual)
        if growth is not None:
            worst = int(np.argmax(np.abs(r)))
            raise SimulationError(
                f"the explicit coupling diverged: the interface residual grew more than "
                f"{GROWTH:g}x in each of the last {BLOCKS} blocks of {self._envelope.block} "
                f"steps ({growth:.3g}x in all), to {residual:.3e} at joint "
                f"'{self.layout.joint_of[worst]}' ({self.layout.labels[worst]}): use a smaller "
                "step or the iterative coupling", time=time + step_size, step=step_index)
        if measuring:
            self._refresh(local, time, step_size, kinematics)
            # the perturbations moved the subsystems: step once more with the forces
            # this step is accepted with, so that the state matches the record
            self.glued.trial_step(local, time, step_size)
        self._ensure_factor(weights, diagonal, time + step_size, step_index)
        self.joints.accept(*trial)
        self.forces = forces
        self._history.append(forces - self._factor.solve(r))
        return StepReport(1, int(measuring), residual)
