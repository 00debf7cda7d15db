"""The small process that supervises ``dsim run`` (docs/results.md, "A run whose process
dies"): the ``dsim`` command runs the run in a child process and waits for it.

Whatever ends the child without its own ending (SIGKILL, the kernel's out-of-memory
killer, Ray ending its driver when the node's raylet goes, a crash in native code), the
supervisor finishes what it leaves as a failed run's files: the CSV under its name with
every whole row, a statistics JSON saying what happened and when, one line on stderr,
exit 1.  When the run writes checkpoints it goes on from the last one by itself
(``--restarts``, 3 unless said, as for lost workers), and the final statistics list
every restart.  Signals reach the child through it (the child runs in a process group
of its own): the first ends the run after its step, a second at once; a child that
is still there 5 s after the second is killed and its files finished here.

Only the standard library and :mod:`dsim.master.recording.output_files` are imported
here: the supervisor stays small (an out-of-memory killer picks the child), and it
imports nothing that starts threads before it starts its child.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

from dsim.master.tools.supervised import REPORT_FD, SUPERVISED
#: seconds a child has to end after the second signal before it is killed
GRACE_SECONDS = 5.0
#: runs started again from a checkpoint, unless ``--restarts`` says
RESTARTS = 3
#: options a restarted run is given again: where it runs (its checkpoint holds the rest)
WHERE_IT_RUNS = ("--backend", "--address", "--call-timeout", "--restarts")


def console() -> None:
    """The ``dsim`` console script: ``dsim run`` under a supervisor (POSIX), every other
    command (and a supervised child, and ``--no-supervisor``) as it is."""
    argv = sys.argv[1:]
    if os.environ.get(SUPERVISED) or os.name != "posix" or argv[:1] != ["run"] or any(
            a in ("-h", "--help", "--no-supervisor") for a in argv):
        from dsim.master.tools.cli import console as command

        command()
        return
    sys.exit(supervise(argv))


def _where(argv) -> list[str]:
    """The options of ``argv`` that say where the run runs, with their values."""
    kept, words = [], iter(argv)
    for word in words:
        name = word.split("=", 1)[0]
        if name in WHERE_IT_RUNS:
            kept.append(word)
            if "=" not in word:
                kept.append(next(words, ""))
    return kept


def _restarts(argv) -> int:
    """``--restarts N`` of ``argv``, else :data:`RESTARTS`."""
    where = _where(argv)
    for word, following in zip(where, where[1:] + [""]):
        name, _, value = word.partition("=")
        if name == "--restarts":
            value = value or following
            return int(value) if value.isdigit() else RESTARTS
    return RESTARTS


def _dies_with(parent: int):
    """What the child runs before dsim: on Linux, it is killed (SIGKILL) when this
    supervisor dies (``prctl(PR_SET_PDEATHSIG)``): a supervisor killed outright takes
    its run with it, as ``dsim`` killed outright did before it had one (the files left
    under their temporary names, for the next run to end)."""
    if not sys.platform.startswith("linux"):
        return None
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)

    def set_up() -> None:
        libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        if os.getppid() != parent:  # it died before the call
            os._exit(1)
    return set_up


def _wait(child: subprocess.Popen) -> int:
    """Wait for ``child``, passing SIGINT, SIGTERM and SIGHUP on; kill it when it has not
    ended ``GRACE_SECONDS`` after the second.  Its return code."""
    received: list[float] = []

    def forward(number, frame):
        received.append(time.monotonic())
        try:
            child.send_signal(number)
        except ProcessLookupError:
            pass

    held = {n: signal.signal(n, forward) for n in (signal.SIGINT, signal.SIGTERM,
                                                   signal.SIGHUP)}
    try:
        while True:
            try:
                return child.wait(timeout=0.1)
            except subprocess.TimeoutExpired:
                if len(received) >= 2 and time.monotonic() - received[1] > GRACE_SECONDS:
                    child.kill()
    finally:
        for number, handler in held.items():
            signal.signal(number, handler)


def _reports(fd: int) -> dict:
    """The last whole line the children wrote on the pipe (parsed), or {}."""
    chunks = []
    while True:
        try:
            chunk = os.read(fd, 65536)
        except BlockingIOError:
            break
        if not chunk:
            break
        chunks.append(chunk)
    lines = [line for line in b"".join(chunks).split(b"\n") if line.strip()]
    try:
        return json.loads(lines[-1]) if lines else {}
    except ValueError:
        return {}


def _ended(code: int) -> str:
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"


def _last_checkpoint(folder) -> tuple[str, float] | None:
    """The newest checkpoint of ``folder`` that has a manifest: (path, time)."""
    if not folder or not os.path.isdir(folder):
        return None
    for name in sorted((n for n in os.listdir(folder) if n.startswith("step-")),
                       reverse=True):
        try:
            with open(os.path.join(folder, name, "manifest.json"), "rb") as stream:
                return os.path.join(folder, name), float(json.load(stream)["time"])
        except (OSError, ValueError, KeyError, TypeError):
            continue
    return None


def _last_row(path) -> tuple[int, float | None]:
    """Whole rows (after the header) of the CSV at ``path`` and the time of the last
    one, read in chunks (a results file may be larger than the supervisor's memory
    should hold; a half row at its end is not counted)."""
    lines, ends, offset = 0, [-1, -1], 0  # the offsets of the last two line ends
    try:
        with open(path, "rb") as stream:
            while chunk := stream.read(1 << 20):
                count = chunk.count(b"\n")
                if count:
                    lines += count
                    last = chunk.rfind(b"\n")
                    before = chunk.rfind(b"\n", 0, last)
                    ends = [offset + before if before >= 0 else ends[1], offset + last]
                offset += len(chunk)
            if lines < 2:
                return 0, None
            stream.seek(ends[0] + 1)
            first = stream.read(64).split(b",", 1)[0]
    except OSError:
        return 0, None
    try:
        return lines - 1, float(first)
    except ValueError:
        return lines - 1, None


def _unfinished(files: dict) -> bool:
    """Whether the child left its results unfinished: a temporary CSV whose lock
    nobody holds."""
    from dsim.master.recording.output_files import lock_is_free, partial_of

    return bool(files.get("csv")) and lock_is_free(partial_of(files["csv"])) is not None


def _finish(files: dict, code: int, restarts: list) -> str:
    """End the files a dead child left as a failed run's: the CSV's whole rows under its
    name, its statistics saying what happened; the line to say."""
    from dsim.master.recording.output_files import (finish_dead_partial, lock_is_free,
                                                    partial_of, write_whole)

    csv, statistics = files["csv"], files.get("statistics")
    partial = partial_of(csv)
    if lock_is_free(partial) is not None:
        fd = os.open(partial, os.O_RDWR | os.O_NOFOLLOW)
        try:
            size = os.fstat(fd).st_size
            tail = os.pread(fd, min(size, 1 << 20), max(0, size - (1 << 20)))
            whole = size - (len(tail) - (tail.rfind(b"\n") + 1))
            os.ftruncate(fd, whole)  # half a row written when it died goes
        finally:
            os.close(fd)
        finish_dead_partial(csv)
    rows, reached = _last_row(csv)
    how = _ended(code)
    at = "" if reached is None else f" at t = {reached:g} s"
    message = (f"the process stepping the run ended without finishing it ({how}){at}: "
               f"its {rows} rows are kept")
    if statistics:
        finish_dead_partial(statistics)  # the empty file it had opened
        data = {"scene": files.get("scene"), "status": "failed", "message": message,
                "time_reached": reached, "rows": rows, "ended": how,
                "exit_code": code if code >= 0 else None,
                "signal": (signal.Signals(-code).name if code < 0 and -code in
                           signal.valid_signals() else None),
                "finished_by": "the supervising process (docs/results.md)",
                "restarts": restarts, "checkpoints": files.get("checkpoints")}
        write_whole(statistics, json.dumps(data, indent=2).encode())
    return (f"dsim: simulation failed: {message} in {csv}"
            + (f", statistics in {statistics}" if statistics else ""))


def _note_restarts(files: dict, restarts: list) -> None:
    """Add the restarts to the statistics of the run that ended them."""
    from dsim.master.recording.output_files import write_whole

    path = files.get("statistics")
    if not (path and restarts and os.path.isfile(path)):
        return
    try:
        with open(path, "rb") as stream:
            data = json.load(stream)
        data["restarts"] = restarts
        write_whole(path, json.dumps(data, indent=2).encode())
    except (OSError, ValueError):
        pass


def supervise(argv) -> int:
    """Run ``dsim ARGV`` in a child process and see its files finished, going on from
    its last checkpoint when it dies; the exit code."""
    read_end, write_end = os.pipe()
    os.set_blocking(read_end, False)
    env = {**os.environ, SUPERVISED: "1", REPORT_FD: str(write_end)}
    command = [sys.executable, "-m", "dsim", *argv]
    allowed, restarts, files = _restarts(argv), [], {}
    while True:
        child = subprocess.Popen(command, env=env, pass_fds=(write_end,), process_group=0,
                                 preexec_fn=_dies_with(os.getpid()))
        code = _wait(child)
        files = _reports(read_end) or files
        if not _unfinished(files):
            _note_restarts(files, restarts)
            if code < 0:
                print(f"dsim: the run's process ended ({_ended(code)})", file=sys.stderr)
                return 128 - code
            return code
        found = _last_checkpoint(files.get("checkpoints"))
        if found is None or len(restarts) >= allowed:
            print(_finish(files, code, restarts), file=sys.stderr)
            return 1
        from dsim.master.recording.output_files import partial_of

        _, reached = _last_row(partial_of(files["csv"]))
        restarts.append({"ended": _ended(code), "time_reached": reached,
                         "resumed_from": os.path.basename(found[0]), "time": found[1]})
        print(f"dsim: the process stepping the run ended ({_ended(code)})"
              + ("" if reached is None else f" at t = {reached:g} s")
              + f"; going on from its checkpoint at t = {found[1]:g} s (restart "
              f"{len(restarts)} of {allowed})", file=sys.stderr)
        command = [sys.executable, "-m", "dsim", "run", "--resume",
                   os.path.dirname(found[0]), *_where(argv),
                   *[a for a in argv if a == "--quiet"]]
