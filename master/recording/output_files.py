"""Files a run writes, written like a storage engineer would.

* A run never writes over one of its own inputs (the scene, its FMUs, its
  parameter files): refused before anything runs.
* The file is written under a temporary name beside the target
  (``.NAME.partial``) and renamed to the target when the run ends, whatever the
  ending, so a reader never sees a file that is still growing under the final
  name, and a failed or interrupted run keeps its rows under the final name.
* The temporary file is a file this run creates: made under a name of its own
  (``O_CREAT | O_EXCL | O_NOFOLLOW``), locked (``flock``), and only then linked to
  ``.NAME.partial``, which fails if anything is there.  So no path that existed
  before is ever opened for writing (a link planted at the temporary name cannot
  redirect the rows into another file), and a ``.NAME.partial`` is always locked
  while its run lives: a second run on the same target is refused instead of
  interleaving its rows, and one whose lock nobody holds was left by a killed run
  and is ended for it: renamed to the target, its rows kept (removed when empty).  The final rename replaces whatever is at the target (a link
  included: rename never follows it), and only after checking that the temporary
  name still holds this run's file.
* Data goes to the file in whole records: a record that cannot be written in full
  (a full disk, a file size limit) is cut off again, and the error is raised.
"""
from __future__ import annotations

import errno
import fcntl
import hashlib
import os
import secrets
import shutil
import stat
import time
from pathlib import Path

from dsim.master.errors import InputError

#: seconds after which an unlocked temporary file of a folder is surely not being
#: made right now (a run locks its file microseconds after creating it)
STALE_SECONDS = 60


class OutputError(Exception):
    """Writing a results file failed during the run (a full disk, for example)."""


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def check_not_input(target: Path, inputs) -> None:
    """Refuse a target that is one of the run's inputs (or inside an input archive's
    place): InputError naming both."""
    target = Path(target)
    resolved = target.resolve()
    # each input once: every component of a large scene names the same FMU file
    for source in dict.fromkeys(Path(source) for source in inputs):
        if resolved == source.resolve() or _same_file(target, source):
            raise InputError(f"{target}: this output would overwrite an input of the run "
                             f"({source}); choose another output file")


def lock_is_free(path: Path) -> os.stat_result | None:
    """The status of the regular file at ``path`` when no process holds its lock (its
    writer is dead), else None.  Opened read-only and without following a link."""
    try:
        if not stat.S_ISREG(os.stat(path, follow_symlinks=False).st_mode):
            return None  # a link, a FIFO, a device: never opened
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            return None
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return None
    finally:
        os.close(fd)  # the lock goes with it: whoever removes the file checks again
    return info


def _same(path: Path, info: os.stat_result) -> bool:
    """Whether ``path`` (not followed) is still the file ``info`` describes."""
    try:
        now = os.stat(path, follow_symlinks=False)
    except OSError:
        return False
    return (now.st_dev, now.st_ino) == (info.st_dev, info.st_ino)


def _finish_for_the_dead(path: Path, info: os.stat_result) -> None:
    """End a killed run's temporary file as the run would have ended it: a
    ``.NAME.partial`` with rows is renamed to NAME (its converged rows kept under the
    final name, as for an interrupted run; rename never follows a link at NAME), an
    empty one or a ``.tmp`` is removed."""
    name = path.name
    if name.endswith(".partial") and info.st_size > 0:
        os.replace(path, path.with_name(name[1:-len(".partial")]))
    else:
        os.unlink(path)


def partial_of(target) -> Path:
    """The temporary name a run writes ``target`` under: ``.NAME.partial`` beside it."""
    target = Path(target)
    return target.with_name(f".{target.name}.partial")


def finish_dead_partial(target: Path) -> bool:
    """End the temporary file of ``target`` that a killed run left (its lock free) as
    that run would have: rows renamed to ``target``, an empty file removed.  Whether
    there was one; a live run's file is left alone."""
    partial = partial_of(target)
    info = lock_is_free(partial)
    if info is None or not _same(partial, info):
        return False
    _finish_for_the_dead(partial, info)
    return True


def sweep_dead_partials(folder: Path) -> list[Path]:
    """End the temporary files of ``folder`` left by killed runs (a ``.*.partial`` or
    ``.*.tmp`` regular file whose lock nobody holds, untouched for
    :data:`STALE_SECONDS`) by :func:`_finish_for_the_dead`; the files ended."""
    removed = []
    try:
        names = [n for n in os.listdir(folder) if n.startswith(".")
                 and n.endswith((".partial", ".tmp"))]
    except OSError:
        return removed
    for name in names:
        path = folder / name
        info = lock_is_free(path)
        if info and time.time() - info.st_mtime > STALE_SECONDS and _same(path, info):
            try:
                _finish_for_the_dead(path, info)
                removed.append(path)
            except OSError:
                pass
    return removed


class OutputFile:
    """One results file of a run: see the module docstring."""

    def __init__(self, target, inputs=()):
        self.target = Path(target)
        self.partial = partial_of(self.target)
        self.inputs = list(inputs)
        self._fd: int | None = None
        self._info: os.stat_result | None = None
        self.size = 0
        #: SHA-256 of the bytes written so far, when asked for (:meth:`keep_digest`: a
        #: run with checkpoints records it), else None
        self.digest = None

    def keep_digest(self) -> None:
        """Keep the SHA-256 of everything written from now on (call before writing)."""
        self.digest = hashlib.sha256()

    def sync(self) -> None:
        """Flush what was written to the disk (``fsync``)."""
        if self._fd is not None:
            os.fsync(self._fd)

    def copy_prefix(self, source: Path, count: int, digest: str) -> None:
        """Append the first ``count`` bytes of the regular file ``source`` (not followed
        if a link), which must have SHA-256 ``digest``; InputError (nothing kept of
        them) when it is shorter or differs."""
        check = hashlib.sha256()
        try:
            fd = os.open(source, os.O_RDONLY | os.O_NOFOLLOW)
        except OSError as error:
            raise InputError(f"{source}: cannot read the results to go on from: "
                             f"{error.strerror}") from None
        start = self.size
        try:
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                raise InputError(f"{source}: not a regular file")
            left = count
            while left > 0:
                chunk = os.read(fd, min(left, 1 << 20))
                if not chunk:
                    break
                check.update(chunk)
                self.append(chunk)
                left -= len(chunk)
        except OutputError as error:
            raise InputError(str(error)) from None
        finally:
            os.close(fd)
        if left > 0 or check.hexdigest() != digest:
            os.ftruncate(self._fd, start)
            self.size = start
            raise InputError(f"{source}: does not begin with the rows the checkpoint saw "
                             "(shortened, changed or another run's since): the run cannot "
                             "go on from it; start a new one (--from)")

    def open(self) -> None:
        """Create and lock the temporary file; InputError when the target is an
        input, cannot be written, or is being written by another run."""
        check_not_input(self.target, self.inputs)
        if self.target.is_dir():
            raise InputError(f"{self.target}: is a folder, not a file name")
        for folder in self.target.parents:
            if folder.exists():
                if not folder.is_dir():
                    raise InputError(f"{self.target}: cannot write: {folder} is a file, "
                                     "not a folder")
                break
        try:
            self.target.parent.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise InputError(f"{self.target}: cannot write: {error.strerror}") from None
        sweep_dead_partials(self.target.parent)
        fd = self._create()
        self._fd, self._info, self.size = fd, os.fstat(fd), 0

    def _create(self) -> int:
        """A new locked file, then linked to the temporary name (see the docstring)."""
        own = self.target.with_name(f".{self.target.name}.{secrets.token_hex(6)}.tmp")
        try:
            fd = os.open(own, os.O_RDWR | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o644)
        except OSError as error:
            raise InputError(f"{self.target}: cannot write: {error.strerror}") from None
        fcntl.flock(fd, fcntl.LOCK_EX)  # a file nobody else can know yet: never waits
        try:
            for _ in range(3):  # a dead run's file removed under us by a third run: again
                try:
                    os.link(own, self.partial, follow_symlinks=False)
                    return fd
                except FileExistsError:
                    self._clear_dead_partial()
                except OSError as error:
                    if error.errno in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP):
                        # no hard links here (some network and FAT file systems): the
                        # rename is as exclusive, only not atomic with the check
                        if os.path.lexists(self.partial):
                            self._clear_dead_partial()
                        os.rename(own, self.partial)
                        return fd
                    raise InputError(f"{self.target}: cannot write: "
                                     f"{error.strerror}") from None
            raise InputError(f"{self.target}: another run is writing this file now")
        except BaseException:
            os.close(fd)
            raise
        finally:
            try:
                os.unlink(own)
            except OSError:
                pass

    def _clear_dead_partial(self) -> None:
        """Remove a temporary file at the temporary name whose run is dead; InputError
        when a live run holds it or it is not a file dsim writes (a link)."""
        try:
            info = os.stat(self.partial, follow_symlinks=False)
        except FileNotFoundError:
            return
        if not stat.S_ISREG(info.st_mode):
            raise InputError(f"{self.target}: {self.partial.name} exists and is not a file "
                             "dsim wrote (a link or a folder): remove it, or choose another "
                             "output")
        dead = lock_is_free(self.partial)
        if dead is None:
            raise InputError(f"{self.target}: another run is writing this file now "
                             f"({self.partial.name} is locked); wait for it or choose "
                             "another output")
        if _same(self.partial, dead):
            # a killed run's rows go to the final name first (nothing a run converged is
            # lost); this run's file replaces them there when it ends
            _finish_for_the_dead(self.partial, dead)

    @property
    def is_open(self) -> bool:
        return self._fd is not None

    def append(self, data: bytes, separator: bytes | None = None) -> None:
        """Write records: ``data`` is one record, or several ended by ``separator``.
        If it cannot be written in full, cut the file back to the last whole record
        that was written and raise OutputError."""
        view = memoryview(data)
        written = 0
        try:
            while written < len(view):
                written += os.write(self._fd, view[written:])
        except OSError as error:
            whole = data.rfind(separator, 0, written) + 1 if separator else 0
            try:
                os.ftruncate(self._fd, self.size + whole)
                self.size += whole
            except OSError:
                pass
            raise OutputError(f"cannot write {self.target}: {error.strerror}") from None
        self.size += written
        if self.digest is not None:
            self.digest.update(view)

    def commit(self) -> None:
        """Rename the temporary file to the target and release the lock; OutputError
        (nothing renamed) when the temporary name no longer holds this run's file."""
        if self._fd is None:
            return
        try:
            if not _same(self.partial, self._info):
                raise OutputError(f"cannot write {self.target}: {self.partial.name} was "
                                  "removed or replaced during the run")
            os.replace(self.partial, self.target)  # replaces a link, never follows it
        finally:
            os.close(self._fd)
            self._fd = None

    def discard(self) -> None:
        """Remove the temporary file and release the lock (nothing was run)."""
        if self._fd is None:
            return
        try:
            if _same(self.partial, self._info):
                os.unlink(self.partial)
        except OSError:
            pass
        finally:
            os.close(self._fd)
            self._fd = None


def check_fits(target: Path, rows: int, columns: int) -> None:
    """Refuse (InputError, one line) a CSV of ``rows`` rows of ``columns`` numbers that
    would not fit the free space of ``target``'s file system: better said before the
    run than found when the disk is full."""
    need = rows * columns * BYTES_PER_VALUE
    folder = next((f for f in (target.parent, *target.parents) if f.is_dir()), Path("."))
    try:
        free = shutil.disk_usage(folder).free
    except OSError:
        return
    if need > free:
        raise InputError(f"{target}: the results would take about {_size(need)} ({rows:.3g} "
                         f"rows of {columns} columns) but {folder} has {_size(free)} free; "
                         "shorten the run or take a larger step (--force runs anyway)")


#: bytes per value of a results CSV: ``repr`` of a double is up to 24 characters,
#: most are 18 to 20, and a comma
BYTES_PER_VALUE = 20


def _size(count: float) -> str:
    for unit in ("bytes", "kB", "MB", "GB", "TB", "PB"):
        if count < 1000 or unit == "PB":
            return f"{count:.0f} {unit}" if unit == "bytes" else f"{count:.3g} {unit}"
        count /= 1000
    return ""


def write_whole(target, data: bytes, inputs=()) -> None:
    """Write a small file (statistics, a plot) atomically: under the temporary name,
    locked, then renamed; OutputError if it cannot be written."""
    output = OutputFile(target, inputs)
    output.open()
    try:
        output.append(data)
    except OutputError:
        output.discard()
        raise
    output.commit()
