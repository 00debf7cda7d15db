"""``dsim sweep --backend ray``: the points of a sweep side by side, one per Ray worker.

Each point is an independent run: a Ray task (one CPU) that runs it in-process
inside its worker and returns its result, with its results CSV and statistics as
bytes that the driver writes into the sweep's folder (so a worker on another
machine needs no shared folder).  The driver keeps one point per CPU of the cluster
in flight, hands points on as they finish and submits the next.  SIGINT or SIGTERM
on the driver raise a flag (a small actor) that every running point looks at
between steps: it ends after its current step, as interrupted, with its converged
steps kept; no further point is submitted.
"""
from __future__ import annotations

import signal
import tempfile
import threading
import time as clock
from pathlib import Path

from dsim.master.api import prepare
from dsim.master.errors import InputError
from dsim.master.recording.observers import CsvRecorder, Observer, StatisticsWriter
from dsim.master.recording.output_files import write_whole
from dsim.master.recording.results import RunResult
from dsim.master.running.execution import Execution
from dsim.master.running.ray_cluster import Shipment, connect, landed
from dsim.master.sweeps.point import PointRun, keywords

#: the settings that choose where the sweep runs, not how each point runs
WHERE = ("backend", "address")
#: seconds between two looks of a running point at the stop flag
POLL_SECONDS = 0.25


class StopFlag:
    """The Ray actor that tells the running points to stop: the signal number, or 0."""

    def __init__(self):
        self.number = 0

    def set(self, number: int) -> None:
        self.number = number

    def get(self) -> int:
        return self.number


def run_points(scene, configurations, fixed: dict, out: Path, inputs, finish) -> None:
    """Run every configuration (``(k, settings and parameters)`` pairs, with the
    ``fixed`` settings) as a Ray task; call ``finish(k, PointRun)`` for each as it
    ends, its files written in ``out`` as ``point_{k + 1:03d}``."""
    connection = connect(fixed.get("address"))
    ray = connection.ray
    stop = ray.remote(StopFlag).options(num_cpus=0).remote()
    caught: list[int] = []
    previous = {}

    def on_signal(number, frame):
        if caught and number == signal.SIGINT:
            raise KeyboardInterrupt  # a second Ctrl-C: do not wait for the points
        caught.append(number)
        stop.set.remote(number)

    if threading.current_thread() is threading.main_thread():
        for number in (signal.SIGINT, signal.SIGTERM):
            previous[number] = signal.signal(number, on_signal)
    try:
        # an .ssp archive holds the whole scene: it travels; a folder must be shared
        archive = Path(scene).is_file() and Path(scene).suffix.lower() == ".ssp"
        shipped = Shipment(ray).add(scene) if archive else None
        point_settings = {k: v for k, v in fixed.items() if k not in WHERE}
        task = ray.remote(_run_remote).options(num_cpus=1, max_retries=0)
        waiting = list(configurations)[::-1]
        width = max(1, connection.cpus())
        pending: dict = {}
        while waiting or pending:
            # one point per CPU in flight: after an interrupt, none more
            while waiting and len(pending) < width and not caught:
                k, settings = waiting.pop()
                pending[task.remote(str(scene), shipped, {**point_settings, **settings},
                                    f"point_{k + 1:03d}", stop)] = k
            if not pending:
                break
            done, _ = ray.wait(list(pending), num_returns=1, timeout=0.5)
            for ref in done:
                k = pending.pop(ref)
                finish(k, _collect(ray, ref, out / f"point_{k + 1:03d}.csv", inputs))
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
        ray.kill(stop)
        connection.close()


def _collect(ray, ref, results: Path, inputs) -> PointRun:
    """The point's run, its files written at ``results``."""
    try:
        answer = ray.get(ref)
    except ray.exceptions.RayError as error:  # the worker died (an FMU crashed it)
        message = f"the worker process running the point died: {str(error).splitlines()[0]}"
        return PointRun(RunResult("failed", message, 0.0, 0, statistics={}), wall_seconds=0.0)
    run, files = answer
    if run.result is not None:
        for suffix, data in files.items():
            write_whole(results.with_suffix(suffix), data, inputs)
        run.results = results
    return run


class _StopWhenAsked(Observer):
    """Ends its run after the current step once the flag is up.  It asks every
    ``POLL_SECONDS`` and looks at the answer without waiting for it: a task that
    waits on Ray lends its CPU to another task, which would start a point too many."""

    def __init__(self, flag):
        self.flag = flag
        self.execution = None
        self._asked = None
        self._when = clock.monotonic()

    def stepped(self, record):
        import ray

        if self._asked is None:
            if clock.monotonic() - self._when >= POLL_SECONDS:
                self._asked, self._when = self.flag.get.remote(), clock.monotonic()
            return
        if not ray.wait([self._asked], timeout=0)[0]:
            return
        number, self._asked = ray.get(self._asked), None
        if number:
            self.execution.stop(f"interrupted by {signal.Signals(number).name}", number)


def _run_remote(scene: str, shipped, settings: dict, name: str, flag):
    """A point in a Ray worker: (PointRun, {suffix: file bytes})."""

    if shipped is not None:
        scene = landed(shipped)
    with tempfile.TemporaryDirectory(prefix="dsim-point-") as folder:
        results = Path(folder) / f"{name}.csv"
        statistics = results.with_suffix(".stats.json")
        start = clock.perf_counter()
        try:
            plan = prepare(scene, **keywords(settings))
        except InputError as error:
            return PointRun(problems=list(error.problems)), {}
        watcher = _StopWhenAsked(flag)
        execution = Execution(plan, [CsvRecorder(results), StatisticsWriter(statistics),
                                     watcher])
        watcher.execution = execution
        try:
            result = execution.run(handle_signals=False)
        except InputError as error:
            return PointRun(problems=list(error.problems)), {}
        wall = clock.perf_counter() - start
        result._signals = result.signals  # read now: the folder goes with the task
        result.files = {}
        files = {path.suffix if path.suffix == ".csv" else ".stats.json": path.read_bytes()
                 for path in (results, statistics) if path.is_file()}
        return PointRun(result, wall_seconds=wall), files
