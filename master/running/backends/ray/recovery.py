"""What the Ray backends do when a worker, a node or the head is lost
(docs/distributed.md, "What survives what"): :class:`Recovery`, mixed into
:class:`~dsim.master.running.backends.ray.backend.RayBackend`.

Every :data:`CHECKPOINT_EVERY` macro steps, at ``begin_step``, each worker that can be
started again sends the saved state of its subsystems, serialized
(:data:`~dsim.master.running.backends.ray.worker.CHECKPOINT`), and the driver keeps it
with the calls answered since (the journal: the batches as they were sent).  When a call finds
its worker lost, a fresh worker (on a node that is left) instantiates the same FMUs,
goes on from that state, takes the journal's calls again and answers the lost call: the
numbers are an undisturbed run's, bit for bit.  The words for what was lost (a lost
node, a killed worker, a crashed FMU), the statistics of every loss, the progress
line's "no answer for N s" and the watch of the head's GCS are here too.
"""
from __future__ import annotations

import pickle
import time as clock

from dsim.master.errors import SimulationError
from dsim.master.running.fmi import serialization_problem
from dsim.master.running.backends.ray.spares import NEW
from dsim.master.running.backends.ray.worker import (CHECKPOINT, FAILED, RESUME, Host,
                                                     crash_report)
from dsim.master.running.backends.ray.cluster import listening as _listening
from dsim.master.running.backends.ray.cluster import ray_log, watch_head

#: workers started again in one run, at most, when no ``restarts`` setting says
RESTARTS = 3
#: seconds a worker started again may take to start (no node left: the run ends)
RESTART_SECONDS = 60.0
#: seconds without an answer from a worker before the progress line names it
LATE_SECONDS = 3.0
#: macro steps between two checkpoints (each subsystem's saved state, serialized by
#: its worker and sent to the driver): a lost worker takes the calls of this many
#: steps again at most.  Sending them every step took a step of chain_10000 on two
#: workers 0.96 to 1.00 s, every 4 steps 0.78 to 0.81 s, every 8 0.75 to 0.83 s (the
#: least and the median of a run's steps, 2026-11-27, in turn; in-process, medians
#: of three runs, 0.87 to 0.90 s)
CHECKPOINT_EVERY = 4
#: batches a worker's journal keeps as sent before it is boiled down to each
#: subsystem's calls since its checkpoint (Recovery._journal): a worker whose every
#: subsystem is saved has two or three a step until the next checkpoint clears them
LOG_BATCHES = 32


class Recovery:
    """The lost-worker half of :class:`~dsim.master.running.backends.ray.backend.RayBackend`
    (it has ``_cluster``: the workers, their specs, checkpoints and journal, the losses)."""

    # --- a lost worker ---------------------------------------------------------
    def _restartable(self, host: int) -> bool:
        cluster = self._cluster
        return cluster.restarts_left > 0 and cluster.unrestartable[host] is None

    def _journal(self, host: int, payload, results, kept) -> None:
        """Keep what a fresh worker needs to take over ``host``: each subsystem's last
        checkpoint, and the batch ``payload`` as sent (``kept``, :attr:`_Cluster.log`).
        A batch is kept as the bytes it was sent as, not loaded back, and looked into
        only when a worker is lost (:meth:`_journaled`): loading and sorting every
        call of every batch took the driver 0.08 s a step of chain_10000."""
        cluster = self._cluster
        if not self._restartable(host):
            cluster.log[host] = []  # never read again (no restart left, or none possible)
            return
        saved = set()
        for (slot, calls), answered in zip(payload, results):
            for call, result in zip(calls, answered):
                if call[0] != CHECKPOINT:
                    continue
                if type(result) is dict:  # {"error": ...}: it said it could, and cannot
                    cluster.unrestartable[host] = (
                        f"component '{cluster.owners[host][slot]}' could not serialize "
                        f"its state ({result['error']})")
                    cluster.log[host] = []
                    return
                cluster.checkpoints[(host, slot)] = result
                saved.add(slot)
        log = cluster.log[host]
        if len(saved) == len(cluster.owners[host]):  # what came before is needed no more
            log.clear()
        log.append((kept, None))
        if len(log) > LOG_BATCHES:  # a subsystem that is never saved (in no joint)
            cluster.log[host] = [([(slot, calls) for slot, calls
                                   in self._journaled(host).items() if calls], None)]

    def _journal_failed(self, host: int, at, kept) -> None:
        """Keep the batch ``kept`` that worker ``host`` answered up to a call that
        raised an error (at (entry, call)): the calls before it and that one are taken
        again as they were (a discarded step the coupling then cuts); without ``at``
        the worker cannot be rebuilt until its next checkpoint."""
        cluster = self._cluster
        if not self._restartable(host):
            return
        if at is None:
            cluster.unrestartable[host] = ("a call failed on its worker in this step and "
                                           "the calls made before it are not known")
            return
        cluster.log[host].append((kept, at))

    def _journaled(self, host: int) -> dict[int, list]:
        """Slot -> the calls of worker ``host``'s subsystem since its last checkpoint,
        as they were sent (from :attr:`_Cluster.log`)."""
        calls_of: dict[int, list] = {}
        for kept, stopped in self._cluster.log[host]:
            payload = pickle.loads(kept) if isinstance(kept, bytes) else kept
            if stopped is None:
                for slot, calls in payload:
                    journal = calls_of.setdefault(slot, [])
                    for call in calls:
                        if call[0] == CHECKPOINT:  # answered: the slot's new start
                            journal.clear()
                        else:
                            journal.append(call)
                continue
            entry, failed = stopped  # the calls made before the error, checkpoints too
            for n, (slot, calls) in enumerate(payload[:entry + 1]):
                journal = calls_of.setdefault(slot, [])
                journal.extend(calls if n < entry else calls[:failed])
                if n == entry:
                    journal.append((FAILED, calls[failed]))
        return calls_of

    def _lost(self, host: int, error) -> dict:
        """What was lost with worker ``host`` (a record for the statistics; "said":
        the words for it)."""
        cluster = self._cluster
        ray = cluster.connection.ray
        place = cluster.places[host] or {}
        pid, node_id = place.get("pid", "?"), place.get("node")
        text = str(error)
        try:
            node = next((n for n in ray.nodes() if n.get("NodeID") == node_id), {})
        except Exception:  # the head itself is gone: Ray cannot say
            node = {}
        address = node.get("NodeManagerAddress") or _field(text, "ip") or "?"
        # the cluster learns of a lost node only after its health checks (many
        # seconds): a raylet that no longer listens is a lost node now
        port = node.get("NodeManagerPort")
        node_lost = bool(node and not node.get("Alive", True)) or \
            bool(port and address != "?" and not _listening(address, int(port))) or \
            any(words in text.lower() for words in ("node has died", "node died",
                                                    "node is dead", "raylet died",
                                                    "node was terminated"))
        report = None
        if not node_lost:
            try:
                here = ray.get_runtime_context().get_node_id() == node_id
            except Exception:
                here = False
            report = crash_report(pid) if here and isinstance(pid, int) else None
        if report:
            what, said = "crashed FMU", (f"the FMU crashed its worker process (pid {pid}): "
                                         f"{report}")
        elif node_lost:
            what, said = "lost node", (f"lost node {address}" + (f":{port}" if port else "")
                                       + f" (its raylet; the worker process, pid {pid}, with "
                                       "it)")
        elif isinstance(error, ray.exceptions.RayActorError):
            # Ray does not say how a process ended: no crash report, and it is started
            # again, was a kill; one that cannot be started again may be its FMU's exit
            what, said = "killed worker", (
                f"the worker process (pid {pid}) on node {address} was killed (no crash "
                "report from its FMU)" if self._restartable(host) else
                f"the worker process (pid {pid}) on node {address} ended without a crash "
                "report (killed, or its FMU ended the process)")
        else:
            what, said = "lost worker", f"Ray lost the worker: {_first_line(error)}"
        return {"time": cluster.time, "node": node_id, "address": address, "pid": pid,
                "components": list(cluster.owners[host]), "what": what, "said": said,
                "ray_error": " ".join(text.split())[:600]}

    def _recover(self, host: int, payload, error, kept=None):
        """Start worker ``host`` again from its subsystems' checkpoints, take their
        calls since, and answer ``payload`` (the call that was lost; ``kept``: as the
        journal keeps it); SimulationError
        when it cannot be, saying what was lost and why it was not started again."""
        cluster = self._cluster
        ray = cluster.connection.ray
        who = _who(cluster.owners[host])
        started = clock.perf_counter()
        lost = self._lost(host, error)
        cluster.dead.add(host)
        cluster.losses.append(lost)
        try:
            ray.kill(cluster.hosts[host])  # unreachable (its node cut off) is not dead
        except Exception:
            pass
        again = False
        while True:
            why = None
            if lost["what"] == "crashed FMU":
                why = ""
            elif again and lost["what"] != "lost node":
                why = ("it was lost again when the call was taken again: the FMU ends its "
                       "worker process")
            elif cluster.unrestartable[host] is not None:
                why = f"not started again: {cluster.unrestartable[host]}"
            elif cluster.restarts_left <= 0:
                why = (f"not started again: a run starts {cluster.restarts} lost workers "
                       "again at most (--restarts)")
            if why is not None:
                lost["recovered"] = False
                raise SimulationError(f"{who}: {lost['said']}" + (f"; {why}" if why else ""),
                                      time=cluster.time) from None
            cluster.restarts_left -= 1
            try:
                results = self._restart(host, payload)
            except _Lost as again_lost:
                lost["recovered"] = False
                lost = self._lost(host, again_lost.error)
                cluster.losses.append(lost)
                again = True
                continue
            except _Answered as answered:  # started again; the call raised its error
                self._recovered(lost, host, started)
                self._journal_failed(host, answered.at, kept)
                raise answered.cause from None
            except SimulationError as failed:
                lost["recovered"] = False
                raise SimulationError(f"{who}: {lost['said']}; starting it again failed: "
                                      f"{failed}", time=cluster.time) from None
            self._recovered(lost, host, started)
            return results

    def _recovered(self, lost: dict, host: int, started: float) -> None:
        lost["recovered"] = True
        lost["recovery_seconds"] = clock.perf_counter() - started
        lost["new_worker"] = dict(self._cluster.places[host])
        self._cluster.dead.discard(host)

    def _restart(self, host: int, payload):
        """A fresh worker for ``host`` brought to where the lost one was, then
        ``payload`` answered by it; _Lost when it is lost too."""
        cluster = self._cluster
        ray = cluster.connection.ray
        options = cluster.options[host]
        placement = next(iter(options.get("resources", {})), "")
        # the cluster learns of a lost node late: a node lost in this run is no choice
        gone = {loss["node"] for loss in cluster.losses if loss["what"] == "lost node"}
        alive = [n for n in ray.nodes() if n.get("Alive") and n.get("NodeID") not in gone]
        pinned = getattr(options.get("scheduling_strategy"), "node_id", None)
        if pinned and pinned not in {n["NodeID"] for n in alive}:
            gone.add(pinned)  # its node is gone too, whatever the words said
        if not alive:
            raise SimulationError("no node of the cluster is left")
        if placement and not any(n.get("Resources", {}).get(placement) for n in alive):
            # the placed node is gone: the run goes on wherever there is room
            options = {k: v for k, v in options.items() if k != "resources"}
            options["scheduling_strategy"] = "SPREAD"
            cluster.options[host] = options
            cluster.losses[-1]["moved_from"] = placement
        if gone:  # on a node that is left, the one with the fewest of this run's workers
            from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

            fitting = [n for n in alive if not placement or "resources" not in options
                       or n.get("Resources", {}).get(placement)]
            load = [sum(1 for p in cluster.places if p and p.get("node") == n["NodeID"])
                    for n in fitting]
            chosen = fitting[load.index(min(load))]["NodeID"]
            options = {**options, "scheduling_strategy":
                       NodeAffinitySchedulingStrategy(node_id=chosen, soft=False)}
        worker = ray.remote(Host).options(**options).remote()
        opened = worker.open.remote(cluster.specs[host], cluster.files[host])
        ready, _ = ray.wait([opened], timeout=RESTART_SECONDS)
        if not ready:
            ray.kill(worker)
            raise SimulationError(f"no worker started in {RESTART_SECONDS:g} s (no node "
                                  "left with room for it?)")
        try:
            place = ray.get(opened)
        except ray.exceptions.RayTaskError as failed:
            raise SimulationError(str(_cause(failed))) from None
        except ray.exceptions.RayError as failed:
            raise _Lost(failed) from None
        cluster.hosts[host], cluster.places[host] = worker, {**place, "started": NEW}
        replay, journaled = [], self._journaled(host)
        for slot in range(len(cluster.owners[host])):
            checkpoint = cluster.checkpoints[(host, slot)]
            calls = ([(RESUME, (checkpoint,))] if checkpoint else []) + \
                journaled.get(slot, [])
            if calls:
                replay.append((slot, calls))
        try:
            results = ray.get(worker.run.remote(replay + list(payload)),
                              timeout=cluster.call_timeout)
        except ray.exceptions.RayTaskError as failed:
            cause = _cause(failed)
            at = getattr(cause, "dsim_at", None)
            if at is None or at[0] < len(replay):  # the calls taken again went otherwise
                raise SimulationError(f"taking its calls again failed: {cause}") from None
            # the lost call itself raised, as it would have on the lost worker
            raise _Answered(cause, (at[0] - len(replay), at[1])) from None
        except ray.exceptions.GetTimeoutError:
            ray.kill(worker)
            raise SimulationError(f"no answer in {cluster.call_timeout:g} s "
                                  "(--call-timeout)") from None
        except ray.exceptions.RayError as failed:
            raise _Lost(failed) from None
        return results[len(replay):]

    def waiting(self) -> str | None:
        """Which components have not answered for how long, once that is more than
        :data:`LATE_SECONDS` (a frozen worker, a node cut off, a slow FMU); else None.
        Safe from any thread (the progress line asks it)."""
        waiting = self._cluster.waiting
        if waiting is None:
            return None
        host, since = waiting
        seconds = clock.monotonic() - since
        if seconds < LATE_SECONDS:
            return None
        return f"{_who(self._cluster.owners[host])}: no answer for {seconds:.0f} s"

    def watch_head(self, on_lost) -> None:
        """Call ``on_lost(what)`` from a thread of its own when the cluster's head (its
        GCS) stops answering (:func:`~dsim.master.running.backends.ray.cluster.watch_head`)."""
        cluster = self._cluster
        watch_head(cluster.connection.ray,
                   lambda what: on_lost(f"{what}: no worker can be reached"),
                   lambda: cluster.closed)

    def losses(self) -> list[dict]:
        """Every worker lost in the run: time (s, simulated), node (Ray id and
        address), pid, components, what (lost node, killed worker, crashed FMU),
        whether it was started again and how long that took (s), message."""
        log = ray_log()
        said = {"ray_log": str(log)} if log.exists() else {}  # what Ray said meanwhile
        return [{k: v for k, v in loss.items() if k != "said"} | {"message": loss["said"]}
                | said for loss in self._cluster.losses]

    def notes(self) -> list[str]:
        """What a user should know before the run: a placement that cannot hold (fewer
        nodes than workers to spread), the components whose worker cannot be started
        again if it is lost."""
        cluster = self._cluster
        notes = list(cluster.notes)
        if cluster.restarts_left <= 0:
            return notes
        reasons = sorted({why for why in cluster.unrestartable if why})
        return notes + [f"a lost worker ends the run: {why}" for why in reasons]


class _Answered(Exception):
    """The call taken again on a worker started again raised ``cause`` (at ``at``)."""

    def __init__(self, cause, at):
        super().__init__(str(cause))
        self.cause, self.at = cause, at


class _Lost(Exception):
    """A worker started again was lost too (``error``: Ray's)."""

    def __init__(self, error):
        super().__init__(str(error))
        self.error = error


def _unrestartable(specs) -> str | None:
    """Why a worker with these subsystems cannot be started again from a saved state
    (the first of them that cannot serialize it), or None."""
    for spec in specs:
        if spec.table is None and (spec.interface != "CoSimulation"
                                   or not spec.fmi_version.startswith("2")):
            return (f"component '{spec.name}' runs FMI {spec.fmi_version} "
                    f"{spec.interface}, whose state dsim does not move between processes "
                    "yet")
        problem = serialization_problem(spec)
        if problem:
            return problem
    return None


def _field(text: str, name: str) -> str | None:
    """The value of a ``name: value`` line of a Ray error."""
    for line in text.splitlines():
        key, _, value = line.strip().partition(": ")
        if key == name:
            return value.strip()
    return None


def _who(names) -> str:
    return f"component {_quoted(names)}" if len(names) == 1 else \
        f"components {_quoted(names)} (one worker process)"


def _quoted(names) -> str:
    return ", ".join(f"'{n}'" for n in names)


def _first_line(error) -> str:
    return (str(error).strip().splitlines() or [type(error).__name__])[0]


def _cause(error) -> Exception:
    """The exception a worker raised (dsim's own errors arrive whole)."""
    cause = getattr(error, "cause", None)
    return cause if isinstance(cause, Exception) else error
