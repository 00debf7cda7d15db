"""Observers: everything that watches a run goes through one interface, and only
observers write files.

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

import io
import json
import os
import sys
import threading
import time as clock
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from dsim.master.recording.output_files import OutputError, OutputFile, check_fits
from dsim.master.recording.results import in_display_units, mat_bytes, plot_signals, set_title
from dsim.master.recording.selection import recorded_rows


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


def _quoted(text: str) -> str:
    """A CSV field for a String value: always quoted, quotes doubled (RFC 4180)."""
    return '"' + text.replace('"', '""') + '"'


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


def _csv_block(records) -> str:
    """The CSV text of :class:`StepRecord` rows (time, values, texts), each number as
    ``repr`` writes it (the shortest text that reads back as the same double).  Rows
    of float times and float64 values only (every run's, unless it records Strings)
    go through one table: numpy gathers them, one ``map(repr)`` over all its numbers
    (Python's loop, in C) and one join per row, about 1.6 times as fast as a join of
    reprs per row.  (``repr`` of the table's ``tolist()`` with its brackets and
    spaces replaced gives the same text, 1.2 times slower: measured in
    docs/causal_benchmark.md; the ``repr`` of each double is most of the cost.)"""
    rows = [(record.time, record.values, record.texts) for record in records]
    width = len(rows[0][1])
    if any(texts or type(time) is not float or values.dtype != np.float64
           or len(values) != width for time, values, texts in rows):
        return "".join(",".join([repr(time)] + list(map(repr, values.tolist()))
                               + [_quoted(t) for t in texts]) + "\n"
                       for time, values, texts in rows)
    table = np.empty((len(rows), width + 1))
    table[:, 0] = [time for time, _, _ in rows]
    if width:
        table[:, 1:] = [values for _, values, _ in rows]
    numbers = list(map(repr, table.ravel().tolist()))
    return "\n".join(map(",".join, zip(*[iter(numbers)] * (width + 1)))) + "\n"


class CsvRecorder(Observer):
    """``time``, recorded outputs, joint forces: one row per converged step, in full
    double precision, under a temporary name renamed to ``path`` when the run ends
    (see :mod:`dsim.master.recording.output_files`).  Rows reach the file (``os.write``: the
    operating system's, whatever happens to this process) in whole rows at least
    every ``flush_seconds`` and when the run ends, however it ends: a failed or
    interrupted run keeps every converged step, and a process killed outright loses
    at most the last ``flush_seconds`` (under the temporary name).

    Rows wait in memory until ``flush_seconds`` have passed, so that a fast run makes
    few writes.  A step that never returns (an FMU stuck in its own code) must not keep
    the rows before it in memory, so a daemon thread writes rows that have waited
    ``flush_seconds``; the main thread is in native code then (it released the
    interpreter) and the thread runs.  The rows wait in a deque (appended without a
    lock: the step costs what it did) and leave it, in order, only under a lock that
    guards the file; that lock is never held across an FMU call."""

    def __init__(self, path, flush_seconds: float = 0.05, force: bool = False):
        self.path = Path(path)
        #: run even when the CSV would not fit the free disk space
        self.force = force
        self.output: OutputFile | None = None
        self._written = 0
        self.flush_seconds = flush_seconds
        self._pending: deque = deque()
        self._flushed_at = 0.0
        #: when the main thread writes the pending rows itself (monotonic seconds)
        self._due = 0.0
        self._lock = threading.Lock()
        self._done = threading.Event()
        self._late_error: OutputError | None = None
        self.files = {}

    def started(self, info: RunInfo) -> None:
        if not self.force:
            check_fits(self.path, recorded_rows(info.planned_steps, info.record_every),
                       1 + len(info.columns) + len(info.text_columns))
        self.output = OutputFile(self.path, info.inputs)
        self.output.open()
        self.output.append((",".join(("time",) + info.columns + info.text_columns)
                            + "\n").encode())
        self._flushed_at = clock.monotonic()
        self._due = self._flushed_at + self.flush_seconds
        self._done.clear()
        threading.Thread(target=self._flush_late_rows, name="dsim-csv-flush",
                         daemon=True).start()

    @property
    def rows(self) -> int:
        """Rows recorded so far (written or pending)."""
        return self._written + len(self._pending)

    def stepped(self, record: StepRecord) -> None:
        # no lock here: a deque's append and popleft are atomic, and the rows leave it
        # in order, only under the lock (the record is kept as it is: a NamedTuple,
        # its values a new array every step)
        self._pending.append(record)
        if clock.monotonic() >= self._due:
            self.flush()

    def flush(self) -> None:
        """Write the pending rows (whole rows, or none of them: OutputError; also when
        the flushing thread's last write failed)."""
        with self._lock:
            if self._late_error is not None:
                error, self._late_error = self._late_error, None
                self._pending.clear()  # rows after a lost batch would leave a gap
                raise error
            self._write_pending()

    def _write_pending(self) -> None:
        """Write the rows pending now, with the lock held."""
        pending = self._pending
        rows = [pending.popleft() for _ in range(len(pending))]
        if rows:
            self.output.append(_csv_block(rows).encode(), separator=b"\n")
            self._written += len(rows)
        self._flushed_at = clock.monotonic()
        self._due = self._flushed_at + self.flush_seconds

    def _flush_late_rows(self) -> None:
        """The flushing thread: rows that waited ``flush_seconds`` go to the file
        (an error is raised by the main thread's next flush)."""
        while not self._done.wait(self.flush_seconds / 2):
            if not self._pending or clock.monotonic() - self._flushed_at < self.flush_seconds:
                continue
            with self._lock:
                if self._late_error is not None or self._done.is_set():
                    continue
                try:
                    self._write_pending()
                except OutputError as error:
                    self._late_error = error

    def finished(self, result) -> None:
        self._done.set()
        with self._lock:
            if self.output and self.output.is_open:
                try:
                    if self._late_error is not None:
                        raise self._late_error
                    self._write_pending()
                except OutputError as error:
                    result.warnings.append(str(error))
                try:
                    self.output.commit()
                except OutputError as error:
                    result.warnings.append(str(error))
                    return
                self.files["csv"] = self.path

    def abandoned(self, result) -> None:
        """The process ends at once (a second signal): the pending rows are written
        and the file renamed, unless the main thread holds the lock (it is writing
        them itself; what it handed to the OS is kept under the temporary name, and
        the next run on this output ends that file for it: dsim.master.recording.output_files)."""
        self._done.set()
        if not self._lock.acquire(timeout=0.5):
            return
        try:
            if self.output and self.output.is_open:
                try:
                    self._write_pending()
                except OutputError:
                    pass  # the whole rows written before stay
                try:
                    self.output.commit()
                except OutputError:
                    return
                self.files["csv"] = self.path
        finally:
            self._lock.release()

    def aborted(self) -> None:
        self._done.set()
        if self.output:
            self.output.discard()


class MemoryRecorder(Observer):
    """Keeps every row in memory (the signals of a run that writes no CSV)."""

    def __init__(self):
        self.columns: tuple[str, ...] = ()
        self.rows: list[np.ndarray] = []
        self.files = {}

    def started(self, info: RunInfo) -> None:
        self.columns = info.columns
        self.text_columns = info.text_columns
        self.times: list[float] = []
        self.rows = []
        self.texts = []

    def stepped(self, record: StepRecord) -> None:
        self.times.append(record.time)
        self.rows.append(record.values)  # a new array every step: kept, not copied
        if record.texts:
            self.texts.append(record.texts)

    def finished(self, result) -> None:
        if result._signals is None:
            result._signals = self.signals  # made when first asked for

    def signals(self) -> dict[str, np.ndarray]:
        """Column name -> values over time (``time`` first)."""
        # (a scene that records no column still has its time column)
        data = np.array(self.rows, dtype=float).reshape(len(self.rows), len(self.columns))
        signals = {"time": np.array(self.times)}
        signals.update({name: data[:, i] for i, name in enumerate(self.columns)})
        for i, name in enumerate(self.text_columns):
            signals[name] = np.array([row[i] for row in self.texts], dtype=object)
        return signals


class FileWriter(Observer):
    """A file written whole when the run ends, also when it failed or was
    interrupted (``content`` makes it; None: nothing to write); its temporary file
    is made and locked when the run starts (see :mod:`dsim.master.recording.output_files`), so that
    a run that cannot write it, or that another run is writing, is refused before
    anything runs; a failure to write it is a warning, never a replacement for how
    the run ended."""

    #: what the file is, for ``files`` and messages ("statistics", "plot", "mat")
    kind = ""

    def __init__(self, path):
        self.path = Path(path)
        self.output: OutputFile | None = None
        self.files = {}
        #: held while the file is written (a second signal waits for it, see abandoned)
        self._writing = threading.Lock()

    def started(self, info: RunInfo) -> None:
        self.output = OutputFile(self.path, info.inputs)
        self.output.open()

    def content(self, result) -> bytes | None:
        """The file's bytes for this result."""
        raise NotImplementedError

    def finished(self, result) -> None:
        with self._writing:
            if self.output is None or not self.output.is_open:
                return
            try:
                data = self.content(result)
                if data is None:
                    self.output.discard()
                    return
                self.output.append(data)
                self.output.commit()
            except Exception as error:  # a full disk must not hide how the run ended
                self.output.discard()
                result.warnings.append(f"{self.kind} not written to {self.path}: {error}")
                return
            self.files[self.kind] = self.path

    def aborted(self) -> None:
        if self.output:
            self.output.discard()


#: components above which the statistics JSON puts each component's table on one line
ONE_LINE_EACH = 200


def statistics_json(statistics: dict) -> str:
    """The statistics as JSON text: indented, or, with more than
    :data:`ONE_LINE_EACH` components, one line per top-level key and per component.
    Python's JSON encoder indents in Python, its compact encoder is C: 0.52 against
    0.16 s at 10,000 components, 5.1 against 2.0 s at 100,000, where a second Ctrl-C
    leaves 3 s to write everything."""
    components = statistics.get("components")
    if not isinstance(components, dict) or len(components) <= ONE_LINE_EACH:
        return json.dumps(statistics, indent=2, default=str)
    lines = []
    for key, value in statistics.items():
        if value is components:
            each = ",\n".join(f"    {json.dumps(name)}: {json.dumps(table, default=str)}"
                              for name, table in components.items())
            text = "{\n" + each + "\n  }"
        else:
            text = json.dumps(value, default=str)
        lines.append(f"  {json.dumps(key)}: {text}")
    return "{\n" + ",\n".join(lines) + "\n}"


class StatisticsWriter(FileWriter):
    """The statistics JSON of a run (``result.statistics``)."""

    kind = "statistics"

    def content(self, result) -> bytes:
        return statistics_json(result.statistics).encode()

    def abandoned(self, result) -> None:
        # the main thread may be writing it (the run had ended): let it finish, briefly
        if not self._writing.acquire(timeout=0.5):
            return
        self._writing.release()
        if self.kind not in self.files:  # unless the run's end wrote it already
            self.finished(result)


class PlotWriter(FileWriter):
    """A PNG of the run's signals (outputs and joint forces)."""

    kind = "plot"

    def __init__(self, path, title: str = ""):
        super().__init__(path)
        self.title = title

    def started(self, info: RunInfo) -> None:
        super().started(info)
        self.scene = info.scene
        self.units = info.units

    def content(self, result) -> bytes | None:
        if result.steps == 0:
            return None
        image = io.BytesIO()
        signals, units = in_display_units(result.signals, self.units,
                                          result.statistics.get("display_units"))
        # the title says the scene and the values given for this run (--set)
        plot_signals(signals, image, self.title or set_title(
            self.scene, result.statistics.get("parameters")), units=units)
        return image.getvalue()


class MatWriter(FileWriter):
    """A MATLAB .mat file of the run's signals (see :func:`dsim.master.recording.results.mat_bytes`)."""

    kind = "mat"

    def started(self, info: RunInfo) -> None:
        super().started(info)
        self.units = info.units

    def content(self, result) -> bytes | None:
        return mat_bytes(result.signals, self.units) if result.signals else None


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
