"""The PNG plot of a run's signals (:class:`PlotWriter`, ``--plot``), in the display
units the FMUs declare."""
from __future__ import annotations

import io

from dsim.master.recording.observers.base import RunInfo
from dsim.master.recording.observers.file_writer import FileWriter
from dsim.master.recording.results import in_display_units, plot_signals, set_title


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
        # in the display units the FMUs declare (an angle in deg)
        signals, units = in_display_units(result.signals, self.units,
                                          result.statistics.get("display_units"))
        # the title says the scene and the values given for this run (--set)
        plot_signals(signals, image, self.title or set_title(
            self.scene, result.statistics.get("parameters")), units=units)
        return image.getvalue()
