"""``dsim sweep --backend ray``: the points of a sweep side by side, one per Ray worker.

Each point is an independent run: a Ray task (one CPU) that runs it in-process
inside its worker and returns its result, with its results CSV and statistics as
bytes that the driver writes into the sweep's folder (so a worker on another
machine needs no shared folder).  The driver keeps one point per CPU of the cluster
in flight, hands points on as they finish and submits the next.  SIGINT or SIGTERM
on the driver raise a flag (a small actor) that every running point looks at
between steps: it ends after its current step, as interrupted, with its converged
steps kept; no further point is submitted.

A point lost to the infrastructure is run again from its start: one lost with a node
(a node of the cluster was lost meanwhile) up to ``restarts`` times (default 3), then
it is ``lost`` (a rerun of the sweep runs it again); one whose worker died while every
node stayed once more, and if it dies again it ``failed`` (its FMU ends its process).
A lost head (its GCS) ends the sweep within seconds (the head watch of ray_cluster.py):
the points under way are ``lost``, the finished ones kept; :class:`HeadLost` says which.
"""
from __future__ import annotations

import atexit
import os
import signal
import sys
import tempfile
import threading
import time as clock
from pathlib import Path

from dsim.master.api import prepare
from dsim.master.errors import InputError, SimulationError
from dsim.master.recording.observers import CsvRecorder, Observer, StatisticsWriter
from dsim.master.recording.output_files import write_whole
from dsim.master.recording.results import RunResult
from dsim.master.running.backends.ray_recovery import RESTARTS
from dsim.master.running.execution import Execution
from dsim.master.running.ray_cluster import Shipment, connect, landed, listening, watch_head
from dsim.master.sweeps.point import PointRun, keywords

#: the settings that choose where the sweep runs, not how each point runs
WHERE = ("backend", "address", "restarts")
#: seconds between two looks of a running point at the stop flag
POLL_SECONDS = 0.25
#: seconds the sweep has to end once its head is lost before the process is ended
#: anyway (a call into Ray that waits for the lost head: Ray would wait a minute)
HEAD_DEADLINE = 20.0


class HeadLost(SimulationError):
    """The cluster's head was lost during a sweep: the points under way are lost
    (``lost``: their numbers), the finished ones kept."""

    def __init__(self, message: str, lost: list[int]):
        super().__init__(message)
        self.lost = lost

    def __reduce__(self):
        return type(self), (self.message, self.lost)


class StopFlag:
    """The Ray actor that tells the running points to stop: the signal number, or 0."""

    def __init__(self):
        self.number = 0

    def set(self, number: int) -> None:
        self.number = number

    def get(self) -> int:
        return self.number


def run_points(scene, configurations, fixed: dict, out: Path, inputs, finish,
               where: dict | None = None) -> None:
    """Run every configuration (``(k, settings and parameters)`` pairs, with the
    ``fixed`` settings) as a Ray task; call ``finish(k, PointRun)`` for each as it
    ends, its files written in ``out`` as ``point_{k + 1:03d}``.  ``where``: more
    keywords of every point's run (the sweep's ``allow_outside`` folders)."""
    connection = connect(fixed.get("address"))
    ray = connection.ray
    # the flag on the driver's own node: anywhere else its node may be lost (Ray put it
    # on a node already lost, still "alive" to the head, and the running points failed;
    # imported here: Ray is an optional extra)
    from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

    here = NodeAffinitySchedulingStrategy(ray.get_runtime_context().get_node_id(), soft=False)
    stop = ray.remote(StopFlag).options(num_cpus=0, scheduling_strategy=here).remote()
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
    # never left to Ray's own timeouts: the sweep's watch of the head ends it in seconds
    head_lost: list[str] = []
    over = threading.Event()
    watch_head(ray, lambda what: _head_lost(what, head_lost, over), over.is_set)
    try:
        # an .ssp archive holds the whole scene: it travels; a folder must be shared
        archive = Path(scene).is_file() and Path(scene).suffix.lower() == ".ssp"
        shipped = Shipment(ray).add(scene) if archive else None
        point_settings = {k: v for k, v in fixed.items() if k not in WHERE}
        task = ray.remote(_run_remote).options(num_cpus=1, max_retries=0)
        waiting = list(configurations)[::-1]
        chosen = dict(configurations)
        limit = RESTARTS if fixed.get("restarts") is None else int(fixed["restarts"])
        losses: dict[int, list[str]] = {}
        nodes = {node["NodeID"] for node in ray.nodes() if node.get("Alive")}
        width = max(1, connection.cpus())
        pending: dict = {}
        while (waiting or pending) and not head_lost:
            # one point per CPU in flight: after an interrupt, none more
            while waiting and len(pending) < width and not caught and not head_lost:
                k, settings = waiting.pop()
                pending[task.remote(str(scene), shipped, {**point_settings, **settings},
                                    f"point_{k + 1:03d}", stop, where or {})] = k
            if not pending:
                break
            done, _ = ray.wait(list(pending), num_returns=1, timeout=0.5)
            for ref in done:
                if head_lost:
                    break
                k = pending.pop(ref)
                run = _collect(ray, ref, out / f"point_{k + 1:03d}.csv", inputs, nodes)
                if isinstance(run, _LostPoint):
                    run = _again(k, run, losses.setdefault(k, []), limit)
                    if run is None and not caught:
                        waiting.append((k, chosen[k]))  # next, before the others
                        continue
                    run = run or PointRun(RunResult(
                        "interrupted", "lost with its worker, not run again: the sweep was "
                        "interrupted", 0.0, 0, statistics={}), wall_seconds=0.0)
                finish(k, run)
        if head_lost:
            lost = sorted(k + 1 for k in pending.values())
            for k in sorted(pending.values()):
                finish(k, PointRun(RunResult(
                    "lost", f"{head_lost[0]} while the point ran; a rerun of the sweep runs "
                    "it again", 0.0, 0, statistics={}), wall_seconds=0.0))
            named = ", ".join(map(str, lost)) or "none"
            raise HeadLost(f"{head_lost[0]}: the points under way are lost ({named}; a "
                           "rerun of the sweep into the same folder runs them and those "
                           "not started), the finished points are kept", lost)
    finally:
        over.set()
        for number, handler in previous.items():
            signal.signal(number, handler)
        if not head_lost:  # without a head these calls wait for it (a minute)
            ray.kill(stop)
            connection.close()
        else:  # and so does Ray's own shutdown when the process exits (seconds)
            atexit.unregister(ray.shutdown)


def _head_lost(what: str, said: list[str], over: threading.Event) -> None:
    """The head watch's news: the sweep's loop ends at its next look (half a second);
    if something waits on Ray instead, the process ends at the deadline, exit 1."""
    said.append(what)

    def deadline():
        if not over.is_set():
            print(f"dsim: sweep failed: {what}; the sweep did not end within "
                  f"{HEAD_DEADLINE:g} s: ended now, the finished points are kept",
                  file=sys.stderr, flush=True)
            os._exit(1)

    timer = threading.Timer(HEAD_DEADLINE, deadline)
    timer.daemon = True
    timer.start()


class _LostPoint:
    """A point whose worker was lost: Ray's words, and whether a node was lost too."""

    def __init__(self, said: str, node_lost: bool):
        self.said, self.node_lost = said, node_lost


def _again(k: int, lost: _LostPoint, said: list[str], limit: int) -> PointRun | None:
    """None when point ``k`` is to run again after ``lost``, else how it ended: lost
    (with a node, over and over) or failed (its worker died twice, every node there)."""
    said.append(lost.said)
    if lost.node_lost:
        if len(said) <= limit:
            return None
        return PointRun(RunResult("lost", f"lost with a node of the cluster {len(said)} "
                                  f"times ({lost.said}); a rerun of the sweep runs it again",
                                  0.0, 0, statistics={}), wall_seconds=0.0)
    if len(said) < 2:
        return None  # a killed worker, or an FMU that ends its process: once more
    return PointRun(RunResult("failed", "the worker process running the point died twice, "
                              f"every node of the cluster there: the FMU ends its process "
                              f"({lost.said})", 0.0, 0, statistics={}), wall_seconds=0.0)


def _collect(ray, ref, results: Path, inputs, nodes: set) -> PointRun | _LostPoint:
    """The point's run, its files written at ``results``; _LostPoint when its worker
    was lost (killed, its FMU crashed, its node lost: one of ``nodes``, those there
    when the sweep began)."""
    try:
        answer = ray.get(ref)
    except ray.exceptions.RayTaskError as error:  # dsim's own, a bug: said as it is
        message = f"the point's task failed: {str(error).splitlines()[0]}"
        return PointRun(RunResult("failed", message, 0.0, 0, statistics={}), wall_seconds=0.0)
    except ray.exceptions.RayError as error:
        return _LostPoint(str(error).strip().splitlines()[0], _a_node_lost(ray, nodes))
    run, files = answer
    if run.result is not None:
        for suffix, data in files.items():
            write_whole(results.with_suffix(suffix), data, inputs)
        run.results = results
    return run


def _a_node_lost(ray, nodes: set) -> bool:
    """Whether one of ``nodes`` (ids) is gone: the cluster says so, or its raylet no
    longer listens (the cluster learns of it only after its health checks)."""
    try:
        head = str(ray.get_runtime_context().gcs_address)
    except Exception:
        head = ""
    host, _, port = head.rpartition(":")
    if host and port.isdigit() and not listening(host, int(port)):
        return True  # the head itself is gone (asking it would wait a minute)
    try:
        found = [node for node in ray.nodes() if node.get("NodeID") in nodes]
    except Exception:  # the head itself is gone
        return True
    for node in found:
        if not node.get("Alive"):
            return True
        if "NodeManagerPort" not in node or not listening(node.get("NodeManagerAddress", ""),
                                                          node["NodeManagerPort"]):
            return True
    return False


class _StopWhenAsked(Observer):
    """Ends its run after the current step once the flag is up.  It asks every
    ``POLL_SECONDS`` and looks at the answer without waiting for it: a task that
    waits on Ray lends its CPU to another task, which would start a point too many."""

    def __init__(self, flag):
        self.flag = flag
        self.execution = None
        self._asked = None
        self._when = clock.monotonic()
        #: the flag is lost (with the driver's node, or the driver): nobody can ask
        #: this point to stop any more, and that is no reason for it to fail
        self.lost = False

    def stepped(self, record):
        import ray

        if self.lost:
            return
        if self._asked is None:
            if clock.monotonic() - self._when >= POLL_SECONDS:
                self._asked, self._when = self.flag.get.remote(), clock.monotonic()
            return
        if not ray.wait([self._asked], timeout=0)[0]:
            return
        try:
            number, self._asked = ray.get(self._asked), None
        except ray.exceptions.RayError:
            self.lost, self._asked = True, None
            return
        if number:
            self.execution.stop(f"interrupted by {signal.Signals(number).name}", number)


def _run_remote(scene: str, shipped, settings: dict, name: str, flag, where=None):
    """A point in a Ray worker: (PointRun, {suffix: file bytes}); ``where``: more
    keywords of its run (``allow_outside``)."""

    if shipped is not None:
        scene = landed(shipped)
    with tempfile.TemporaryDirectory(prefix="dsim-point-") as folder:
        results = Path(folder) / f"{name}.csv"
        statistics = results.with_suffix(".stats.json")
        start = clock.perf_counter()
        try:
            plan = prepare(scene, **keywords(settings), **(where or {}))
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
