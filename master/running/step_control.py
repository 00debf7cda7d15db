"""Error-controlled macro steps (``step="auto"``, ``dsim run --step auto``).

The run still lands on every output point (the output interval, default the scene's
step), so the CSV keeps its rows and columns; inside each output interval the macro
step is chosen from a local error estimate and a step whose estimate is too large is
taken again, smaller.

The estimate is step doubling (Richardson), as MasterSim and PyFMI's master take it:
from one snapshot of every FMU's state and of the coupling's own (joint states,
predictor history), the step of size h is taken once whole and, after a rollback, as
two halves; the accepted solution is the halves'.  The difference d of the two, over
what the execution gives (the connected values and the glued ports' positions and
velocities: not the joint forces, known only to the Newton tolerance over a
flexibility that grows as 1 / h**2), estimates the local error of the whole coupled
step: the FMUs' own integration, the interface's approximation over the step, and the
Newton tolerance, with nothing assumed about any FMU.  Its measure is

    err = sqrt(mean((d_i / (E + E |y_i|))^2))

(the weighted RMS norm of MasterSim and scipy's solvers, with ``E`` for both the
absolute and the relative part: a local error per step).  A step passes when
err <= 1.

Step sizes are the interval's span over a power of two, h = S / 2**k: the interface
flexibility and the strong coupling's Jacobian are kept per step size, so a run that
moves between a few levels measures each once instead of at every change of step,
and every step lands on the output grid exactly.  The next level comes from a PI
controller (Gustafsson's, exponents 0.7 / p and 0.4 / p with p = 2, safety 0.9),
rounded to a power of two: one level up at most per step (where the position allows
it), as many down as the estimate asks.  At the smallest step a step is accepted
whatever its estimate; the run says so once and counts such steps.

Every FMU must go back to a saved state (``canGetAndSetFMUstate``, or Model
Exchange, which dsim integrates) and take steps of any size; the plan refuses others
before anything runs.
"""
from __future__ import annotations

import math
from array import array
from dataclasses import dataclass

import numpy as np

from dsim.master.errors import StepFailure
from dsim.master.running.couplings.base import StepReport
from dsim.master.running.timeline import halves, size_to

#: the error tolerance of ``step="auto"`` when none is given
DEFAULT_TOLERANCE = 1e-6
#: the smallest step by default: the output interval over 2**LEVELS
LEVELS = 20
#: the PI controller: assumed order, safety factor, exponents (Gustafsson 1991)
ORDER, SAFETY, INTEGRAL, PROPORTIONAL = 2.0, 0.9, 0.7, 0.4


@dataclass(frozen=True)
class StepControl:
    """What an error-controlled run was asked for: ``tolerance`` E and the smallest
    and largest macro step (s; None: the defaults), and the first step tried (s)."""

    tolerance: float
    min_step: float | None
    max_step: float | None
    first_step: float


def levels(span: float, control: StepControl) -> tuple[int, int, int]:
    """The coarsest and finest level of a step (h = span / 2**level) over an output
    interval of ``span`` s, and the level of the first step tried."""
    coarsest = 0
    if control.max_step is not None and control.max_step < span:
        coarsest = math.ceil(math.log2(span / control.max_step) - 1e-9)
    finest = LEVELS
    if control.min_step is not None:
        finest = max(0, math.floor(math.log2(span / control.min_step) + 1e-9))
    finest = max(finest - 1, coarsest)  # the halves of the finest step are the smallest
    first = min(max(math.ceil(math.log2(span / control.first_step) - 1e-9), coarsest), finest)
    return coarsest, finest, first


class StepController:
    """Crosses each output interval in error-controlled macro steps.

    ``take(time, size, index, end)`` advances every subsystem by one macro step from
    ``time`` (s) by ``size`` (s) to ``end`` and returns its
    :class:`~dsim.master.running.couplings.base.StepReport`; ``values()`` gives the
    quantities the estimate weighs (one flat array), ``labels`` their names; the
    ``backend`` and ``coupling`` keep and restore snapshots; ``interval`` is the
    output interval (s)."""

    #: what a checkpoint keeps (:mod:`dsim.master.running.checkpointing`)
    CHECKPOINTED = ("_level", "_previous", "rejected", "at_smallest", "worst", "times",
                    "sizes", "notes")

    def __init__(self, control: StepControl, take, values, labels, backend, coupling,
                 interval: float):
        self.control = control
        self._take, self._values, self.labels = take, values, tuple(labels)
        self._backend, self._coupling = backend, coupling
        self._coarsest, self._finest, self._level = levels(interval, control)
        self._previous = None  # the last accepted estimate (the PI controller's memory)
        #: steps taken again, steps accepted above the tolerance at the smallest step,
        #: and where the largest accepted estimate was
        self.rejected = self.at_smallest = 0
        self.worst = {"estimate": 0.0, "time": None, "quantity": None}
        #: the start (s) and size (s) of every accepted step, in order
        self.times, self.sizes = array("d"), array("d")
        #: what the run should say once (the smallest step could not meet the tolerance)
        self.notes: list[str] = []

    # --- the estimate ------------------------------------------------------------------
    def _estimate(self, whole: np.ndarray, halves_: np.ndarray, size: float):
        """err of the step (see the module's docstring) and, per quantity, its share."""
        if not len(whole):
            return 0.0, None
        scale = self.control.tolerance * (1.0 + np.abs(halves_))
        ratio = np.abs(halves_ - whole) / scale
        if not np.all(np.isfinite(ratio)):
            return math.inf, ratio
        return float(np.sqrt(np.mean(ratio * ratio))), ratio

    def _next_level(self, error: float, accepted: bool, aligned: bool) -> int:
        """The level of the next step from this one's estimate (PI, rounded to a power
        of two; grown one level at most, and only where the position allows)."""
        level = self._level
        if error == 0.0:
            factor = 2.0
        elif not math.isfinite(error):
            factor = 0.25
        elif not accepted:  # no memory for a step taken again: as deep as it asks
            factor = SAFETY * error ** (-1.0 / ORDER)
        else:
            factor = SAFETY * error ** (-INTEGRAL / ORDER)
            if self._previous:
                factor *= self._previous ** (PROPORTIONAL / ORDER)
        if not accepted:
            level += max(1, math.ceil(math.log2(1.0 / min(factor, 0.5))))
        elif factor >= 2.0 and aligned:
            level -= 1
        elif factor < 0.5:
            level += math.floor(math.log2(1.0 / factor))
        return min(max(level, self._coarsest), self._finest)

    # --- one output interval -------------------------------------------------------------
    def advance(self, time: float, size: float, index: int, end: float) -> StepReport:
        """Cross the output interval from ``time`` by ``size`` (s) to ``end`` in accepted
        steps; the report of all the work it took."""
        finest = self._finest  # positions count in steps of the finest level
        position, last_position = 0, 1 << finest
        t = time
        totals = [0, 0, 0.0, 0, 0.0]  # iterations, refreshes, residual, cuts, lost
        while position < last_position:
            units = 1 << (finest - self._level)
            h = size / (1 << self._level)
            closing = position + units >= last_position
            whole = size_to(t, end, h) if closing else h
            reached = end if closing else t + whole
            accepted, error = self._attempt(t, whole, index, reached, totals)
            if accepted:
                position += units
                t = reached
            # a coarser step must start on its own grid: a whole number of them done
            aligned = position % (2 * units) == 0
            self._level = self._next_level(error, accepted, aligned)
            if accepted:
                self._previous = error if math.isfinite(error) and error > 0 else None
        return StepReport(totals[0], totals[1], totals[2], totals[3], totals[4])

    def _attempt(self, t: float, whole: float, index: int, end: float, totals):
        """One step from ``t`` by ``whole`` (s) to ``end``, doubled: whether it is
        accepted (the subsystems then at ``end``; else back at ``t``) and its estimate."""
        snapshot = self._backend.snapshot()
        state = self._coupling.state()
        at_floor = self._level >= self._finest
        try:
            try:
                self._add(totals, self._take(t, whole, index, end))
                coarse = self._values()
                self._backend.rollback(snapshot)
                self._coupling.set_state(state)
                (start, half), (middle, rest) = halves(t, whole)
                self._add(totals, self._take(start, half, index, middle))
                self._add(totals, self._take(middle, rest, index, end))
                error, ratio = self._estimate(coarse, self._values(), whole)
            except StepFailure as failure:  # too long a step for Newton: a smaller one
                if at_floor:
                    raise
                totals[0] += failure.iterations
                error, ratio = math.inf, None
            if error <= 1.0 or at_floor:
                self._accepted(t, whole, error, ratio, at_floor)
                return True, error
            self.rejected += 1
            self._backend.rollback(snapshot)
            self._coupling.set_state(state)
            return False, error
        finally:
            self._backend.discard(snapshot)

    def _accepted(self, t, whole, error, ratio, at_floor) -> None:
        self.times.append(t)
        self.sizes.append(whole)
        if ratio is not None and error > self.worst["estimate"]:
            worst = int(np.argmax(ratio))
            self.worst = {"estimate": error, "time": t + whole,
                          "quantity": self.labels[worst] if worst < len(self.labels) else None}
        if at_floor and error > 1.0:
            self.at_smallest += 1
            if not self.notes:
                self.notes.append(
                    f"t = {t + whole:.6g} s: the error estimate is {error:.3g} times the "
                    f"tolerance at the smallest step ({whole:g} s), accepted there (min_step "
                    "sets the smallest; the statistics count such steps: "
                    "step_control.at_smallest_step)")

    @staticmethod
    def _add(totals, report) -> None:
        totals[0] += report.iterations
        totals[1] += report.refreshed
        totals[2] = max(totals[2], report.residual)
        totals[3] = max(totals[3], report.cuts)
        totals[4] = max(totals[4], report.lost)

    def statistics(self) -> dict:
        """Accepted and rejected steps, the smallest, largest and mean step (s), and the
        largest accepted estimate (in tolerances) with where and when it was."""
        sizes = self.sizes[:]  # (a copy: an abandoned run asks from another thread)
        return {"error_tolerance": self.control.tolerance,
                "accepted_steps": len(sizes), "rejected_steps": self.rejected,
                "smallest_step": min(sizes) if sizes else None,
                "largest_step": max(sizes) if sizes else None,
                "mean_step": sum(sizes) / len(sizes) if sizes else None,
                "largest_estimate": self.worst["estimate"],
                "largest_estimate_time": self.worst["time"],
                "largest_estimate_quantity": self.worst["quantity"],
                "at_smallest_step": self.at_smallest}
