"""The results CSV: ``time``, recorded outputs, joint forces, one whole row per
converged step, written as the run goes (:class:`CsvRecorder`)."""
from __future__ import annotations

import threading
import time as clock
from collections import deque
from pathlib import Path

import numpy as np

from dsim.master.recording.observers.base import RunInfo, StepRecord, Observer
from dsim.master.recording.output_files import OutputError, OutputFile, check_fits
from dsim.master.recording.selection import recorded_rows


def _quoted(text: str) -> str:
    """A CSV field for a String value: always quoted, quotes doubled (RFC 4180)."""
    return '"' + text.replace('"', '""') + '"'


def csv_block(records) -> str:
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

    def __init__(self, path, flush_seconds: float = 0.05, force: bool = False,
                 digest: bool = False, continuing: dict | None = None):
        self.path = Path(path)
        #: keep the SHA-256 of the file as it is written (a run with checkpoints)
        self.digest = digest or continuing is not None
        #: the results a resumed run goes on from ({"bytes", "sha256", "rows"}: the
        #: file at ``path`` as a checkpoint saw it), or None: a new file
        self.continuing = continuing
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
        self.output.open()  # (a killed run's rows go to the final name first)
        if self.digest:
            self.output.keep_digest()
        if self.continuing is not None:
            try:
                self.output.copy_prefix(self.path, self.continuing["bytes"],
                                        self.continuing["sha256"])
            except BaseException:
                self.output.discard()
                raise
            self._written = self.continuing["rows"]
        else:
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

    def position(self) -> dict:
        """The results written so far, every pending row flushed and on the disk: their
        length (bytes), SHA-256 and rows (a checkpoint records them)."""
        self.flush()
        self.output.sync()
        return {"path": str(self.path.resolve()), "bytes": self.output.size,
                "sha256": self.output.digest.hexdigest(), "rows": self._written}

    def _write_pending(self) -> None:
        """Write the rows pending now, with the lock held."""
        pending = self._pending
        rows = [pending.popleft() for _ in range(len(pending))]
        if rows:
            self.output.append(csv_block(rows).encode(), separator=b"\n")
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
