"""The worker side of the Ray backends: the actor that holds some FMU instances in its
process, and how the subsystems are dealt onto workers.

A worker can be replaced (docs/distributed.md, "What survives what"): after every
``begin_step`` the driver may ask for a :data:`CHECKPOINT` of a subsystem (its saved FMU
state serialized, and the inputs last written to it), and a fresh worker elsewhere
goes on from one with :data:`RESUME`.  An FMU that crashes its process leaves a
report (Python's :mod:`faulthandler`, in :func:`fault_file`), so that the driver can
tell a crashed FMU from a killed worker."""
from __future__ import annotations

import faulthandler
import gc
import os
import pickle
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from dsim.master.processes import process_alive
from dsim.master.running.backends.base import terminate_all
from dsim.master.running.backends.ray.lease import Lease
from dsim.master.running.collector import collector_paused
from dsim.master.running.private_folder import private_folder
from dsim.master.running.fmi import open_subsystem
from dsim.master.running.backends.ray.cluster import landed

#: the pseudo-methods of :meth:`Host.run` that take or restore a checkpoint, and that
#: take a call again that raised an error the first time (a step an FMU discarded)
CHECKPOINT, RESUME, FAILED = "@checkpoint", "@resume", "@failed"
#: the Ray options of every worker (placement and node added per run): no CPU of Ray's,
#: so that any number share a node; never restarted by Ray (dsim starts a lost one again)
WORKER_OPTIONS = {"num_cpus": 0, "max_restarts": 0}
#: the calls whose last arguments a checkpoint keeps: inputs an FMU state need not hold
#: (a restored state brings back its own, others keep what was written last)
REMEMBERED = ("write_start_inputs", "write_inputs", "write_texts", "set_forces",
              "hold_inputs")


def fault_file(pid: int) -> Path:
    """Where the worker process ``pid`` of this machine reports a crash."""
    return private_folder(Path(tempfile.gettempdir()) / f"dsim-worker-{os.getuid()}") / \
        f"fault-{pid}.txt"


def sweep_reports(folder: Path) -> list[Path]:
    """Remove the empty crash reports in ``folder`` of worker processes of this machine
    that have ended (killed without a crash, or before this release, which made one for
    every worker, spares too): an empty one says nothing a driver could read, and
    nothing else removes it.  A report with a crash in it waits for its driver.  The
    files removed."""
    removed = []
    for path in folder.glob("fault-*.txt"):
        pid = path.stem.removeprefix("fault-")
        if not pid.isdigit() or process_alive(int(pid)):
            continue
        try:
            if path.lstat().st_size == 0:
                path.unlink()
                removed.append(path)
        except OSError:  # gone meanwhile
            pass
    return removed


def crash_report(pid: int) -> str | None:
    """The first line of the crash report of worker ``pid`` on this machine (e.g.
    ``Fatal Python error: Aborted``), or None when it left none; the report is
    removed."""
    path = fault_file(pid)
    try:
        text = path.read_text(errors="replace")
        path.unlink()
    except OSError:
        return None
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return lines[0] if lines else None


class Host:
    """A worker process (the Ray actor): some subsystems, called in order."""

    def __init__(self, spare_seconds: float | None = None):
        self.subsystems = []
        #: per subsystem: {"start": {method: arguments}, "inputs": {...}}, most recent
        #: last (what a checkpoint keeps besides the FMU state)
        self.written = []
        self.initialized = []
        self._faults = None  # the crash report's file, from the first FMU on (open)
        #: a spare kept in the cluster for a later command (pool.py): its wait
        self._lease = Lease(spare_seconds) if spare_seconds is not None else None

    def ready(self) -> int:
        """This worker's process id, once it has started (spares.py)."""
        return os.getpid()

    def claim(self, job: str) -> int | None:
        """Take this spare of the cluster for the driver of Ray job ``job``
        (pool.py): its process id, or None when another driver took it first,
        its wait ran out, or it is no such spare."""
        taken = self._lease is not None and self._lease.take(job)
        return os.getpid() if taken else None

    def give_back(self, job: str) -> bool:
        """Let go of this spare unused, for a later run (see :meth:`claim`)."""
        return self._lease is not None and self._lease.give_back(job)

    def open(self, specs, files) -> dict:
        """Instantiate the FMUs of ``specs`` from the shipped ``files`` (for each, its
        FMU and its scene files by parameter,
        :class:`~dsim.master.running.backends.ray.cluster.Shipment`);
        where this worker runs."""
        import ray

        if self._faults is None:
            # a crashing FMU (SIGSEGV, SIGABRT, SIGBUS, SIGFPE, SIGILL) leaves its report
            # here, where the driver looks when the process is gone; a worker that hosts
            # none (a spare) leaves no file
            path = fault_file(os.getpid())
            self._faults = open(path, "w")
            faulthandler.enable(self._faults)
            sweep_reports(path.parent)
        places: dict[tuple, Path] = {}  # shipped file -> where it landed: once per file

        def place(shipped) -> Path:
            key = tuple(shipped[:2])  # (path, content digest)
            if key not in places:
                places[key] = landed(shipped)
            return places[key]

        # a worker instantiates hundreds of FMUs in a row, as the in-process backend
        # does: with the collector paused (collector.py)
        with collector_paused():
            for spec, (fmu, scene_files) in zip(specs, files):
                parameters = {**spec.parameters, **{name: ("String", str(place(shipped)))
                                                    for name, shipped in scene_files.items()}}
                # (a table component has no file to place: its spec carries its data)
                self.subsystems.append(open_subsystem(replace(
                    spec, path=spec.path if fmu is None else place(fmu),
                    parameters=parameters)))
                self.written.append({"start": {}, "inputs": {}})
                self.initialized.append(False)
        if ray.get_runtime_context().get_actor_id() is not None:
            # a worker process holds nothing but its instances, which live as long as
            # it does: out of the collector's passes, each of which walks every object
            # of hundreds of instances (a tenth of a second and more at 500 SpringMass
            # instances, on the path of the run's first calls).  Not when a Host is
            # made in another process (a test's), whose other objects those are not.
            gc.freeze()
        return {"node": ray.get_runtime_context().get_node_id(), "pid": os.getpid()}

    def run(self, calls) -> list:
        """Each (slot, [(method, arguments), ...]) in order; the results of each
        subsystem's calls (a list per subsystem).  An error raised by a call carries
        ``dsim_at``: (entry, call) where the calls stopped (those before it were made)."""
        results = []
        for entry, (slot, steps) in enumerate(calls):
            done = []
            for call, (method, arguments) in enumerate(steps):
                try:
                    done.append(self._call(slot, method, arguments))
                except Exception as error:
                    error.dsim_at = (entry, call)  # pickled with it (BaseException.__reduce__)
                    raise
            results.append(done)
        return results

    def run_packed(self, calls, first: int) -> tuple:
        """:meth:`run`, the results of the entries from ``first`` on packed by
        :func:`pack_answers` when they can be (else as they are), those before as they
        are (calls sent ahead, whose answers are other things)."""
        results = self.run(calls)
        packed = pack_answers(results[first:])
        return results[:first], packed, None if packed is not None else results[first:]

    def run_pickled(self, calls: bytes, first: int) -> bytes | tuple:
        """:meth:`run_packed` of a batch the driver sent as one pickle
        (backend._pickled: Ray's own serialization of thousands of arrays costs
        the driver more).  Loaded here, in a worker that trusts its driver as Ray's
        own calls do (Ray pickles every call's arguments).  The answer goes back the
        same way, as bytes (checkpoints are a dict per subsystem), or as it is when
        pickle cannot take it."""
        answer = self.run_packed(pickle.loads(calls), first)
        try:
            return pickle.dumps(answer, protocol=5)
        except (pickle.PicklingError, TypeError, AttributeError):
            return answer

    def _call(self, slot: int, method: str, arguments):
        if method == FAILED:  # taken again: it failed the first time, and may again
            try:
                return self._call(slot, *arguments)
            except Exception:
                return None
        if method == CHECKPOINT:
            return self._checkpoint(slot, *arguments)
        if method == RESUME:
            return self._resume(slot, *arguments)
        if method in REMEMBERED:
            kept = self.written[slot]["inputs" if self.initialized[slot] else "start"]
            kept.pop(method, None)
            kept[method] = arguments
        elif method == "finish_initialization":
            self.initialized[slot] = True
        return getattr(self.subsystems[slot], method)(*arguments)

    def _checkpoint(self, slot: int, snapshot=None) -> bytes | dict:
        """What a fresh worker needs to go on from subsystem ``slot``'s saved state (or
        from the error-controlled step's ``snapshot`` just kept under that key, which
        the fresh worker then keeps too), as one pickle (the driver only keeps it:
        loading each subsystem's arrays there cost a quarter of a second a step at
        chain_10000), or {"error": why not} (an FMU that says it can serialize and
        cannot)."""
        subsystem = self.subsystems[slot]
        try:
            state = (subsystem.checkpoint() if snapshot is None else
                     subsystem.snapshot_checkpoint(snapshot))
        except Exception as error:  # the run goes on; only a restart is not possible
            return {"error": f"{type(error).__name__}: {error}"}
        written = self.written[slot]
        return pickle.dumps({"state": state, "start": list(written["start"].items()),
                             "inputs": list(written["inputs"].items()),
                             "snapshot": snapshot}, protocol=5)

    def _resume(self, slot: int, checkpoint: bytes) -> None:
        """Bring the fresh subsystem ``slot`` to a :meth:`_checkpoint` of another
        worker's: the start inputs in initialization mode, the inputs written last,
        then the saved FMU state."""
        checkpoint = pickle.loads(checkpoint)
        for method, arguments in checkpoint["start"]:
            self._call(slot, method, arguments)
        self._call(slot, "finish_initialization", ())
        for method, arguments in checkpoint["inputs"]:
            self._call(slot, method, arguments)
        self.subsystems[slot].resume(checkpoint["state"])
        if checkpoint.get("snapshot") is not None:  # the calls since go back to it
            self.subsystems[slot].keep_snapshot(checkpoint["snapshot"])

    def close(self) -> list[Exception]:
        """Terminate every subsystem, even if some fail; the errors they raised."""
        errors, self.subsystems = terminate_all(self.subsystems), []
        if self._faults is not None:
            faulthandler.disable()
            self._faults.close()
            self._faults = None
            try:
                fault_file(os.getpid()).unlink()
            except OSError:
                pass
        return errors


class _Unpackable(Exception):
    """An answer :func:`pack_answers` does not pack."""


def _vector(item, sizes: list, arrays: list) -> None:
    if item is None:
        sizes.append(-1)
    elif type(item) is np.ndarray and item.dtype == np.float64 and item.ndim == 1:
        sizes.append(item.size)
        arrays.append(item)
    else:
        raise _Unpackable


def pack_answers(entries) -> tuple | None:
    """Thousands of subsystems' answers of one form, each a list of float64 vectors
    (``v``) and (u, v, a) kinematics (``k``), a missing one None (a kind the FMU lacks),
    as the form (``"kv"`` for a step and its outputs) and two arrays: every value in
    order, and each vector's length (-1: None); None when the answers are not all of
    one such form (inside the one pickle of :meth:`Host.run_pickled`, two arrays
    instead of one per vector).  Ray serialized each numpy array on its own, and
    unpacking 10,000 subsystems' arrays was most of what the driver did in a step of
    chain_10000 (2.13 to 2.46 s a step before, 1.73 to 1.95 s packed; set-up 4.92 to
    5.94 s before, 4.17 to 4.88 s: docs/distributed.md).  Written by hand: Ray has no
    packing of many small arrays."""
    if not entries:
        return None
    form = "".join("k" if type(item) is tuple else "v" for item in entries[0])
    arrays: list = []
    sizes: list = []
    try:
        for done in entries:
            if len(done) != len(form):
                return None
            for code, item in zip(form, done):
                if code == "v":
                    _vector(item, sizes, arrays)
                elif type(item) is tuple and len(item) == 3:
                    for vector in item:
                        _vector(vector, sizes, arrays)
                else:
                    return None
    except _Unpackable:
        return None
    return (form, np.concatenate(arrays) if arrays else np.zeros(0),
            np.array(sizes, dtype=np.int64))


def unpack_answers(form: str, values: np.ndarray, sizes: np.ndarray) -> list:
    """The answers :func:`pack_answers` packed, each vector a view of one writable
    copy of ``values`` (the same bits)."""
    values = np.array(values, dtype=np.float64)
    vectors, start = [], 0
    for size in sizes.tolist():
        if size < 0:
            vectors.append(None)
        else:
            vectors.append(values[start:start + size])
            start += size
    answers, at = [], 0
    while at < len(vectors):
        done = []
        for code in form:
            if code == "k":
                done.append(tuple(vectors[at:at + 3]))
                at += 3
            else:
                done.append(vectors[at])
                at += 1
        answers.append(done)
    return answers


def deal(count: int, workers: int) -> list[list[int]]:
    """Subsystem indices 0..count-1 dealt round-robin onto ``workers`` workers (two
    heavy subsystems declared one after the other land on different workers)."""
    return [list(range(w, count, workers)) for w in range(min(workers, count))]
