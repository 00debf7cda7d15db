"""The signals of a run that writes no CSV, kept in memory (:class:`MemoryRecorder`)."""
from __future__ import annotations

import numpy as np

from dsim.master.recording.observers.base import RunInfo, StepRecord, Observer


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
        result.keep_signals(self.signals)  # made when first asked for

    def signals(self) -> dict[str, np.ndarray]:
        """Column name -> values over time (``time`` first)."""
        # (a scene that records no column still has its time column)
        data = np.array(self.rows, dtype=float).reshape(len(self.rows), len(self.columns))
        signals = {"time": np.array(self.times)}
        signals.update({name: data[:, i] for i, name in enumerate(self.columns)})
        for i, name in enumerate(self.text_columns):
            signals[name] = np.array([row[i] for row in self.texts], dtype=object)
        return signals
