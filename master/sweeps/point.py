"""One point of a sweep as ``dsim sweep`` runs it in this process
(:func:`dsim.master.sweeps.sweep.run_point`) and in a Ray worker (:func:`run_in_worker`,
which :mod:`dsim.master.running.backends.ray.points` ships): the keywords of its run
(:func:`keywords`) and how it ran (:class:`PointRun`)."""
from __future__ import annotations

import math
import signal
import tempfile
import time as clock
from dataclasses import dataclass, field
from pathlib import Path

from dsim.master.api import prepare
from dsim.master.errors import InputError
from dsim.master.recording.observers import CsvRecorder, Observer, StatisticsWriter
from dsim.master.recording.output_files import write_whole
from dsim.master.recording.results import RunResult, statistics_path
from dsim.master.running.execution import Execution
from dsim.master.sweeps.design import split


@dataclass
class PointRun:
    """How one point ran: its :class:`~dsim.master.recording.results.RunResult` (None
    for bad input), the problems of bad input, wall seconds and where its results are."""

    result: object = None
    problems: list = field(default_factory=list)
    wall_seconds: float = math.nan
    results: Path | None = None


def keywords(configuration: dict) -> dict:
    """The keywords of ``dsim.simulate``/``prepare`` for a point: its settings, and its
    model parameters as ``parameters`` (left out when there are none)."""
    settings, parameters = split(configuration)
    return {**settings, "parameters": parameters} if parameters else settings


def ended(status: str, message: str) -> PointRun:
    """A point that did not run to an end of its own (``lost``, ``failed`` with its
    worker, ``interrupted`` before it ran): no steps, no files."""
    return PointRun(RunResult(status, message, 0.0, 0, statistics={}), wall_seconds=0.0)


def keep_files(run: PointRun, files: dict, results: Path, inputs) -> PointRun:
    """Write a worker's point files (``{suffix: bytes}``) at ``results`` (the CSV; the
    statistics beside it), never over an input; ``run`` with its results there."""
    if run.result is not None:
        for suffix, data in files.items():
            write_whole(results.with_suffix(suffix), data, inputs)
        run.results = results
    return run


class _StopWhenAsked(Observer):
    """Ends its run after the current step once ``stop_requested()`` names a signal."""

    def __init__(self, stop_requested):
        self.stop_requested = stop_requested
        self.execution = None

    def stepped(self, record):
        number = self.stop_requested()
        if number:
            self.execution.stop(f"interrupted by {signal.Signals(number).name}", number)


def run_in_worker(scene: str, settings: dict, name: str, stop_requested):
    """One point run in this process, its files as bytes (a worker on another machine
    shares no folder with the sweep): ``(PointRun, {suffix: file bytes})``;
    ``stop_requested()`` is 0 or the number of the signal that interrupted the sweep."""
    with tempfile.TemporaryDirectory(prefix="dsim-point-") as folder:
        results = Path(folder) / f"{name}.csv"
        statistics = statistics_path(results)
        start = clock.perf_counter()
        try:
            plan = prepare(scene, **keywords(settings))
        except InputError as error:
            return PointRun(problems=list(error.problems)), {}
        watcher = _StopWhenAsked(stop_requested)
        execution = Execution(plan, [CsvRecorder(results), StatisticsWriter(statistics),
                                     watcher])
        watcher.execution = execution
        try:
            result = execution.run(handle_signals=False)
        except InputError as error:
            return PointRun(problems=list(error.problems)), {}
        wall = clock.perf_counter() - start
        result.keep_signals()  # read now: the folder goes with the task
        result.files = {}
        files = {path.suffix if path.suffix == ".csv" else ".stats.json": path.read_bytes()
                 for path in (results, statistics) if path.is_file()}
        return PointRun(result, wall_seconds=wall), files
