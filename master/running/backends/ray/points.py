"""``dsim sweep --backend ray``: the points of a sweep side by side, one per Ray worker.

Each point is an independent run: a Ray task (one CPU) that runs it in-process
inside its worker (the sweep's own function,
:func:`dsim.master.sweeps.point.run_in_worker`) and returns its result, with its
results CSV and statistics as bytes that the driver hands to the sweep, which writes
them into its folder (so a worker on another machine needs no shared folder).  This
module knows Ray, not what a point is.  The driver keeps one point per CPU of the
cluster in flight, hands points on as they finish and submits the next.  SIGINT or
SIGTERM on the driver raise a flag (a small actor) that every running point looks at
between steps: it ends after its current step, as interrupted, with its converged
steps kept; no further point is submitted.

A point lost to the infrastructure is run again from its start: one lost with a node
(a node of the cluster was lost meanwhile) up to ``restarts`` times (default 3), then
it is ``lost`` (a rerun of the sweep runs it again); one whose worker died while every
node stayed once more, and if it dies again it ``failed`` (its FMU ends its process).
A lost head (its GCS) ends the sweep within seconds (the head watch of cluster.py):
the points under way are ``lost``, the finished ones kept; :class:`HeadLost` says which.
"""
from __future__ import annotations

import atexit
import os
import signal
import sys
import threading
import time as clock
from pathlib import Path

from dsim.master.errors import SimulationError
from dsim.master.running.backends.ray.cluster import (Shipment, connect, landed, listening,
                                                      watch_head)
from dsim.master.running.backends.ray.recovery import RESTARTS

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


def run_points(scene, configurations, fixed: dict, finish, work, ended) -> None:
    """Run every configuration (``(k, settings and parameters)`` pairs, with the
    ``fixed`` settings) as a Ray task: ``work(scene, settings, name, stop_requested)``
    in a worker (a module-level function: Ray ships it by name), which returns
    ``(run, files)``, files as ``{suffix: bytes}``; ``stop_requested()`` is 0 or the
    number of the signal that interrupted the sweep.  ``finish(k, run, files)`` is
    called on this process for each as it ends; ``ended(status, message)`` makes the
    run of a point that did not run (lost, failed), with no files."""
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
                pending[task.remote(work, str(scene), shipped,
                                    {**point_settings, **settings}, f"point_{k + 1:03d}",
                                    stop)] = k
            if not pending:
                break
            done, _ = ray.wait(list(pending), num_returns=1, timeout=0.5)
            for ref in done:
                if head_lost:
                    break
                k = pending.pop(ref)
                answer = _collect(ray, ref, nodes, ended)
                if isinstance(answer, _LostPoint):
                    run = _again(k, answer, losses.setdefault(k, []), limit, ended)
                    if run is None and not caught:
                        waiting.append((k, chosen[k]))  # next, before the others
                        continue
                    answer = (run or ended("interrupted", "lost with its worker, not run "
                                           "again: the sweep was interrupted"), {})
                finish(k, *answer)
        if head_lost:
            lost = sorted(k + 1 for k in pending.values())
            for k in sorted(pending.values()):
                finish(k, ended("lost", f"{head_lost[0]} while the point ran; a rerun of "
                                "the sweep runs it again"), {})
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


def _again(k: int, lost: _LostPoint, said: list[str], limit: int, ended):
    """None when point ``k`` is to run again after ``lost``, else how it ended: lost
    (with a node, over and over) or failed (its worker died twice, every node there)."""
    said.append(lost.said)
    if lost.node_lost:
        if len(said) <= limit:
            return None
        return ended("lost", f"lost with a node of the cluster {len(said)} times "
                     f"({lost.said}); a rerun of the sweep runs it again")
    if len(said) < 2:
        return None  # a killed worker, or an FMU that ends its process: once more
    return ended("failed", "the worker process running the point died twice, every node "
                 f"of the cluster there: the FMU ends its process ({lost.said})")


def _collect(ray, ref, nodes: set, ended):
    """The point's ``(run, files)``; _LostPoint when its worker was lost (killed, its
    FMU crashed, its node lost: one of ``nodes``, those there when the sweep began)."""
    try:
        return ray.get(ref)
    except ray.exceptions.RayTaskError as error:  # dsim's own, a bug: said as it is
        return ended("failed", f"the point's task failed: {str(error).splitlines()[0]}"), {}
    except ray.exceptions.RayError as error:
        return _LostPoint(str(error).strip().splitlines()[0], _a_node_lost(ray, nodes))


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


class _StopRequested:
    """``stop_requested()`` for a point's run: 0, or the number of the signal that
    interrupted the sweep.  It asks the flag every ``POLL_SECONDS`` and looks at the
    answer without waiting for it: a task that waits on Ray lends its CPU to another
    task, which would start a point too many."""

    def __init__(self, flag):
        self.flag = flag
        self._asked = None
        self._when = clock.monotonic()
        #: the flag is lost (with the driver's node, or the driver): nobody can ask
        #: this point to stop any more, and that is no reason for it to fail
        self.lost = False

    def __call__(self) -> int:
        import ray

        if self.lost:
            return 0
        if self._asked is None:
            if clock.monotonic() - self._when >= POLL_SECONDS:
                self._asked, self._when = self.flag.get.remote(), clock.monotonic()
            return 0
        if not ray.wait([self._asked], timeout=0)[0]:
            return 0
        try:
            number, self._asked = ray.get(self._asked), None
        except ray.exceptions.RayError:
            self.lost, self._asked = True, None
            return 0
        return number


def _run_remote(work, scene: str, shipped, settings: dict, name: str, flag):
    """A point in a Ray worker: what ``work`` returns, ``(run, {suffix: file bytes})``."""
    if shipped is not None:
        scene = landed(shipped)
    return work(scene, settings, name, _StopRequested(flag))
