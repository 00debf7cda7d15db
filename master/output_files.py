"""Files a run writes, written like a storage engineer would.

* A run never writes over one of its own inputs (the scene, its FMUs, its
  parameter files): refused before anything runs.
* The file is written under a temporary name beside the target
  (``.NAME.partial``) and renamed to the target when the run ends, whatever the
  ending, so a reader never sees a file that is still growing under the final
  name, and a failed or interrupted run keeps its rows under the final name.
* The temporary file is locked (``flock``) while the run writes it: a second run
  on the same target is refused instead of interleaving its rows.  A lock dies
  with its process, so a killed run leaves no stale lock.
* Data goes to the file in whole records: a record that cannot be written in full
  (a full disk, a file size limit) is cut off again, and the error is raised.
"""
from __future__ import annotations

import errno
import fcntl
import os
from pathlib import Path

from master.errors import InputError


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
    for source in inputs:
        source = Path(source)
        if target.resolve() == source.resolve() or _same_file(target, source):
            raise InputError(f"{target}: this output would overwrite an input of the run "
                             f"({source}); choose another output file")


class OutputFile:
    """One results file of a run: see the module docstring."""

    def __init__(self, target, inputs=()):
        self.target = Path(target)
        self.partial = self.target.with_name(f".{self.target.name}.partial")
        self.inputs = list(inputs)
        self._fd: int | None = None
        self.size = 0

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
            fd = os.open(self.partial, os.O_WRONLY | os.O_CREAT, 0o644)
        except OSError as error:
            raise InputError(f"{self.target}: cannot write: {error.strerror}") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as error:
            os.close(fd)
            if error.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise InputError(f"{self.target}: another run is writing this file now "
                                 f"({self.partial.name} is locked); wait for it or choose "
                                 "another output") from None
            raise InputError(f"{self.target}: cannot lock: {error.strerror}") from None
        os.ftruncate(fd, 0)
        self._fd = fd
        self.size = 0

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

    def commit(self) -> None:
        """Rename the temporary file to the target and release the lock."""
        if self._fd is None:
            return
        try:
            os.replace(self.partial, self.target)
        finally:
            os.close(self._fd)
            self._fd = None

    def discard(self) -> None:
        """Remove the temporary file and release the lock (nothing was run)."""
        if self._fd is None:
            return
        try:
            os.unlink(self.partial)
        except OSError:
            pass
        finally:
            os.close(self._fd)
            self._fd = None


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
