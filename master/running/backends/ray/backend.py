"""The subsystems in Ray actors: other processes, other machines (docs/distributed.md).

Each worker process is a Ray actor (:class:`Host`) that builds its
:class:`~dsim.master.running.fmi.cs2.CoSimulation2Subsystem` objects itself from
their picklable specs, so an FMU's states never leave the process that holds the
instance.  Every batched call of the couplings is one remote call per worker
(restore, set forces, step and read kinematics of each of its subsystems in one
message), launched for every worker before the first answer is awaited: the workers
step side by side, the perturbation steps of the flexibility too.  The numbers are the in-process
backend's to the last bit: the same CoSimulation2Subsystem code runs, only elsewhere.

``ray``: one worker per FMU instance, at most one per CPU of the cluster (beyond
that, subsystems share workers, dealt round-robin); a component placed with
``glue:Placement`` runs on a node that has the named Ray resource.
``isolated``: one worker process per FMU instance on a local Ray instance, so an FMU
that crashes its process ends the run with a message, never dsim itself.

A lost worker (killed, or gone with its node) does not end the run
(docs/distributed.md, "What survives what"): after every ``begin_step`` each worker
sends the saved state of its subsystems, serialized, and the driver keeps it with the
calls made since; a fresh worker (on a node that is still there) instantiates the
same FMUs, goes on from that state, takes the same calls again and answers the call
that was lost: the numbers are those of an undisturbed run, bit for bit.  At most
``restarts`` workers are started again in a run; an FMU that cannot serialize its
state, an FMU that crashed (it left a crash report) and a worker lost again on the
same call end the run as before, with a line that says which it was.

A run of a driver that joined a Ray instance it did not start takes the spare workers
the run before left and, as it ends, starts new ones for the next (spares.py); a
run that joined a cluster's address itself leaves them in the cluster for the next
command (pool.py): never a process that hosted FMUs, only the start of a process
taken out of a set-up.
"""
from __future__ import annotations

import copy
import pickle
import threading
import time as clock

from dsim.master.errors import InputError, SimulationError
from dsim.master.running.backends.base import Backend
from dsim.master.running.backends.ray.recovery import (CHECKPOINT_EVERY, RESTARTS, Recovery,
                                                       _cause, _first_line, _quoted,
                                                       _unrestartable, _who)
from dsim.master.running.backends.ray import pool, spares
from dsim.master.running.collector import freeze, thaw
from dsim.master.running.backends.ray.placement import Placement
from dsim.master.running.backends.ray.worker import (CHECKPOINT, WORKER_OPTIONS, Host, deal,
                                                     unpack_answers)
from dsim.master.running.backends.ray.cluster import (INSTALL, Shipment, address_problem,
                                                      available, connect, connect_ahead,
                                                      ray_log_line, release, starts_ray)

#: seconds to wait for the workers to start and instantiate their FMUs
START_SECONDS = 300.0
#: what a placed worker takes of its node's resource: little, so that any number of
#: components can share a node (the resource says where, not how many)
PLACEMENT_SHARE = 0.001
#: seconds a worker may take to end its FMUs when the run is over (a frozen one: never)
CLOSE_SECONDS = 10.0


class _Cluster:
    """What the views of one run share: the connection, the workers, where each
    subsystem lives and the last simulated time (to name it when a worker dies)."""

    def __init__(self, connection, hosts, owners):
        #: the last snapshot's key (RayBackend.snapshot)
        self.snapshots = 0
        #: the error control's snapshots that live (any view's), and whether a
        #: checkpoint is due at the next one (none is taken while one lives:
        #: RayBackend.begin_step)
        self.live, self.due = 0, False
        self.connection = connection
        self.hosts = hosts
        #: per worker: the names of its subsystems
        self.owners = owners
        #: per worker: {"node": Ray node id, "pid": process id}, once started
        self.places = [None] * len(hosts)
        self.time = None
        #: seconds a worker may take to answer one call (None: no limit)
        self.call_timeout: float | None = None
        self.dead: set[int] = set()
        self.closed = False
        #: subsystem name -> its counters, taken before the workers end
        self.counters: dict[str, dict] = {}
        #: per worker: calls that need no answer (save the state, write forces or
        #: inputs), sent ahead of its next call that does: a round trip saved
        self.deferred: dict[int, list] = {}
        #: (worker, slot) -> the outputs read right after its last step, while no other
        #: call has reached it: what read_outputs returns without a round trip
        self.outputs: dict[tuple[int, int], object] = {}
        # --- what it takes to start a lost worker again --------------------------
        #: per worker: its specs, shipped files and Ray options (to start it again)
        self.specs: list[list] = []
        self.files: list[list] = []
        self.options: list[dict] = []
        #: per worker: why it cannot be started again (None: it can)
        self.unrestartable: list[str | None] = []
        #: workers that may be started again in this run, at most, and still may be
        self.restarts = self.restarts_left = 0
        #: (worker, slot) -> the last checkpoint, pickled by the worker (None: from
        #: instantiation on)
        self.checkpoints: dict[tuple[int, int], bytes | None] = {}
        #: worker -> the batches of calls it answered (or failed) since the last batch in
        #: which every subsystem of it sent a checkpoint: (the calls as sent: the bytes of
        #: their pickle, or a deep copy; where a failed batch stopped: (entry, call), or
        #: None); Recovery._journaled reads each subsystem's calls since its checkpoint
        self.log: dict[int, list] = {}
        #: every worker lost: time, node, address, pid, components, what, recovery seconds
        self.losses: list[dict] = []
        #: (worker, since when, time.monotonic) while the driver waits for its answer
        self.waiting: tuple[int, float] | None = None
        #: what a user should know of where the workers run (a placement that cannot hold)
        self.notes: list[str] = []
        #: whether the set-up's objects are frozen out of the collector's passes
        self.frozen = False


class RayBackend(Recovery, Backend):
    """Every subsystem in a Ray actor (a worker process); batched calls in parallel."""

    name = "ray"
    remote = True
    has_workers = True
    #: one worker per FMU instance whatever the number of CPUs
    one_per_instance = False

    def __init__(self, cluster: _Cluster, members, names):
        self._cluster = cluster
        #: per subsystem: (worker index, slot in the worker)
        self.members = list(members)
        self._names = list(names)
        #: macro steps begun by these subsystems (a checkpoint every CHECKPOINT_EVERY)
        self._begun = 0

    # --- set-up ------------------------------------------------------------------
    @classmethod
    def problems(cls, **options) -> list[str]:
        found = super().problems(**{k: v for k, v in options.items()
                                    if k not in ("address", "call_timeout", "restarts")})
        if not available():
            found.append(f"backend '{cls.name}' needs the ray package: {INSTALL}")
        address = options.get("address")
        if address and address_problem(address):
            found.append(address_problem(address))
        return found

    @classmethod
    def ahead(cls, settings: dict) -> None:
        """Join the cluster at the run's ``address`` and start spare workers while the
        scene is read and planned (cluster.connect_ahead, spares.ahead)."""
        connect_ahead(settings.get("address"))
        spares.ahead()

    @classmethod
    def release_ahead(cls) -> None:
        """End the connection :meth:`ahead` made when no run took it."""
        release()

    @classmethod
    def log_line(cls) -> str | None:
        """The line naming Ray's own log when its processes said anything (ray_log_line)."""
        return ray_log_line()

    @classmethod
    def from_specs(cls, specs, address=None, call_timeout=None, restarts=None,
                   progress=None, **options) -> "RayBackend":
        if progress is not None and starts_ray(address):  # seconds with nothing to show
            progress(0, 0, "starting a local Ray instance")
        connection = connect(address)
        specs = list(specs)
        try:
            backend = cls._start(connection, specs)
            if progress is not None:  # the workers instantiate at once: all or none
                progress(len(specs), len(specs))
            backend._cluster.call_timeout = call_timeout
            backend._cluster.restarts = RESTARTS if restarts is None else restarts
            backend._cluster.restarts_left = backend._cluster.restarts
            # the scene, its plan and the driver's side of the workers live as long as
            # the run: out of the collector's passes until it ends (collector.py; at
            # chain_10000 the full passes took 0.35 to 0.4 s of a 1.4 s step)
            freeze()
            backend._cluster.frozen = True
            return backend
        except BaseException:
            connection.close()
            raise

    @classmethod
    def _start(cls, connection, specs) -> "RayBackend":
        ray = connection.ray
        shipment = Shipment(ray)
        remote = ray.remote(Host)
        hosts, assigned, members, worker_options = [], [], [None] * len(specs), []
        started = []  # per worker, how the run got it (spares.NEW, SPARE, ...)
        groups = [(placement, indices, cls._workers(connection, placement, len(indices)))
                  for placement, indices in cls._groups(connection, specs)]
        # each worker pinned to its node, chosen here (placement.py)
        nodes = Placement(connection, [(placement, n) for placement, _, n in groups])
        spread = {}  # worker number in the group without a placement -> its components
        for placement, indices, count in groups:
            options = dict(WORKER_OPTIONS)
            if placement:
                options["resources"] = {placement: PLACEMENT_SHARE}
            for number, dealt in enumerate(deal(len(indices), count)):
                chosen = [indices[i] for i in dealt]
                for slot, index in enumerate(chosen):
                    members[index] = (len(hosts), slot)
                placed = {**options, **nodes.options(placement, number)}
                host, how = cls._worker(connection, remote, placed)
                hosts.append(host)
                started.append(how)
                assigned.append(chosen)
                worker_options.append(placed)
                if not placement:
                    spread[number] = [specs[i].name for i in chosen]
        nodes.check(spread)
        shipped = [[_shipped_files(shipment, specs[i]) for i in chosen] for chosen in assigned]
        opened = [host.open.remote([specs[i] for i in chosen], files)
                  for host, chosen, files in zip(hosts, assigned, shipped)]
        owners = [[specs[i].name for i in chosen] for chosen in assigned]
        cluster = _Cluster(connection, hosts, owners)
        cluster.specs = [[specs[i] for i in chosen] for chosen in assigned]
        cluster.files = shipped
        cluster.options = worker_options
        cluster.notes = nodes.notes
        cluster.unrestartable = [_unrestartable(cluster.specs[h]) for h in range(len(hosts))]
        for h, chosen in enumerate(assigned):
            cluster.log[h] = []
            for slot in range(len(chosen)):
                cluster.checkpoints[(h, slot)] = None
        backend = cls(cluster, members, [s.name for s in specs])
        try:
            backend._cluster.places = backend._open(opened, started)
        except BaseException:
            backend.close()
            raise
        return backend

    @classmethod
    def _groups(cls, connection, specs) -> list[tuple[str, list[int]]]:
        """Subsystem indices by placement (Ray resource; '' for anywhere), checked
        against the cluster's resources."""
        groups: dict[str, list[int]] = {}
        for index, spec in enumerate(specs):
            groups.setdefault(spec.placement, []).append(index)
        known = connection.resources()
        missing = [f"component '{specs[i].name}' is placed on Ray resource '{place}', which "
                   f"no node of the cluster has (it has: {', '.join(sorted(known))})"
                   for place, indices in groups.items() if place and place not in known
                   for i in indices]
        if missing:
            raise InputError(missing)
        return list(groups.items())

    @classmethod
    def _workers(cls, connection, placement: str, count: int) -> int:
        if cls.one_per_instance:
            return count
        return max(1, min(count, connection.cpus(placement)))

    @classmethod
    def _keeps_spares(cls, connection) -> bool:
        """Whether runs of this kind on ``connection`` keep spare workers at all: not
        one worker per instance, nor inside a Ray worker (a sweep's point), nor when
        they are turned off (spares.keep)."""
        return (spares.keeping() and not cls.one_per_instance
                and spares.in_driver(connection.ray))

    @classmethod
    def _spares(cls, connection, leaving: bool = False) -> bool:
        """Whether this run takes (or, ``leaving``, leaves) this driver's spare workers
        (spares.py): it leaves none when it made its connection (the driver ends
        with the run, or Ray does), and takes those only when the connection was made
        ahead of it (cluster.connect_ahead)."""
        made_by_run = connection.owned and (leaving or not connection.ahead)
        return not made_by_run and cls._keeps_spares(connection)

    @classmethod
    def _leaves_in_cluster(cls, connection) -> bool:
        """Whether this run leaves its spares in the cluster for the next command
        (pool.py): it made its connection to a cluster's address itself."""
        return bool(connection.owned and connection.address
                    and cls._keeps_spares(connection))

    @classmethod
    def _worker(cls, connection, remote, options: dict) -> tuple[object, str]:
        """A worker with ``options``, and how the run got it (spares.take)."""
        if cls._spares(connection):
            return spares.take(connection.ray, remote, options)
        return remote.options(**options).remote(), spares.NEW

    def _open(self, opened, started: list[str]) -> list[dict]:
        """Wait for every worker to instantiate its FMUs: their places, each with how
        the run got the worker (``started``, per worker: spares.NEW, SPARE or
        CLUSTER_SPARE), which the statistics show.  A spare found dead is replaced by a
        new worker, once."""
        ray = self._cluster.connection.ray
        self._started(dict(enumerate(opened)))
        places = []
        for h, ref in enumerate(opened):
            try:
                place = self._place(h, ref, last=started[h] == spares.NEW)
                places.append({**place, "started": started[h]})
            except ray.exceptions.RayActorError:
                # a spare that died while it waited for a run, before it held anything
                worker = ray.remote(Host).options(**self._cluster.options[h]).remote()
                self._cluster.hosts[h] = worker
                again = worker.open.remote(self._cluster.specs[h], self._cluster.files[h])
                self._started({h: again})
                places.append({**self._place(h, again, last=True),
                               "started": spares.NEW})
        return places

    def _started(self, opened: dict) -> None:
        """Wait at most START_SECONDS for the ``opened`` calls (worker number -> its
        call), else say whose are late."""
        ray = self._cluster.connection.ray
        ready, waiting = ray.wait(list(opened.values()), num_returns=len(opened),
                                  timeout=START_SECONDS)
        if waiting:
            late = [name for h, ref in opened.items() if ref in waiting
                    for name in self._cluster.owners[h]]
            raise InputError(f"the Ray workers of components {_quoted(late)} did not start "
                             f"in {START_SECONDS:g} s (is the cluster short of memory, or "
                             "are its nodes gone?)")

    def _place(self, h: int, ref, last: bool = False) -> dict:
        """Where worker ``h`` runs, from its answer ``ref`` to ``open``; a dead worker
        raises RayActorError unless ``last`` (then the run's InputError)."""
        ray = self._cluster.connection.ray
        try:
            return ray.get(ref)
        except ray.exceptions.RayTaskError as error:
            raise _cause(error) from None
        except ray.exceptions.RayActorError:
            if not last:
                raise
            self._cluster.dead.add(h)
            raise InputError(f"{_who(self._cluster.owners[h])}: the worker process "
                             "died while the FMU was instantiated (it crashed or was "
                             "killed)") from None
        except ray.exceptions.RayError as error:
            self._cluster.dead.add(h)
            raise InputError(f"{_who(self._cluster.owners[h])}: Ray could not start "
                             f"its worker: {_first_line(error)}") from None

    # --- the batched calls -------------------------------------------------------
    def _run(self, steps, time=None, answer: bool = True) -> list:
        """``steps[i]``: the (method, arguments) calls of subsystem i, in order; one
        remote call per worker, all launched before any answer is awaited.  The results
        of each subsystem's calls (a list; empty for one given no call).  Without
        ``answer`` the calls wait for the worker's next call (Ray runs one caller's
        calls of an actor in order; an error they raise surfaces with that call)."""
        cluster = self._cluster
        if time is not None:
            cluster.time = time
        batches: dict[int, list] = {}
        for member, calls in zip(self.members, steps):
            if calls:
                batches.setdefault(member[0], []).append((member[1], calls))
                cluster.outputs.pop(member, None)  # the subsystem may change
        if not answer:
            for host, batch in batches.items():
                cluster.deferred.setdefault(host, []).extend(batch)
            return [[] for _ in steps]
        pending, skipped, payloads, kept = {}, {}, {}, {}
        for host, batch in batches.items():
            ahead = cluster.deferred.pop(host, [])
            skipped[host] = len(ahead)
            payloads[host] = ahead + batch
            sent = _pickled(payloads[host])
            if self._restartable(host):  # the journal must hold the values as sent
                kept[host] = copy.deepcopy(payloads[host]) if sent is None else sent
            # the answers of thousands of subsystems come back packed (pack_answers)
            worker = cluster.hosts[host]
            pending[host] = worker.run_packed.remote(payloads[host], skipped[host]) \
                if sent is None else worker.run_pickled.remote(sent, skipped[host])
        answers = {}
        for host, ref in pending.items():
            cluster.waiting = (host, clock.monotonic())  # for the progress line
            try:
                results = self._answer(host, ref, payloads[host], _unpacked, kept.get(host))
            finally:
                cluster.waiting = None
            self._journal(host, payloads[host], results, kept.get(host))
            answers[host] = iter(results[skipped[host]:])
        return [next(answers[host]) if calls else []
                for (host, _), calls in zip(self.members, steps)]

    def _answer(self, host: int, ref, payload=None, answered=None, kept=None):
        """The answer of worker ``host`` to ``ref`` (``answered`` of it, if given: a
        batch's packed answers made plain), or what its loss leaves; ``payload``: the
        calls ``ref`` made, ``kept``: as the journal keeps them (Recovery._journal)."""
        ray = self._cluster.connection.ray
        who = _who(self._cluster.owners[host])
        try:
            got = ray.get(ref, timeout=self._cluster.call_timeout)
            return got if answered is None else answered(got)
        except ray.exceptions.GetTimeoutError:
            self._cluster.dead.add(host)
            ray.kill(self._cluster.hosts[host])  # a hung FMU: its process must go
            raise SimulationError(f"{who}: no answer from the worker in "
                                  f"{self._cluster.call_timeout:g} s (--call-timeout): the "
                                  "FMU hangs or is too slow; the worker was stopped",
                                  time=self._cluster.time) from None
        except ray.exceptions.RayTaskError as error:
            cause = _cause(error)
            if payload is not None:  # the calls made up to the error changed the worker
                self._journal_failed(host, getattr(cause, "dsim_at", None), kept)
            raise cause from None
        except ray.exceptions.RayError as error:  # the worker, its node, or the cluster
            if payload is None:
                self._cluster.dead.add(host)
                raise SimulationError(f"{who}: {self._lost(host, error)['said']}",
                                      time=self._cluster.time) from None
            return self._recover(host, payload, error, kept)

    def _each(self, method, *columns, time=None, answer: bool = True) -> list:
        """``method`` on every subsystem, with the i-th entry of each column: the
        result of each."""
        return [results[0] if results else None for results in self._run(
            [[(method, tuple(c[i] for c in columns))] for i in range(len(self.members))],
            time, answer)]

    def _stepped(self, method, columns, time) -> list:
        """A step of every subsystem (``method`` with the i-th entry of each column)
        and, in the same call, a read of its outputs, kept for :meth:`read_outputs`:
        after the step that converges, the couplings read the outputs next, so that
        round trip is saved (reading changes nothing in an FMU)."""
        answers = self._run([[(method, tuple(c[i] for c in columns)), ("read_outputs", ())]
                             for i in range(len(self.members))], time)
        for member, (_, outputs) in zip(self.members, answers):
            self._cluster.outputs[member] = outputs
        return [kinematics for kinematics, _ in answers]

    def _some(self, method, inputs, answer: bool = False) -> None:
        """``method`` on the subsystems of (index, values) ``inputs``, with the values."""
        steps = [[] for _ in self.members]
        for index, values in inputs:
            steps[index].append((method, (values,)))
        self._run(steps, answer=answer)

    def subset(self, indices) -> "RayBackend":
        return type(self)(self._cluster, [self.members[i] for i in indices],
                          [self._names[i] for i in indices])

    def __len__(self) -> int:
        return len(self.members)

    @property
    def names(self) -> list[str]:
        return list(self._names)

    def begin_step(self) -> None:
        # a worker that may be started again sends each subsystem's saved state too,
        # every CHECKPOINT_EVERY steps (recovery.py); not while an error-controlled
        # step's snapshot lives (a fresh worker going on from there would be sent back
        # to a snapshot it never made), but with the next snapshot (:meth:`snapshot`)
        saving = self._begun % CHECKPOINT_EVERY == 0
        self._begun += 1
        cluster = self._cluster
        if cluster.live:
            cluster.due, saving = cluster.due or saving, False
        self._run([[("begin_step", ())] + ([(CHECKPOINT, ())] if saving and
                                           self._restartable(host) else [])
                   for host, _ in self.members], answer=False)

    def trial_step(self, forces, time, step_size):
        n = len(self.members)
        return self._stepped("trial_step", (forces, [time] * n, [step_size] * n), time)

    def advance(self, forces, time, step_size):
        n = len(self.members)
        return self._stepped("advance", (forces, [time] * n, [step_size] * n), time)

    def step(self, time, step_size, inputs=()):
        steps = [[] for _ in self.members]
        for index, values in inputs:
            steps[index].append(("write_inputs", (values,)))
        for calls in steps:
            calls.append(("exchange", (time, step_size)))
        return [results[-1] for results in self._run(steps, time)]

    snapshots = True

    def snapshot(self):
        """Every subsystem's state kept in its worker under a new key (the key is the
        handle).  Where a checkpoint is due, the worker sends the snapshot's state as
        its checkpoint: a fresh worker goes on from it, keeps it under the same key and
        takes the calls since (the step, a rollback to it, the halves)."""
        cluster = self._cluster
        cluster.snapshots += 1
        key = cluster.snapshots
        due, cluster.due = cluster.due, False
        cluster.live += 1
        self._run([[("keep_snapshot", (key,))] + ([(CHECKPOINT, (key,))] if due and
                                                  self._restartable(host) else [])
                   for host, _ in self.members], answer=False)
        return key

    def rollback(self, snapshot) -> None:
        self._each("rollback_to", [snapshot] * len(self.members), answer=False)

    def discard(self, snapshot) -> None:
        self._cluster.live -= 1
        self._each("drop_snapshot", [snapshot] * len(self.members), answer=False)

    def hold_inputs(self, ramps) -> None:
        self._each("hold_inputs", [r[0] for r in ramps], [r[1] for r in ramps],
                   [r[2] for r in ramps], answer=False)

    def trial_exchange(self, time, step_size, ramps):
        n = len(self.members)
        outputs = self._each("trial_exchange", [r[0] for r in ramps], [r[1] for r in ramps],
                             [time] * n, [step_size] * n, time=time)
        for member, values in zip(self.members, outputs):
            self._cluster.outputs[member] = values
        return outputs

    def flexibility(self, forces, time, step_size, deltas, bases):
        n = len(self.members)
        return self._each("flexibility", forces, [time] * n, [step_size] * n, deltas, bases,
                          time=time)

    def set_forces(self, forces) -> None:
        self._each("set_forces", forces, answer=False)

    def start_flexibility(self, forces, deltas):
        return self._each("start_flexibility", forces, deltas)

    def kinematics(self):
        return self._each("kinematics")

    def read_outputs(self):
        kept = self._cluster.outputs
        if all(member in kept for member in self.members):
            return [kept[member].copy() for member in self.members]
        return self._each("read_outputs")

    def write_inputs(self, inputs, start: bool = False) -> None:
        self._some("write_start_inputs" if start else "write_inputs", inputs)

    def set_values(self, entries) -> None:
        steps = [[] for _ in self.members]
        for index, names, values in entries:
            steps[index].append(("set_values", (tuple(names), tuple(values))))
        self._run(steps, answer=False)  # an error surfaces with the worker's next call

    def read_texts(self):
        return self._each("read_texts")

    def write_texts(self, inputs) -> None:
        self._some("write_texts", inputs)

    def finish_initialization(self) -> None:
        # answered: a model that refuses to leave initialization is bad input, said now
        self._each("finish_initialization")

    def counters(self):
        cluster = self._cluster
        if cluster.closed or any(host in cluster.dead for host, _ in self.members):
            return [cluster.counters.get(name, {}) for name in self._names]
        return self._each("statistics")

    def places(self) -> list:
        return [self._cluster.places[host] for host, _ in self.members]

    def save_states(self) -> list[dict]:
        return self._each("current_checkpoint")

    def load_states(self, states, counters) -> None:
        self._run([[("resume", (state,)), ("restore_counters", (counted,))]
                   for state, counted in zip(states, counters)])

    def close(self) -> list[Exception]:
        """Terminate every subsystem (the live workers'), then end the workers and,
        if this run started Ray, Ray itself; the errors the subsystems raised."""
        cluster = self._cluster
        if cluster.closed:
            return []
        ray = cluster.connection.ray
        errors: list[Exception] = []
        try:
            live = [h for h in range(len(cluster.hosts)) if h not in cluster.dead]
            cluster.counters = self._last_counters(live)
            closing = {h: cluster.hosts[h].close.remote() for h in live}
            for h, ref in closing.items():
                try:
                    errors += ray.get(ref, timeout=CLOSE_SECONDS)
                except ray.exceptions.RayError:
                    pass  # a worker gone (or frozen) while closing: it is killed below
            for host in cluster.hosts:
                ray.kill(host)
            if self._spares(cluster.connection, leaving=True):  # the driver's next run
                spares.stock(ray, ray.remote(Host), cluster.options)
            elif self._leaves_in_cluster(cluster.connection):
                try:
                    pool.stock(ray, Host, cluster.options)  # the next command's
                except Exception:  # a spare not left costs the next command its start
                    pass
        finally:
            cluster.closed = True
            if cluster.frozen:
                cluster.frozen = False
                thaw()
            cluster.connection.close()
        return errors

    def abandon(self) -> None:
        """Kill every worker (on a cluster they are not this machine's to kill by pid),
        giving Ray a second at most: the process ends at once."""
        cluster = self._cluster
        if cluster.closed:
            return
        ray = cluster.connection.ray

        def kill_all():
            for host in cluster.hosts:
                try:
                    ray.kill(host)
                except Exception:  # gone already, or Ray itself is
                    pass

        killer = threading.Thread(target=kill_all, name="dsim-ray-kill", daemon=True)
        killer.start()
        killer.join(timeout=1.0)

    def _last_counters(self, live) -> dict:
        """Every live subsystem's counters before the workers go (the statistics are
        made after the run has closed its backend)."""
        ray = self._cluster.connection.ray
        counters = {}
        for h in live:
            ahead = self._cluster.deferred.pop(h, [])  # counted, as in-process
            slots = [(slot, [("statistics", ())]) for slot in
                     range(len(self._cluster.owners[h]))]
            try:
                values = ray.get(self._cluster.hosts[h].run.remote(ahead + slots),
                                 timeout=CLOSE_SECONDS)
            except ray.exceptions.RayError:  # gone, or frozen: its counters are not known
                continue
            counters.update(zip(self._cluster.owners[h],
                                (v[0] for v in values[len(ahead):])))
        return counters


class IsolatedBackend(RayBackend):
    """One worker process per FMU instance on this machine: a crashing FMU ends the
    run with a message naming it, never dsim (``dsim run --isolate``)."""

    name = "isolated"
    one_per_instance = True

    @classmethod
    def ahead(cls, settings: dict) -> None:
        """Nothing: a local instance starts with the run (its workers are the FMUs')."""

    @classmethod
    def problems(cls, **options) -> list[str]:
        found = super().problems(**options)
        if options.get("address"):
            found.append("setting address: the isolated backend runs on this machine; "
                         "use --backend ray to run on a cluster")
        return found

    @classmethod
    def from_specs(cls, specs, address=None, **options) -> "IsolatedBackend":
        return super().from_specs(specs, None, **options)  # this machine's own instance


def _unpacked(answer) -> list:
    """A worker's :meth:`~dsim.master.running.backends.ray.worker.Host.run_packed`
    (or ``run_pickled``) answer as
    :meth:`~dsim.master.running.backends.ray.worker.Host.run` gives it."""
    if type(answer) is bytes:  # Host.run_pickled's
        answer = pickle.loads(answer)
    head, packed, rest = answer
    return head + (unpack_answers(*packed) if packed is not None else rest)


def _shipped_files(shipment, spec) -> tuple:
    """What a worker needs to find a subsystem's files: its FMU, and the scene files
    its String parameters name (parameter -> shipped file)."""
    if spec.table is not None:  # a table component carries its data in its spec
        return None, {}
    return (shipment.add(spec.path),
            {name: shipment.add(spec.parameters[name][1]) for name in spec.files})


def _pickled(payload) -> bytes | None:
    """A batch of calls as one pickle (protocol 5, Python's C pickler), or None when
    pickle cannot take it.  Ray serializes a call's arguments with cloudpickle, whose
    dispatch runs in Python for every object: a batch of thousands of force vectors
    cost the driver more than the C pickler's whole batch does, and Ray then sends
    bytes (chain_10000 on two workers: 1.49 to 1.60 s a step against 1.76 to 1.79 s,
    the driver's CPU 0.71 to 0.83 s against 0.98 to 1.03 s, in turn, 2026-11-27).  The
    driver keeps the bytes themselves as the values sent (the journal of
    recovery.py): nothing the caller changes after the call reaches them.  Written
    by hand: Ray has no option to pickle a call's arguments with the C pickler."""
    try:
        return pickle.dumps(payload, protocol=5)
    except (pickle.PicklingError, TypeError, AttributeError):
        return None
