"""Spare workers kept in a running cluster for the next command (docs/distributed.md,
"Spare workers").

Every ``dsim run --address ...`` is a new process and a new Ray job: the spares a
script keeps (spares.py) end with it, so each command paid the start of its
workers (0.3 to 1.5 s a process on these machines) in its set-up.  A run that joined
a running cluster itself (``--address``) therefore leaves its spares in the cluster
instead, as detached Ray actors named in a namespace of the user's
(:func:`namespace`), and the next such command takes them while it reads and plans
its scene.  A spare has hosted nothing: it is a worker process that has started and
waits.  It ends itself when no run takes it within :func:`wait_seconds`
(``DSIM_RAY_SPARE_SECONDS``, 600 by default), and, once taken, when the taking driver's
Ray job ends (lease.py): the run ends its workers itself, this is for a driver
killed outright.  ``DSIM_RAY_SPARES=0`` turns them off, as it does a script's.

Taking one is a call to the spare itself (:meth:`Host.claim`), which only the first
caller wins, so two commands never share a worker.  What a spare answers is trusted as
far as Ray trusts the cluster's users: anyone who can run a job on a cluster can run
code in its workers and read its object store (where the FMUs travel anyway); a name
that is not dsim's form, a spare of another build of dsim (:func:`build`) or of other
options, and an actor that does not answer the claim as a spare does are passed over.
"""
from __future__ import annotations

import getpass
import hashlib
import os
import random
import re
import uuid
from collections import Counter
from functools import lru_cache
from pathlib import Path

#: how long a spare waits for a run (s), unless ``DSIM_RAY_SPARE_SECONDS`` says
WAIT_SECONDS = 600.0
#: how long a run waits for a spare's answer to its claim (s): one still starting
#: answers when it has started, which a new worker would take longer to do
CLAIM_SECONDS = 5.0
#: a spare's name: this build of dsim, the kind of worker (its options), a random part
NAME = re.compile(r"([0-9a-f]{12})-([0-9a-f]{12})-[0-9a-f]{12}")

#: the names of the spares this process claimed: its own workers, not spares left
_claimed: set[str] = set()


def wait_seconds() -> float:
    """How long a spare left in the cluster waits for a run, in seconds
    (``DSIM_RAY_SPARE_SECONDS``; :data:`WAIT_SECONDS` when unset or not a positive
    number)."""
    try:
        seconds = float(os.environ.get("DSIM_RAY_SPARE_SECONDS", ""))
    except ValueError:
        return WAIT_SECONDS
    return seconds if 0 < seconds < float("inf") else WAIT_SECONDS


def namespace() -> str:
    """The Ray namespace of this user's spares: another user's are not taken."""
    try:
        user = getpass.getuser()
    except (OSError, KeyError):  # no name for this uid
        user = f"uid{os.getuid()}"
    return "dsim-spares-" + re.sub(r"[^A-Za-z0-9_.-]", "_", user)[:64]


@lru_cache(maxsize=1)
def build() -> str:
    """Which build of dsim this is, as far as its workers' code goes: its version and
    the size and time of every Python file of the package (a spare of an older build
    runs older code).  12 hex digits."""
    from dsim.master import __version__

    root = Path(__file__).resolve().parents[2]  # the master package
    digest = hashlib.sha256(__version__.encode())
    for path in sorted(root.rglob("*.py")):
        stat = path.stat()
        digest.update(f"{path.relative_to(root)}:{stat.st_size}:{stat.st_mtime_ns};".encode())
    return digest.hexdigest()[:12]


def key(options: dict) -> tuple:
    """What makes two workers interchangeable: their node, resources and Ray options."""
    strategy = options.get("scheduling_strategy")
    where = (getattr(strategy, "node_id", None), getattr(strategy, "soft", None)) \
        if strategy is not None and not isinstance(strategy, str) else strategy
    return (where, tuple(sorted(options.get("resources", {}).items())),
            options.get("num_cpus"), options.get("max_restarts"))


def kind(options: dict) -> str:
    """:func:`key` as 12 hex digits, for a spare's name."""
    return hashlib.sha256(repr(key(options)).encode()).hexdigest()[:12]


def _listed(ray) -> list[tuple[str, str]]:
    """(name, kind) of every spare of this build in this user's namespace."""
    found = []
    space = namespace()
    for entry in ray.util.list_named_actors(all_namespaces=True):
        matched = NAME.fullmatch(str(entry.get("name", "")))
        if entry.get("namespace") == space and matched and matched[1] == build():
            found.append((matched[0], matched[2]))
    return found


def claim(ray, options: list[dict]) -> list[tuple[dict, object, object]]:
    """Claim spares of the cluster for workers with ``options`` (one entry each): per
    spare claimed, (its options, the actor, its claim call, which answers the process
    id, or None when the spare was not won).  Sent, not awaited."""
    wanted = Counter(kind(o) for o in options)
    examples = {kind(o): o for o in options}
    job = ray.get_runtime_context().get_job_id()
    try:
        listed = _listed(ray)
    except Exception:  # the cluster cannot say (Ray's own error): new workers, as before
        return []
    random.shuffle(listed)  # two commands at once do not go for the same spares
    claims = []
    for name, its_kind in listed:
        if wanted[its_kind] <= 0:
            continue
        try:
            actor = ray.get_actor(name, namespace=namespace())
            call = actor.claim.remote(job)
        except (ValueError, AttributeError):  # ended since it was listed; no such method
            continue
        wanted[its_kind] -= 1
        _claimed.add(name)
        claims.append((examples[its_kind], actor, call))
    return claims


def won(ray, call) -> bool:
    """Whether a :func:`claim` call won its spare (waiting :data:`CLAIM_SECONDS` at
    most): the answer is a process id."""
    try:
        answer = ray.get(call, timeout=CLAIM_SECONDS)
    except Exception:  # gone, late, or an actor that raised: not a spare to take
        return False
    return type(answer) is int and answer > 0


def stock(ray, host, options: list[dict]) -> int:
    """Leave spares in the cluster for the next command: one per entry of
    ``options`` (the workers of a run that ended) of components without a placement
    (the only ones a command claims before its scene is planned: spares.ahead),
    less the spares of that kind already there (not counting those this process
    took).  ``host``: the worker class.  How many it started."""
    options = [o for o in options if not o.get("resources")]
    there = Counter(its_kind for name, its_kind in _listed(ray) if name not in _claimed)
    wanted = Counter(kind(o) for o in options)
    examples = {kind(o): o for o in options}
    remote = ray.remote(host)
    started = 0
    for its_kind, count in wanted.items():
        for _ in range(count - there[its_kind]):
            name = f"{build()}-{its_kind}-{uuid.uuid4().hex[:12]}"
            remote.options(**examples[its_kind], name=name, namespace=namespace(),
                           lifetime="detached").remote(wait_seconds())
            started += 1
    return started
