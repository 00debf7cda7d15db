"""The PNG plot of a run's signals (:class:`PlotWriter`, ``--plot``)."""
from __future__ import annotations

import io

from dsim.master.recording.observers.base import RunInfo
from dsim.master.recording.observers.file_writer import FileWriter
from dsim.master.recording.results import plot_signals, set_title


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
        # the title says the scene and the values given for this run (--set)
        plot_signals(result.signals, image, self.title or set_title(
            self.scene, result.statistics.get("parameters")), units=self.units)
        return image.getvalue()
