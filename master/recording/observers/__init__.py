"""Observers: everything that watches a run goes through one interface
(:class:`Observer`, base.py), and only observers write files; one observer per module.

- ``base.py``: :class:`Observer`, :class:`RunInfo`, :class:`StepRecord`
- ``csv_recorder.py``: :class:`CsvRecorder`, the results CSV as the run goes
- ``memory_recorder.py``: :class:`MemoryRecorder`, the signals kept in memory
- ``file_writer.py``: :class:`FileWriter`, one file written as the run ends
- ``statistics_writer.py``: :class:`StatisticsWriter`, the statistics JSON
- ``plot_writer.py``, ``mat_writer.py``: the PNG plot, the .mat file
- ``progress_bar.py``: :class:`ProgressBar` on a terminal
"""
from dsim.master.recording.observers.base import Observer, RunInfo, StepRecord
from dsim.master.recording.observers.csv_recorder import CsvRecorder
from dsim.master.recording.observers.file_writer import FileWriter
from dsim.master.recording.observers.mat_writer import MatWriter
from dsim.master.recording.observers.memory_recorder import MemoryRecorder
from dsim.master.recording.observers.plot_writer import PlotWriter
from dsim.master.recording.observers.progress_bar import ProgressBar
from dsim.master.recording.observers.statistics_writer import (ONE_LINE_EACH, StatisticsWriter,
                                                              statistics_json)

__all__ = ["CsvRecorder", "FileWriter", "MatWriter", "MemoryRecorder", "ONE_LINE_EACH",
           "Observer", "PlotWriter", "ProgressBar", "RunInfo", "StatisticsWriter",
           "StepRecord", "statistics_json"]
