"""Connections coupled as strongly as joints: the values that SSP connections carry
between FMUs that can roll back are iterated to convergence at every macro step,
together with the joints' forces where the scene has joints.

The once-per-step exchange (the causal coupling, and the iterative coupling for what
is not in a joint) hands each FMU its inputs as the sources had them at the step's
start and holds them over the step: two FMUs that pass position one way and force
the other then carry an O(h) coupling error that no tolerance removes.  Here the
unknowns are the connected inputs at the step's end, u; one evaluation steps every
iterated FMU from its saved state with its inputs moving linearly from their values
at the step's start to u (a Model Exchange FMU: dsim's integrator takes the ramp; a
co-simulation FMU that can interpolate inputs: ``SetRealInputDerivatives``; any
other: u held over the step) and, where there are joints, solves the joints' Newton
(the iterative coupling's, with its flexibility and predictor) for those inputs.  The
residual is

    R(u) = u - T(y(u))

with y the outputs at the step's end and T the connections (gather, units, linear
transformations).  Newton on R, with the Jacobian I - T' dy/du measured by
perturbation and rollback (one more evaluation per connected input: the machinery
of a joint's flexibility), kept across steps and measured anew when the step size
changes or convergence slows (``refresh_after`` iterations).  The step is accepted
when every |R_k| <= tolerance + relative_tolerance |u_k|.

FMUs that cannot roll back (FMI 1.0, no FMU state) take one step per macro step,
first, with their inputs from the outputs at the step's start; their outputs at the
step's end then feed the iterated FMUs as known values.  With joints, a failed step
is not cut in halves (the connections' ramps span the whole step).
"""
from __future__ import annotations

from collections import deque

import numpy as np
from scipy.linalg import lu_factor, lu_solve

from dsim.master.errors import SimulationError
from dsim.master.running.connections import Transfer
from dsim.master.running.couplings.base import Coupling, StepReport, _joined
from dsim.master.running.couplings.iterative import IterativeCoupling


class StrongCoupling(IterativeCoupling):
    """Newton on the connected inputs of the FMUs that can roll back, around the joint
    Newton of the iterative coupling where the scene has joints."""

    name = "strong"
    CHECKPOINTED = ("_previous", "_jacobian", "_measured_for", "_jacobians")

    def __init__(self, backend, glued, layout, joints, settings, transfer=None):
        super().__init__(backend, glued, layout, joints, settings, transfer)
        self._transfer = transfer or Transfer(np.zeros(0, int), np.zeros(0), np.zeros(0), ())
        self._jacobian = None
        self._measured_for = None
        #: step size -> the factored Jacobian measured for it (an error-controlled run
        #: moves between a few sizes and back)
        self._jacobians: dict = {}
        self._previous = None  # the inputs at the last step's start (the predictor)
        #: the iterated inputs' names (component.variable), for messages
        self.labels: tuple = ()
        self.iterate(glued)

    def configure(self, plan, sensitivity=None) -> None:
        """The connections of the plan's iterated components, and their inputs' names
        for the message of one that fails."""
        super().configure(plan, sensitivity)
        self.iterate(plan.iterated)
        self.labels = tuple(f"'{plan.specs[g].name}.{name}'" for g in self.group
                            for name in plan.specs[g].writes)

    @property
    def joined(self) -> bool:
        """Whether the scene has joints (their Newton runs inside each evaluation)."""
        return bool(self.layout is not None and self.layout.size)

    @property
    def group(self) -> list[int]:
        """The subsystems whose connected inputs are iterated, in the order of u."""
        return list(self._group)

    @property
    def cut_limit(self) -> int:
        """No cut steps: the connections' ramps span the whole step."""
        return 0

    @cut_limit.setter
    def cut_limit(self, value) -> None:
        pass

    def iterate(self, indices) -> None:
        """Iterate the connections of the subsystems at ``indices`` (those that can roll
        back); with joints, the glued ones are iterated too, and the others step once."""
        glued, free = self._order
        chosen = set(indices) | set(glued)
        extra = [i for i in free if i in chosen] if self.joined else []
        self._group = sorted(set(glued) | set(extra)) if self.joined else list(glued)
        self._position = {index: k for k, index in enumerate(self._group)}
        self._exchangers = extra if self.joined else list(glued)
        self._exchanging = self.backend.subset(self._exchangers)
        self._rest = [i for i in free if i not in chosen]
        self._resting = self.backend.subset(self._rest)
        self._group_inputs = self._transfer.restricted(self._group)
        self._rest_inputs = self._transfer.restricted(self._rest)

    def state(self) -> dict:
        return {**super().state(), "previous": self._previous}

    def set_state(self, state: dict) -> None:
        super().set_state(state)
        self._previous = state["previous"]

    def start(self, kinematics=None, forces=None) -> None:
        if self.joined:
            super().start(kinematics, forces)
        else:
            Coupling.start(self, kinematics, forces)

    # --- one evaluation of R(u) --------------------------------------------------------
    def _fed(self, outputs: np.ndarray) -> np.ndarray:
        """T(y): the iterated group's inputs from a flat output vector."""
        if not self._group_inputs.size:
            return np.zeros(0)
        return self._group_inputs.values(outputs)

    def _ramps(self, members, start, end, step_size):
        starts = dict(self._group_inputs.split(start))
        ends = dict(self._group_inputs.split(end))
        return [(starts.get(self._position[i]), ends.get(self._position[i]))
                for i in members]

    def _evaluate(self, time, step_size, step_index, start, u, first, snapshot):
        """Step the group from its saved state with inputs ramping to ``u`` (and solve
        the joints); the residual and the joint Newton's report (None without)."""
        report = None
        if self._exchangers:
            ramps = self._ramps(self._exchangers, start, u, step_size)
            for index, outputs in zip(self._exchangers, self._exchanging.trial_exchange(
                    time, step_size, ramps)):
                self._outputs_by_subsystem[index] = outputs
        if self.joined:
            glued = self._order[0]
            self.glued.hold_inputs([(s, e, step_size) for s, e in
                                    self._ramps(glued, start, u, step_size)])
            if not first:
                self._restore(snapshot)
            report = self._newton(time, step_size, step_index, save=first)
            for index, outputs in zip(glued, self.glued.read_outputs()):
                self._outputs_by_subsystem[index] = outputs
        return u - self._fed(np.concatenate(self._outputs_by_subsystem)), report

    def _snapshot(self):
        """What a joint Newton solve changes in the coupling: joint states, predictor
        history, forces (restored before the step is solved again)."""
        joints = self.joints
        return (joints.q.copy(), joints.qd.copy(), joints.qdd.copy(),
                list(self._history), self.forces.copy())

    def _restore(self, snapshot) -> None:
        q, qd, qdd, history, forces = snapshot
        self.joints.q, self.joints.qd, self.joints.qdd = q.copy(), qd.copy(), qdd.copy()
        self._history = deque((f.copy() for f in history), maxlen=self._history.maxlen)
        self.forces = forces.copy()

    def _measure(self, time, step_size, step_index, start, u, base, snapshot) -> int:
        """J = dR/du by perturbing one connected input at a time (each an evaluation
        from the saved state); the joint iterations it took."""
        n = len(u)
        jacobian = np.zeros((n, n))
        spent = 0
        for k in range(n):
            delta = self.settings.perturbation * max(1.0, abs(u[k]))
            probe = u.copy()
            probe[k] += delta
            residual, report = self._evaluate(time, step_size, step_index, start, probe,
                                              False, snapshot)
            spent += report.iterations if report else 0
            jacobian[:, k] = (residual - base) / delta
        self._jacobian = lu_factor(jacobian, check_finite=False)
        self._measured_for = step_size
        self._jacobians[step_size] = self._jacobian
        self.refreshes += 1
        self.factorizations += 1
        return spent

    # --- the macro step ----------------------------------------------------------------
    def step(self, time: float, step_size: float, step_index: int) -> StepReport:
        outputs_now = self.outputs
        if self._rest:  # what cannot roll back: one step, inputs from the step's start
            inputs = self._rest_inputs.inputs(outputs_now) if self._rest_inputs.size else ()
            for index, outputs in zip(self._rest, self._resting.step(time, step_size,
                                                                     inputs)):
                self._outputs_by_subsystem[index] = outputs
        if not self._group:
            self.outputs = _joined(self._outputs_by_subsystem)
            return StepReport(0, 0, 0.0)
        start = self._fed(outputs_now)
        predictor = self.settings.predictor
        u = start.copy() if self._previous is None or predictor in ("none", "constant") \
            else start + (start - self._previous)
        if self._exchangers:
            self._exchanging.begin_step()
        snapshot = self._snapshot() if self.joined else None
        residual, report = self._evaluate(time, step_size, step_index, start, u, True,
                                          snapshot)
        iterations = report.iterations if report else 1
        refreshed, evaluations = 0, 1
        limit = self.settings.tolerance + self.settings.relative_tolerance * np.abs(u)
        while np.any(np.abs(residual) > limit):
            if evaluations >= self.settings.max_iterations:
                worst = int(np.argmax(np.abs(residual) - limit))
                raise SimulationError(
                    f"connections did not converge in {evaluations} iterations at "
                    f"t = {time + step_size:g} s: input {self._label(worst)} is "
                    f"{abs(residual[worst]):.3g} from its source's value (tolerance "
                    f"{limit[worst]:.3g})", time=time + step_size)
            if self._measured_for != step_size and step_size in self._jacobians:
                self._jacobian, self._measured_for = self._jacobians[step_size], step_size
            if self._jacobian is None or self._measured_for != step_size or (
                    evaluations % self.settings.refresh_after == 0):
                iterations += self._measure(time, step_size, step_index, start, u,
                                            residual, snapshot)
                refreshed += 1
            u = u - lu_solve(self._jacobian, residual, check_finite=False)
            residual, report = self._evaluate(time, step_size, step_index, start, u,
                                              False, snapshot)
            iterations += report.iterations if report else 1
            evaluations += 1
            limit = self.settings.tolerance + self.settings.relative_tolerance * np.abs(u)
        self._previous = start
        self.outputs = np.concatenate(self._outputs_by_subsystem)
        return StepReport(iterations, refreshed,
                          float(np.max(np.abs(residual), initial=0.0)))

    def _label(self, position: int) -> str:
        """'component.variable' of the connected input at ``position``."""
        return self.labels[position] if position < len(self.labels) else f"#{position}"
