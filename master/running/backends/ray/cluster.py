"""The connection to Ray that the ray backends and ``dsim sweep --backend ray`` share.

:func:`connect` joins the Ray instance this process is already connected to (a
script's own ``ray.init``), else the cluster at an address (``ray start --head``),
else starts a private local instance; :meth:`Connection.close` disconnects, and
shuts a local instance down, only when this connection made it.  Everything that
goes wrong here is bad input or usage (:class:`~dsim.master.errors.InputError`: exit 2,
one line), never a traceback: Ray missing, a malformed or unreachable address.
"""
from __future__ import annotations

import hashlib
import logging
import os
import signal
import socket
import sys
import tempfile
import threading
import time as clock
from pathlib import Path

from dsim.master.errors import InputError
from dsim.master.running.private_folder import private_folder

#: how to get Ray, said whenever it is missing
INSTALL = "pip install 'dsim[ray]'"
#: object store of a local instance started by dsim (bytes): only small arrays and
#: results move through it (a sweep point's CSV at most)
LOCAL_OBJECT_STORE = 256 * 1024 ** 2
#: seconds to wait for a TCP answer from a cluster's address before calling it
#: unreachable (Ray itself retries for minutes)
REACH_SECONDS = 5.0
#: the head watch: seconds between two looks at the head's GCS port, and the looks in a
#: row that find nothing listening before the head is called lost
HEAD_EVERY, HEAD_MISSES = 1.0, 3
#: when this process began (a Ray log older than that is another process's)
_BEGAN = clock.time()


def ray_module():
    """The ``ray`` package, or InputError saying how to install it."""
    try:
        import ray
    except ImportError as error:
        raise InputError(f"the Ray backends need the ray package ({error}): {INSTALL}") \
            from None
    return ray


def available() -> bool:
    """Whether Ray can be imported."""
    try:
        ray_module()
    except InputError:
        return False
    return True


def address_problem(address: str) -> str | None:
    """What is wrong with the form of a cluster address, or None.  Valid: ``auto``
    (the cluster ``ray start`` started on this machine), ``HOST:PORT`` (the head's
    GCS address) and ``ray://HOST:PORT`` (Ray Client)."""
    if address == "auto":
        return None
    host, port = _host_port(address)
    if not host or port is None:
        return (f"setting address '{address}' is not HOST:PORT, ray://HOST:PORT or auto "
                "(the address that `ray start --head` prints)")
    return None


def _host_port(address: str) -> tuple[str, int | None]:
    text = address[len("ray://"):] if address.startswith("ray://") else address
    host, _, port = text.rpartition(":")
    return host.strip("[]"), int(port) if port.isdigit() and 0 < int(port) < 65536 else None


#: what lets go of the Ray objects it holds when this process's connection ends, before
#: it ends (spares.forget: the workers started ahead of a run and not taken): Ray
#: objects left for after ``ray.shutdown`` are a handle into a core worker that is gone
BEFORE_SHUTDOWN: list = []


class Connection:
    """This process's connection to Ray; ``owned`` when :func:`connect` made it (and
    then :meth:`close` undoes it); ``address``: the cluster's, when one was given."""

    def __init__(self, ray, owned: bool, address: str | None = None):
        self.ray = ray
        self.owned = owned
        self.address = address
        #: made before its run's scene was read (connect_ahead): workers were started
        #: ahead for that run (spares.ahead)
        self.ahead = False

    def cpus(self, resource: str = "") -> int:
        """Logical CPUs of the live nodes (those holding ``resource``, if named)."""
        total = 0.0
        for node in self.ray.nodes():
            resources = node.get("Resources", {})
            if node.get("Alive") and (not resource or resources.get(resource, 0) > 0):
                total += resources.get("CPU", 0.0)
        return int(total)

    def resources(self) -> set[str]:
        """Names of every resource of the cluster (custom ones, ``node:IP``, CPU...)."""
        return set(self.ray.cluster_resources())

    def close(self) -> None:
        if self.owned and self.ray.is_initialized():
            for let_go in BEFORE_SHUTDOWN:
                let_go()
            self.ray.shutdown()
        self.owned = False


#: the connection :func:`connect_ahead` made for the run about to begin, until that
#: run's backend takes it (:func:`connect`) or the run ends without one (:func:`release`)
_ahead: list[Connection] = []


def connect_ahead(address: str | None) -> Connection | None:
    """Join the cluster at ``address`` before the run's scene is read and planned, so
    that its workers start meanwhile (spares.ahead): the backend then takes this
    connection, and ends it as its own.  Only for an address (a running cluster, a
    fraction of a second to join): a new local instance takes seconds to start, a
    cost a scene refused as bad input should not pay.  None when there is no address
    or this process is already connected.  InputError as :func:`connect`."""
    if not address:
        return None
    ray = ray_module()
    if ray.is_initialized():
        return None
    connection = connect(address)
    connection.ahead = True
    _ahead.append(connection)
    return connection


def made_ahead() -> Connection | None:
    """The connection :func:`connect_ahead` made for the run about to begin (always
    this process's own, to a cluster's address), until that run's backend takes it;
    else None."""
    return _ahead[-1] if _ahead else None


def release() -> None:
    """End the connection made ahead of a run that did not take it (refused as bad
    input before its backend started)."""
    while _ahead:
        _ahead.pop().close()


def joined() -> bool:
    """Whether this process is connected to Ray (without importing Ray: a process that
    never imported it is connected to none)."""
    ray = sys.modules.get("ray")
    return ray is not None and ray.is_initialized()


def starts_ray(address: str | None) -> bool:
    """Whether :func:`connect` would start a local Ray instance (seconds)."""
    return not address and not joined()


def connect(address: str | None = None) -> Connection:
    """Join Ray: the instance this process is connected to, the cluster at
    ``address``, or (no address) a new local instance with every core of the
    machine.  InputError when Ray is missing or the cluster cannot be reached."""
    ray = ray_module()
    _quiet_worker_deaths(ray)
    if _ahead and ray.is_initialized() and _ahead[-1].address == address:
        return _ahead.pop()  # made for this run (connect_ahead): ended with it
    if ray.is_initialized():  # a script's (or a test session's) own instance
        return Connection(ray, owned=False)
    if address:
        problem = address_problem(address)
        if problem:
            raise InputError(problem)
        _check_reachable(address)
    options = dict(address=address or "local", logging_level=logging.ERROR,
                   log_to_driver=False, configure_logging=True)
    if not address:
        options.update(include_dashboard=False, object_store_memory=LOCAL_OBJECT_STORE)
    # ray.init replaces the driver's SIGTERM handler: the run's own (stop after the
    # current step, results kept) must stay in force
    in_main = threading.current_thread() is threading.main_thread()
    previous = signal.getsignal(signal.SIGTERM) if in_main else None
    try:
        ray.init(**options)
    except Exception as error:  # ConnectionError, ValueError, RuntimeError, Ray's own
        if address:  # the same answer whatever listens there (see _check_reachable)
            raise InputError(_unreachable(address)) from None
        raise InputError(f"cannot connect to a local Ray instance: "
                         f"{' '.join(str(error).split())[:300]}") from None
    finally:
        if in_main and previous is not None:
            signal.signal(signal.SIGTERM, previous)
    return Connection(ray, owned=True, address=address)


def _check_reachable(address: str) -> None:
    """A quick TCP check: Ray waits minutes on an address where nothing listens."""
    if address == "auto":
        return
    host, port = _host_port(address)
    try:
        with socket.create_connection((host, port), timeout=REACH_SECONDS) as connection:
            # a Ray head (GCS, or Ray Client) speaks gRPC: HTTP/2 answers the client's
            # preface with a SETTINGS frame; anything else listening there is no cluster
            # (and Ray would wait minutes on it, printing its own warnings)
            connection.settimeout(REACH_SECONDS)
            connection.sendall(b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + _EMPTY_SETTINGS)
            header = b""
            while len(header) < 9:
                chunk = connection.recv(9 - len(header))
                if not chunk:
                    break
                header += chunk
    except OSError:
        header = b""
    if len(header) < 9 or header[3] != 0x4:  # frame type 4: SETTINGS
        raise InputError(_unreachable(address))


#: an HTTP/2 SETTINGS frame with no settings: length 0, type 4, no flags, stream 0
_EMPTY_SETTINGS = b"\x00\x00\x00\x04\x00\x00\x00\x00\x00"


def _unreachable(address: str) -> str:
    """The one answer for an address where no Ray cluster answers: a closed port, a
    silent one and one where something else listens read the same, so that the
    setting (a run setting of ``dsim serve`` too) tells nothing about the network.  In
    a process without ``RAY_AUTH_MODE=token`` it also says what a cluster with token
    authentication (``ray start --head``'s default since Ray 2.52) needs: Ray itself
    reports such a refusal only as warnings, then as a failure to connect."""
    said = (f"setting address '{address}': no Ray cluster answers there; start one with "
            "`ray start --head` and give the address it prints")
    if os.environ.get("RAY_AUTH_MODE", "").strip().lower() != "token":
        said += (" (a cluster with token authentication, the default of `ray start` since "
                 "Ray 2.52, also needs RAY_AUTH_MODE=token and its token here: "
                 "docs/distributed.md, \"Authentication\")")
    return said


def watch_head(ray, on_lost, over) -> bool:
    """Call ``on_lost(what)`` from a thread of its own when the cluster's head (its
    GCS) stops answering: :data:`HEAD_MISSES` looks in a row, :data:`HEAD_EVERY` s
    apart, find nothing listening at its address; the watch ends when ``over()``.
    Ray itself would wait a minute, then end this process without a word of its own.
    False when there is no address to watch (Ray Client, or a Ray that does not say)."""
    try:
        address = ray.get_runtime_context().gcs_address
    except Exception:
        return False
    host, _, port = str(address).rpartition(":")
    if not host or not port.isdigit():
        return False

    def watch():
        misses = 0
        while not over():
            clock.sleep(HEAD_EVERY)
            misses = 0 if listening(host, int(port)) else misses + 1
            if misses >= HEAD_MISSES and not over():
                on_lost(f"lost the Ray head (its GCS at {address} stopped answering)")
                return

    threading.Thread(target=watch, name="dsim-ray-head", daemon=True).start()
    return True


def listening(host: str, port: int) -> bool:
    """Whether something accepts a TCP connection at host:port (within a second)."""
    try:
        with socket.create_connection((host, port), timeout=1.0):
            return True
    except OSError:
        return False


def ray_log_line() -> str | None:
    """The line that names :func:`ray_log` after something failed, when Ray's
    processes said anything to this process (else None)."""
    path = ray_log()
    try:
        if path.stat().st_mtime >= _BEGAN:
            return f"dsim: what Ray's own processes said meanwhile is in {path}"
    except OSError:
        pass
    return None


_QUIETED = False


def ray_log() -> Path:
    """Where this process keeps what Ray's own processes said to it (a raylet's notice
    of a dead worker, its post-mortem when it is lost): never on dsim's output."""
    return private_folder(Path(tempfile.gettempdir()) / f"dsim-{os.getuid()}") / \
        f"ray-{os.getpid()}.log"


def _quiet_worker_deaths(ray) -> None:
    """Keep Ray's raylet messages (the multi-line notice of a worker process that died,
    a lost raylet's post-mortem) off the driver's output, in :func:`ray_log`: the run
    says what happened in one line naming the component and the time.  (Ray prints
    them from a thread of every driver; the hook is internal to Ray, so if it is not
    there they are only noise, never a failure.)"""
    global _QUIETED
    if _QUIETED:
        return
    _QUIETED = True
    try:
        from ray._private import worker as ray_worker
        original = ray_worker.print_to_stdstream
    except (ImportError, AttributeError):
        return

    def filtered(data, *args, **kwargs):
        if isinstance(data, dict) and data.get("pid") == "raylet":
            try:
                path = ray_log()
                path.parent.mkdir(parents=True, exist_ok=True)
                with open(path, "a") as log:
                    log.write("".join(f"{line}\n" for line in data.get("lines", [])))
            except OSError:  # the log is a courtesy; the output stays quiet regardless
                pass
            return None
        return original(data, *args, **kwargs)

    ray_worker.print_to_stdstream = filtered


class Shipment:
    """Files a driver sends to its workers through Ray's object store (an FMU, a
    scene archive), so that a worker on another machine needs no shared folder:
    each distinct file is put once; :func:`landed` finds it on the worker's node."""

    def __init__(self, ray):
        self.ray = ray
        self._shipped: dict[Path, tuple[str, str, object]] = {}

    def add(self, path) -> tuple[str, str, object]:
        """What a worker needs to find ``path``: (path, content digest, object
        reference of the content)."""
        path = Path(path)
        if path not in self._shipped:
            data = path.read_bytes()
            self._shipped[path] = (str(path), _digest(data), self.ray.put(data))
        return self._shipped[path]


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def landed(shipped: tuple[str, str, object]) -> Path:
    """The shipped file on this node: the driver's own path when it holds the same
    content here (one machine, a shared folder), else a copy in a folder named by the
    content, written once per node (atomically: workers of a node land it together)."""
    path, digest, ref = shipped
    original = Path(path)
    if original.is_file() and _digest(original.read_bytes()) == digest:
        return original
    import tempfile

    import ray

    folder = private_folder(Path(tempfile.gettempdir()) / f"dsim-worker-{os.getuid()}") \
        / digest[:32]
    target = folder / original.name
    if not target.is_file():
        folder.mkdir(parents=True, exist_ok=True)
        partial = folder / f".{original.name}.{os.getpid()}.partial"
        partial.write_bytes(ray.get(ref))
        os.replace(partial, target)
    return target
