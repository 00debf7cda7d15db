"""What every observer shares: the hooks (:class:`Observer`), what a run tells
them as it starts (:class:`RunInfo`) and at every converged step (:class:`StepRecord`).

An execution calls, in order: :meth:`Observer.started` once before any FMU is
instantiated (an observer that cannot do its job refuses the run here, as bad
input), :meth:`Observer.stepped` for the start time (index 0) and for every
converged macro step, :meth:`Observer.warned` for every warning, and
:meth:`Observer.finished` once with the :class:`~dsim.master.recording.results.RunResult`,
whatever the ending; :meth:`Observer.aborted` instead when the run never started
(bad input found while initialising).  When a second signal ends the process at
once, :meth:`Observer.abandoned` is called instead of :meth:`Observer.finished`,
from another thread (see :mod:`dsim.master.running.interrupts`).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np



@dataclass(frozen=True)
class RunInfo:
    """What an observer learns when a run starts."""

    scene: str
    file: Path
    columns: tuple[str, ...]  # of StepRecord.values: recorded outputs, then joint forces
    start_time: float
    stop_time: float
    step_size: float
    planned_steps: int
    coupling: str
    backend: str
    inputs: tuple = ()
    #: columns of the recorded String outputs (``StepRecord.texts``), after ``columns``
    text_columns: tuple[str, ...] = ()
    #: steps are recorded (and reach the observers) every this many macro steps, and
    #: at the last converged one (``output_interval``, dsim.master.recording.selection)
    record_every: int = 1
    #: the unit of ``time`` and of every column of ``columns`` ('' where the FMU
    #: declares none)
    units: dict = None


class StepRecord(NamedTuple):
    """One converged macro step (index 0: the start time, nothing stepped):
    ``values`` in the order of ``RunInfo.columns``; Newton iterations, flexibility
    refreshes and the largest residual left (units of the joints' measure); the
    recorded String outputs in the order of ``RunInfo.text_columns``."""

    index: int
    time: float
    values: np.ndarray
    iterations: int = 0
    refreshed: int = 0
    residual: float = 0.0
    texts: tuple[str, ...] = ()


class Observer:
    """Base class: every hook does nothing."""

    #: files this observer wrote, by kind ("csv", "statistics", "plot")
    files: dict

    def started(self, info: RunInfo) -> None:
        """The run is about to start (raise InputError to refuse it)."""

    def preparing(self, what: str, done: int, total: int) -> None:
        """The set-up goes on: ``done`` of ``total`` ``what`` (``"FMUs instantiated"``;
        ``total`` 0: no count, ``"initialising"``); between :meth:`started` and the
        first :meth:`stepped`, a few times a second at most."""

    def stepped(self, record: StepRecord) -> None:
        """A step converged (index 0: the start)."""

    def warned(self, message: str) -> None:
        """The run warns (an inconsistent start, a cleanup that failed)."""

    def finished(self, result) -> None:
        """The run ended: completed, failed or interrupted."""

    def aborted(self) -> None:
        """The run never started; undo what :meth:`started` did."""

    def abandoned(self, result) -> None:
        """The process ends at once (a second SIGINT or SIGTERM), from another thread,
        while the main thread may be stuck in an FMU's native code: write what can be
        written without waiting for the main thread (never a lock it may hold, never
        an FMU call); ``result`` is the interrupted run as far as it got."""
