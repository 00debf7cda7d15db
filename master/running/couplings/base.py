"""What every coupling shares: one template macro step.

A coupling decides how the subsystems advance together over a macro step.  The
template :meth:`Coupling.step` is the same for all of them (seen from the
execution): causal inputs from the outputs at the step start (Jacobi), then the
coupling's own advance of the glued subsystems (:meth:`Coupling._advance`: T-T
Newton with rollback, one explicit trial, or nothing), then one plain doStep of
every subsystem that is in no joint (never saved nor restored), then one batched
read of every subsystem's outputs.
"""
from __future__ import annotations

import time as clock
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from dsim.master.running.connections import Transfer
from dsim.master.running.loops import LoopSolver


@dataclass
class StepReport:
    """What one macro step took: Newton iterations (0 when nothing is glued),
    flexibility refreshes, the largest residual left (units of the measure), how
    deep the step was cut (0: not cut; 2: down to quarter steps), and the residual
    left along directions no joint force changes where the gluing matrix lost rank
    (0: none; the step was accepted in the least-squares sense)."""

    iterations: int
    refreshed: int
    residual: float
    cuts: int = 0
    lost: float = 0.0

    @classmethod
    def of_parts(cls, parts) -> "StepReport":
        """The report of a step taken in ``parts`` (a cut step's halves, a step cut at
        an event's time): their iterations and refreshes summed, the largest residual,
        cut depth and lost residual."""
        return cls(sum(p.iterations for p in parts), sum(p.refreshed for p in parts),
                   max(p.residual for p in parts), max(p.cuts for p in parts),
                   max(p.lost for p in parts))


def _joined(parts) -> np.ndarray:
    """The subsystems' outputs as one flat array (a scene without components: none)."""
    return np.concatenate(parts) if parts else np.zeros(0)


#: the report of a step that glued nothing
_NOTHING = StepReport(0, 0, 0.0)


class Coupling(ABC):
    """Advances every subsystem of a backend over macro steps.

    ``glued`` lists the backend's subsystems that are in a joint (the layout's
    incidence follows their order); the others take one doStep per macro step.
    ``transfer`` moves causal connection values (see :mod:`dsim.master.running.connections`).
    """

    #: registry name
    name = ""
    #: what a checkpoint keeps of a coupling (:mod:`dsim.master.running.checkpointing`;
    #: a subclass adds its own)
    CHECKPOINTED = ("outputs", "forces", "_outputs_by_subsystem", "refreshes",
                    "factorizations", "loop_solver")
    #: whether the glued subsystems must save and restore their state
    rolls_back = True
    #: the backend's kernel that takes whole steps, where this coupling has one (the
    #: causal coupling without loops: :meth:`Backend.causal_kernel`); None: the
    #: template step
    kernel = None

    def __init__(self, backend, glued, layout, joints, settings, transfer=None):
        self.backend = backend
        glued = list(glued)
        chosen = set(glued)  # made once: 0.8 s at 10,000 subsystems when made per index
        free = [i for i in range(len(backend)) if i not in chosen]
        self.glued = backend.subset(glued)
        self.free = backend.subset(free)
        self._order = (glued, free)
        transfer = transfer or Transfer(np.zeros(0, int), np.zeros(0), np.zeros(0), ())
        self._glued_inputs = transfer.restricted(glued)
        self._free_inputs = transfer.restricted(free)
        self._outputs_by_subsystem: list[np.ndarray] = [np.zeros(0)] * len(backend)
        self.layout = layout
        self.joints = joints
        self.settings = settings
        self.forces = np.zeros(layout.size if layout else 0)
        self.outputs = np.zeros(0)
        self.refreshes = 0
        #: solves the scene's algebraic loops at each communication point (set by the
        #: execution when the plan found any: :mod:`dsim.master.running.loops`)
        self.loop_solver = None
        #: times the gluing matrix was factored
        self.factorizations = 0
        #: seconds spent measuring flexibilities and factoring the gluing matrix
        self.seconds = {"flexibility": 0.0, "factorization": 0.0}

    @classmethod
    def from_plan(cls, plan, backend, layout, joints, settings, sensitivity=None):
        """The coupling of a run of ``plan`` (a checked
        :class:`~dsim.master.planning.plan.Plan`) over ``backend``, configured from it
        (:meth:`configure`); ``sensitivity``: d a / d f of the glued subsystems at the
        start, where the plan asked for it."""
        coupling = cls(backend, plan.glued, layout, joints, settings, plan.transfer)
        coupling.configure(plan, sensitivity)
        return coupling

    def configure(self, plan, sensitivity=None) -> None:
        """Take from the plan what this coupling uses besides its constructor's: here
        the solver of the scene's algebraic loops; a subclass adds its own."""
        if plan.loops:
            self.loop_solver = LoopSolver(plan.transfer, plan.loops, plan.loop_positions,
                                          self.settings)

    def start(self, kinematics=None, forces=None) -> None:
        """Set up at the start time, after initialization: ``kinematics`` of the
        glued subsystems and the start forces (None: zero)."""
        if forces is not None:
            self.forces = np.array(forces, dtype=float)
        self.read_outputs()

    def counts(self) -> dict:
        """What the coupling counted over the run, by the statistics' names: flexibility
        refreshes and factorizations, and (a coupling that cuts steps or solves in the
        least-squares sense says more) step cuts, least-squares factorizations and
        steps, steps accepted at the round-off floor; and the algebraic loops'
        solver's counts (None without loops)."""
        return {"lambda_refreshes": self.refreshes,
                "lambda_factorizations": self.factorizations, "step_cuts": 0,
                "least_squares_factorizations": 0, "least_squares_steps": 0,
                "roundoff_steps": 0,
                "algebraic_loops": None if self.loop_solver is None
                else self.loop_solver.counts()}

    def state(self) -> dict:
        """What a macro step changes in the coupling (outputs, forces, and a
        subclass's joint states and predictor history), for :meth:`set_state`: the
        error-controlled step takes a step, goes back and takes it again in halves."""
        return {"outputs": self.outputs.copy(), "forces": self.forces.copy(),
                "parts": list(self._outputs_by_subsystem)}

    def set_state(self, state: dict) -> None:
        """Go back to a :meth:`state` (which stays usable)."""
        self.outputs = state["outputs"].copy()
        self.forces = state["forces"].copy()
        self._outputs_by_subsystem = list(state["parts"])

    def resumed(self) -> None:
        """Make again what is derived from the state a checkpoint set
        (:mod:`dsim.master.running.checkpointing`): here nothing."""

    def solve_loops(self, time: float) -> None:
        """Solve the algebraic loops at the communication point ``time`` (the outputs
        then hold the solution)."""
        if self.loop_solver is None:
            return
        parts = self.loop_solver.solve(self.backend, self.outputs, time)
        if parts is not None:
            self._outputs_by_subsystem = list(parts)
            self.outputs = np.concatenate(parts)

    def read_outputs(self) -> np.ndarray:
        """Every subsystem's read values (recorded outputs and connection sources),
        one flat array in the backend's order."""
        self._outputs_by_subsystem = list(self.backend.read_outputs())
        self.outputs = np.concatenate(self._outputs_by_subsystem) if self._outputs_by_subsystem else np.zeros(0)
        return self.outputs

    def _assemble(self, subset: int, parts) -> None:
        for index, part in zip(self._order[subset], parts):
            self._outputs_by_subsystem[index] = part

    def step(self, time: float, step_size: float, step_index: int) -> StepReport:
        """Advance every subsystem from ``time`` by ``step_size`` (s)."""
        glued, free = self._order
        if not glued:  # causal: every subsystem free, in order
            inputs = self._free_inputs.inputs(self.outputs) if self._free_inputs.size else ()
            self._outputs_by_subsystem = self.free.step(time, step_size, inputs)
            self.outputs = _joined(self._outputs_by_subsystem)
            return _NOTHING
        if self._glued_inputs.size:
            self.glued.write_inputs(self._glued_inputs.inputs(self.outputs))
        report = self._advance(time, step_size, step_index)
        if free:
            # write inputs, step, read outputs: one call per subsystem
            inputs = self._free_inputs.inputs(self.outputs) if self._free_inputs.size else ()
            self._assemble(1, self.free.step(time, step_size, inputs))
        self._assemble(0, self.glued.read_outputs())
        self.outputs = _joined(self._outputs_by_subsystem)
        return report

    @abstractmethod
    def _advance(self, time: float, step_size: float, step_index: int) -> StepReport:
        """Advance the glued subsystems (the coupling's own work)."""

    def _timed(self, phase: str, function, *args):
        start = clock.perf_counter()
        try:
            return function(*args)
        finally:
            self.seconds[phase] += clock.perf_counter() - start


class CausalCoupling(Coupling):
    """No joints: every subsystem takes one doStep per macro step with inputs from
    the outputs at the step start; no state is saved, no Newton runs.  Without
    algebraic loops the backend's causal kernel takes the steps, where it has one
    (:meth:`~dsim.master.running.backends.base.Backend.causal_kernel`)."""

    name = "causal"
    rolls_back = False
    _kernel_asked = False

    def solve_loops(self, time: float) -> None:
        super().solve_loops(time)
        # at the start point every loop has been probed: a kernel when none is solved
        # (a loop of FMUs that compute their outputs only in their step is passed on)
        if self._kernel_asked:
            return
        self._kernel_asked = True
        if not self._order[0] and (self.loop_solver is None or not any(
                active is not False for active in self.loop_solver.active)):
            self.kernel = self.free.causal_kernel(self._free_inputs,
                                                  self._outputs_by_subsystem)

    def step(self, time: float, step_size: float, step_index: int) -> StepReport:
        if self.kernel is None:
            return super().step(time, step_size, step_index)
        self.outputs = self.kernel(self.outputs, time, step_size)
        return _NOTHING

    def _advance(self, time, step_size, step_index) -> StepReport:
        return StepReport(0, 0, 0.0)
