"""The progress bar of a run on a terminal (:class:`ProgressBar`, rich)."""
from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field

from dsim.master.recording.observers.base import RunInfo, StepRecord, Observer


@dataclass
class ProgressBar(Observer):
    """A rich progress bar on a terminal (simulated time, iterations per step),
    nothing elsewhere (CI logs, pipes); warnings go to the stream either way."""

    label: str = ""
    stream: object = None
    files: dict = field(default_factory=dict)
    #: the warnings printed so far
    shown: list = field(default_factory=list)
    #: what the run waits for, once it is late (a callable the run sets: the components
    #: of a worker that has not answered for a while), shown at the end of the line
    waiting: object = None

    def started(self, info: RunInfo) -> None:
        self.progress = None
        stream = self.stream or sys.stderr
        if not stream.isatty():
            return
        # rich is needed only on a terminal (a run in CI or a sweep's worker has none)
        from rich.console import Console
        from rich.progress import (BarColumn, Progress, TextColumn, TimeElapsedColumn,
                                   TimeRemainingColumn)
        from rich.progress import ProgressColumn
        from rich.text import Text

        bar = self

        class Late(ProgressColumn):
            """What the run has waited for too long (asked at every refresh, also
            while the main thread waits for it)."""

            def render(self, task):
                said = bar.waiting() if bar.waiting else None
                return Text(f"waiting: {said}" if said else "", style="bold yellow")

        self.progress = Progress(TextColumn("{task.description}"), BarColumn(),
                                 TextColumn("t = {task.fields[t]:.4g} s"),
                                 TextColumn("it/step {task.fields[it]:.2f}"),
                                 TimeElapsedColumn(), TimeRemainingColumn(), Late(),
                                 transient=True, console=Console(file=stream))
        self.progress.start()
        self.iterations = 0
        self.task_label = self.label or info.scene
        self.task = self.progress.add_task(self.task_label, total=info.planned_steps,
                                           t=info.start_time, it=0.0)

    def preparing(self, what: str, done: int, total: int) -> None:
        # a set-up of thousands of FMUs takes seconds: the line says how far it is
        if self.progress:
            counted = f" {done:,}/{total:,}" if total else ""
            self.progress.update(self.task, refresh=True,
                                 description=f"{self.task_label} · {what}{counted}")

    def stepped(self, record: StepRecord) -> None:
        if self.progress and not record.index:
            self.progress.update(self.task, description=self.task_label)
        if self.progress and record.index:
            self.iterations += record.iterations
            self.progress.update(self.task, completed=record.index, t=record.time,
                                 it=self.iterations / record.index)

    def warned(self, message: str) -> None:
        self.shown.append(message)
        if self.progress:
            self.progress.console.print(f"dsim: warning: {message}", markup=False,
                                        highlight=False)
        else:
            print(f"dsim: warning: {message}", file=self.stream or sys.stderr)

    def finished(self, result=None) -> None:
        if self.progress:
            self.progress.stop()
            self.progress = None

    def aborted(self) -> None:
        self.finished()

    def abandoned(self, result) -> None:
        # the bar's own stop takes its console's lock, which the main thread may hold:
        # only the terminal's cursor, which the bar hid, is given back
        if self.progress:
            try:
                os.write((self.stream or sys.stderr).fileno(), b"\r\x1b[2K\x1b[?25h")
            except (OSError, ValueError):
                pass
