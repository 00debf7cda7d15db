"""The MATLAB .mat file of a run's signals (:class:`MatWriter`, ``--mat``)."""
from __future__ import annotations

from dsim.master.recording.observers.base import RunInfo
from dsim.master.recording.observers.file_writer import FileWriter
from dsim.master.recording.results import mat_bytes


class MatWriter(FileWriter):
    """A MATLAB .mat file of the run's signals
    (:func:`dsim.master.recording.results.mat_bytes`)."""

    kind = "mat"

    def started(self, info: RunInfo) -> None:
        super().started(info)
        self.units = info.units

    def content(self, result) -> bytes | None:
        return mat_bytes(result.signals, self.units) if result.signals else None
