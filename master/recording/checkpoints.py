"""Checkpoint folders, written so that a checkpoint is whole or absent
(docs/checkpoints.md).

A run's checkpoints sit in one folder (``run.checkpoints`` beside ``run.csv``), each
in its own sub-folder ``step-NNNNNNNNNN``:

* ``manifest.json``: the format, dsim's version, the step and time, what the run was
  asked (the scene, its settings), the digests of the files the run read, the
  results file's length and SHA-256 at that step, and the length and SHA-256 of the
  two files below;
* ``state.json`` and ``arrays.npz``: dsim's own state and every FMU's serialized
  state (:mod:`~dsim.master.recording.state_codec`: no pickle).

A checkpoint is made in a new folder of its own name (``mkdir`` fails if anything is
there), its files created (``O_EXCL | O_NOFOLLOW``), written, flushed to the disk
(``fsync``), then the folder is renamed to its ``step-`` name and the parent flushed:
a process killed at any point leaves either the whole checkpoint or a ``.tmp``
folder that the next run removes.  The last ``keep`` checkpoints stay.  The folder
is locked (``flock``) for the run's life: a second run is refused instead of
interleaving its checkpoints.
"""
from __future__ import annotations

import fcntl
import hashlib
import io
import json
import os
import re
import secrets
import stat
import time as clock
from pathlib import Path

import numpy as np

from dsim.master.errors import InputError
from dsim.master.recording.output_files import OutputError, check_not_input
from dsim.master.recording.state_codec import encode

#: the manifest's ``format``: a checkpoint of another format is refused
FORMAT = "dsim checkpoint 1"
#: a checkpoint's folder name: the step it was taken at, ten digits (sorted by name)
NAME = re.compile(r"^step-(\d{10})$")


def checkpoint_name(step: int) -> str:
    """The folder name of the checkpoint at macro step ``step``."""
    return f"step-{step:010d}"


def checkpoints_beside(results) -> Path:
    """The default checkpoint folder of a run writing ``results``: ``NAME.checkpoints``
    beside it (``run.csv`` -> ``run.checkpoints``)."""
    results = Path(results)
    return results.with_name(f"{results.stem}.checkpoints")


def _write_new(folder_fd: int, name: str, data: bytes) -> dict:
    """Create ``name`` in the folder (never an existing path), write ``data``, flush it
    to the disk; its length and SHA-256."""
    fd = os.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o644,
                 dir_fd=folder_fd)
    try:
        view, written = memoryview(data), 0
        while written < len(view):
            written += os.write(fd, view[written:])
        os.fsync(fd)
    finally:
        os.close(fd)
    return {"bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}


def arrays_bytes(arrays: dict) -> bytes:
    """The arrays as an uncompressed .npz (what ``numpy.load(allow_pickle=False)``
    reads; stored, not deflated, so that a reader can bound what it unpacks)."""
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


class CheckpointFolder:
    """The checkpoint folder of one run: made, locked, written to, pruned."""

    def __init__(self, folder, keep: int = 2, inputs=()):
        self.folder = Path(folder)
        self.keep = keep
        self.inputs = list(inputs)
        self._fd: int | None = None
        #: the checkpoints written by this run: (step, folder)
        self.written: list[tuple[int, Path]] = []
        #: seconds spent writing them, and their bytes
        self.seconds = 0.0
        self.bytes = 0

    def open(self) -> None:
        """Make (or take) the folder and lock it; InputError when it is an input of the
        run, not a folder dsim can own (a link, a file), or another run's now."""
        folder = self.folder
        check_not_input(folder, self.inputs)
        try:
            info = os.stat(folder, follow_symlinks=False)
        except FileNotFoundError:
            try:
                folder.mkdir(parents=True)
            except OSError as error:
                raise InputError(f"{folder}: cannot make the checkpoint folder: "
                                 f"{error.strerror}") from None
            info = os.stat(folder, follow_symlinks=False)
        if not stat.S_ISDIR(info.st_mode):
            raise InputError(f"{folder}: the checkpoint folder is not a folder (a file or "
                             "a link); remove it or choose another (--checkpoints)")
        fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            raise InputError(f"{folder}: another run is writing checkpoints here now; "
                             "wait for it or choose another folder (--checkpoints)") from None
        self._fd = fd
        for name in os.listdir(fd):  # what a killed run left half made
            if name.startswith(".") and name.endswith(".tmp"):
                _remove_folder(fd, name)

    def write(self, step: int, manifest: dict, state) -> Path:
        """Write the checkpoint of macro step ``step``: ``state`` (plain data and numpy
        arrays, which go into arrays.npz) and ``manifest`` (plain JSON), whole or not at
        all; the older ones beyond ``keep`` removed.  OutputError when it cannot be
        written (the run goes on without it)."""
        started = clock.perf_counter()
        tree, arrays = encode(state, {})
        name = checkpoint_name(step)
        temporary = f".{name}.{secrets.token_hex(6)}.tmp"
        fd = self._fd
        try:
            os.mkdir(temporary, 0o755, dir_fd=fd)
            inner = os.open(temporary, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW,
                            dir_fd=fd)
            try:
                files = {"state.json": _write_new(inner, "state.json",
                                                  json.dumps(tree).encode()),
                         "arrays.npz": _write_new(inner, "arrays.npz",
                                                  arrays_bytes(arrays))}
                document = {"format": FORMAT, **manifest, "files": files}
                _write_new(inner, "manifest.json", json.dumps(document, indent=1).encode())
                os.fsync(inner)
            finally:
                os.close(inner)
            if os.path.lexists(self.folder / name):  # a resumed run passing it again
                _remove_folder(fd, name)
            os.rename(temporary, name, src_dir_fd=fd, dst_dir_fd=fd)
            os.fsync(fd)
        except OSError as error:
            _remove_folder(fd, temporary)
            raise OutputError(f"cannot write the checkpoint {self.folder / name}: "
                              f"{error.strerror}") from None
        self.written.append((step, self.folder / name))
        self.bytes += sum(f["bytes"] for f in files.values())
        self._prune()
        self.seconds += clock.perf_counter() - started
        return self.folder / name

    def _prune(self) -> None:
        """Remove the checkpoints beyond the last ``keep`` (by step)."""
        steps = sorted((int(m.group(1)), name) for name in os.listdir(self._fd)
                       if (m := NAME.match(name)))
        for _, name in steps[:-self.keep] if self.keep > 0 else steps:
            _remove_folder(self._fd, name)

    def close(self) -> None:
        """Release the folder's lock."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


def _remove_folder(parent_fd: int, name: str) -> None:
    """Remove the folder ``name`` of the open folder (a link there only unlinked)."""
    try:
        info = os.stat(name, dir_fd=parent_fd, follow_symlinks=False)
    except OSError:
        return
    if not stat.S_ISDIR(info.st_mode):
        try:
            os.unlink(name, dir_fd=parent_fd)
        except OSError:
            pass
        return
    try:
        inner = os.open(name, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW, dir_fd=parent_fd)
    except OSError:
        return
    try:
        for entry in os.listdir(inner):
            entry_info = os.stat(entry, dir_fd=inner, follow_symlinks=False)
            if stat.S_ISDIR(entry_info.st_mode):
                _remove_folder(inner, entry)
            else:
                os.unlink(entry, dir_fd=inner)
    finally:
        os.close(inner)
    try:
        os.rmdir(name, dir_fd=parent_fd)
    except OSError:
        pass
