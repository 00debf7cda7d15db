"""Worker processes started ahead for the next run of this driver (docs/distributed.md,
"Spare workers").

Starting a worker process (Python, Ray, dsim's worker module) costs 0.3 to 1.5 s on
these machines, more than setting up chain_1000 in-process.  A process that runs
several scenes on one Ray instance (a script with its own ``ray.init``, a study) pays
it again for every run: a run's workers end with it, because a worker that held one
run's FMUs (their Python, their libraries, whatever they left behind) must not host
the next run's.  So when such a run ends, dsim starts as many *new* workers as it
used, on the same nodes with the same options, and the next run takes them instead
of starting its own: fresh processes that have hosted nothing, ready by the time the
next scene is read and planned; a run with none kept (the first) starts its workers
before its scene is read and planned (:func:`ahead`, from ``dsim.simulate``; a run given
a cluster's address joins it first, cluster.connect_ahead).  A run that made its own
connection ends it, and keeps no spare here: one that started Ray itself leaves none,
one that joined a cluster's address leaves them in the cluster for the next command
(pool.py), and such a command takes those first (:func:`ahead`).

Only a driver keeps spares (a sweep's point runs inside a Ray worker, and leaves
none).  Spares are kept per Ray session (a new ``ray.init`` forgets the old ones), take
no CPU of Ray's (``num_cpus=0``, as every worker of dsim's), and end with the driver or
with :func:`drop`.  A spare found dead (its ready call failed) is not used; one that
dies between being taken and being used is replaced by a new worker
(backend.RayBackend._open).
"""
from __future__ import annotations

import os
import sys
from collections import Counter

from dsim.master.running.backends.ray import cluster
from dsim.master.running.backends.ray import pool
from dsim.master.running.backends.ray.pool import key

#: session -> {options key -> [(actor, its ready call, claimed), ...]}; one session at a
#: time; ``claimed``: a spare of the cluster (pool.py), whose call is its claim
_pool: dict[tuple, dict[tuple, list]] = {}
#: whether runs leave spares: ``DSIM_RAY_SPARES=0`` in the environment, or :func:`keep`,
#: turns them off (a shared cluster whose idle processes others need)
_keeping = [os.environ.get("DSIM_RAY_SPARES", "1").strip() != "0"]


def keep(on: bool = True) -> None:
    """Whether the runs of this driver leave spare workers from now on (off: the spares
    kept now are ended too)."""
    _keeping[0] = bool(on)
    if not on:
        drop()


def keeping() -> bool:
    """Whether runs leave spare workers (:func:`keep`, ``DSIM_RAY_SPARES``)."""
    return _keeping[0]


def _session(ray) -> tuple:
    """Which Ray session this driver is in: a spare of an earlier one is gone."""
    context = ray.get_runtime_context()
    return context.get_job_id(), context.get_node_id()


def in_driver(ray) -> bool:
    """Whether this process is a Ray driver (a script, ``dsim``), not a Ray worker
    running a task (a sweep's point): spares are a driver's, ended with it."""
    return ray.get_runtime_context().get_task_id() is None


def settle(ray=None, timeout: float = 60.0) -> int:
    """Wait until every spare worker has started (at most ``timeout`` s): how many are
    ready.  A script that times its runs calls it first, so that the spares' start does
    not slow what it times."""
    if ray is None:
        ray = cluster.ray_module()
    return len(_started(ray, timeout))


def _started(ray, timeout: float) -> list:
    """The ready calls of the spares that have answered (waiting ``timeout`` s at most)."""
    calls = [ready for spares in _pool.values() for kept in spares.values()
             for _, ready, _ in kept]
    return ray.wait(calls, num_returns=len(calls), timeout=timeout)[0] if calls else []


def _spares(ray) -> dict[tuple, list]:
    session = _session(ray)
    if session not in _pool:
        _pool.clear()  # an earlier session's actors went with it: nothing to end
        _pool[session] = {}
    return _pool[session]


#: how a run got a worker, as its statistics say (``worker.started``)
SPARE, CLUSTER_SPARE, NEW = "ahead", "cluster spare", "new"


def take(ray, remote, options: dict) -> tuple[object, str]:
    """A worker with ``options``: a live spare when there is one (and :data:`SPARE`, or
    :data:`CLUSTER_SPARE` for one an earlier command left in the cluster), else a new
    one (and :data:`NEW`).  ``remote``: ``ray.remote(Host)``."""
    kept = _spares(ray).get(key(options), [])
    while kept:
        actor, ready, claimed = kept.pop()
        if claimed:  # the cluster's (pool.py): only if this driver won it
            if pool.won(ray, ready):
                return actor, CLUSTER_SPARE
            continue  # another's, or gone: not this driver's to end
        done, _ = ray.wait([ready], timeout=0)
        if not done:  # still starting: it will be ready sooner than a new one
            return actor, SPARE
        try:
            ray.get(ready, timeout=0)
            return actor, SPARE
        except ray.exceptions.RayError:  # gone while it waited: never used
            _kill(ray, actor)
    return remote.options(**options).remote(), NEW


def stock(ray, remote, options: list[dict]) -> None:
    """Start new workers, one per entry of ``options`` (those of a run that ended), for
    the next run: the pool holds at most that many of each kind."""
    spares = _spares(ray)
    wanted = Counter(key(o) for o in options)
    examples = {key(o): o for o in options}
    for kind, count in wanted.items():
        kept = spares.setdefault(kind, [])
        for _ in range(count - len(kept)):
            actor = remote.options(**examples[kind]).remote()
            kept.append((actor, actor.ready.remote(), False))
        kept.sort(key=lambda entry: entry[2])  # the cluster's last: taken (popped) first


def ahead(ray=None) -> int:
    """Start spare workers for the run about to begin, while its scene is read and
    planned: as many as the cluster has CPUs (the most workers a run of components
    without a placement uses), on the nodes such a run chooses, less those already
    kept; only in a driver connected to Ray that keeps spares.  A command that joined
    a cluster first claims the spares an earlier command left there (pool.py), and
    when it found any starts none.  How many it took or started."""
    if not cluster.joined() or not keeping():
        return 0
    ray = ray or sys.modules["ray"]
    if not in_driver(ray):
        return 0
    from dsim.master.running.backends.ray.placement import Placement
    from dsim.master.running.backends.ray.worker import WORKER_OPTIONS, Host

    connection = cluster.Connection(ray, owned=False)
    workers = connection.cpus("")
    if workers < 1:
        return 0
    nodes = Placement(connection, [("", workers)])
    before = count()
    # the options RayBackend._start gives the workers of components without a placement
    options = [{**WORKER_OPTIONS, **nodes.options("", n)} for n in range(workers)]
    if cluster.made_ahead() is not None:  # joined a cluster's address for this run
        spares = _spares(ray)
        claimed = pool.claim(ray, options)
        for example, actor, call in claimed:
            spares.setdefault(key(example), []).append((actor, call, True))
        if claimed:  # as many as the command before used: no more started ahead (on a
            return count() - before  # large cluster, one per CPU is mostly waste)
    stock(ray, ray.remote(Host), options)
    return count() - before


def pids(ray) -> set[int]:
    """The process ids of the spare workers that have started (see :func:`settle`)."""
    found = set()
    for ready in _started(ray, 0):
        try:
            pid = ray.get(ready, timeout=0)
        except ray.exceptions.RayError:  # it died before it started
            continue
        if type(pid) is int:  # not a claim another driver won (pool.py)
            found.add(pid)
    return found


def count() -> int:
    """How many spare workers this driver keeps now."""
    return sum(len(kept) for spares in _pool.values() for kept in spares.values())


def drop(ray=None) -> None:
    """End every spare worker (they end with the driver anyway)."""
    if ray is None:
        ray = cluster.ray_module()
    for spares in _pool.values():
        for kept in spares.values():
            for actor, ready, claimed in kept:
                if not claimed or pool.won(ray, ready):  # never another's
                    _kill(ray, actor)
    _pool.clear()


def forget() -> None:
    """Let go of the spare workers of a Ray connection about to end: they end with it
    (cluster.Connection.close); the cluster's that a refused run claimed and did
    not use are given back to wait for the next command (pool.py)."""
    claimed = [(actor, ready) for spares in _pool.values() for kept in spares.values()
               for actor, ready, claimed in kept if claimed]
    _pool.clear()
    if claimed:
        ray = sys.modules["ray"]
        job = ray.get_runtime_context().get_job_id()
        try:
            ray.get([actor.give_back.remote(job) for actor, _ in claimed],
                    timeout=pool.CLAIM_SECONDS)
        except Exception:  # not given back: it ends once this driver's job has
            pass


cluster.BEFORE_SHUTDOWN.append(forget)


def _kill(ray, actor) -> None:
    try:
        ray.kill(actor)
    except Exception:  # gone already, or Ray itself is
        pass
