"""What a run counted while it ran, handed to recording as one object: running counts,
recording writes (:func:`dsim.master.recording.statistics.run_statistics`), and no
module reads another's private fields for it."""
from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class RunCounts:
    """An ended (or abandoned) run's counts, in the units the statistics give them."""

    #: how the run ended: completed, failed, interrupted, aborted
    status: str
    #: the error that ended a failed run, else None
    error: Exception | None
    #: the last communication point reached (s), its index, and the planned number
    time: float
    steps: int
    planned_steps: int
    #: the component that ended the simulation itself and the time it reached, or None
    ended_by: dict | None
    warnings: tuple[str, ...]
    #: Newton iterations -> how many macro steps took that many
    iterations: dict
    #: seconds per phase (setup, steps, observers, finish, and the coupling's own parts)
    phases: dict
    #: the coupling's counters (:meth:`~dsim.master.running.couplings.base.Coupling.counts`)
    coupling: dict
    #: the recorded numeric columns (outputs, then joint forces), before any selection
    columns: tuple[str, ...]
    #: an error-controlled run's steps (:meth:`StepController.statistics`), or None
    step_control: dict | None = None
    #: per subsystem (name, FMI function -> [calls, seconds], where it ran or None);
    #: None when the subsystems could not be asked (an abandoned run)
    subsystems: list | None = None
    #: every worker lost, and how the run went on
    lost_workers: list = field(default_factory=list)
    #: a fixed-step run's estimate of its connections' coupling error
    #: (:meth:`CouplingErrorWatch.statistics`), or None
    coupling_error: dict | None = None
    #: what ended a failed or interrupted run (the error; the signal or stop, where and
    #: when), None for a completed one
    message: str | None = None
    #: a run with a scenario: every change it applied (time, target, action, old and
    #: new value: :attr:`dsim.master.running.scenario.ScenarioRun.applied`), else None
    scenario: list | None = None
