"""A checkpoint folder as untrusted input (docs/checkpoints.md): its manifest read and
checked (format, dsim's version), each file's length and SHA-256 checked against it
before anything is parsed, its state decoded as data only (JSON, and
``numpy.load(allow_pickle=False)`` of an .npz whose members are stored, not packed).
A damaged or foreign checkpoint is one line of bad input, never used."""
from __future__ import annotations

import hashlib
import json
import os
import stat
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dsim.master import __version__
from dsim.master.errors import InputError
from dsim.master.reading.small_files import bounded_bytes
from dsim.master.recording.checkpoints import FORMAT, NAME
from dsim.master.recording.state_codec import StateError, decode

#: bytes a manifest may hold
MANIFEST_LIMIT = 16 << 20
#: bytes a checkpoint's state text and arrays may hold
STATE_LIMIT = 64 << 30
#: the files a checkpoint holds besides its manifest
FILES = ("state.json", "arrays.npz")


@dataclass
class Checkpoint:
    """A checked checkpoint: its ``folder``, ``manifest`` (plain JSON) and ``state``
    (the plain data it kept); ``skipped``: newer checkpoints of the same folder that
    were damaged, each a line saying why."""

    folder: Path
    manifest: dict
    state: object
    skipped: list[str] = field(default_factory=list)

    @property
    def step(self) -> int:
        return self.manifest["step"]

    @property
    def time(self) -> float:
        return self.manifest["time"]


def _digest(path: Path, expected: dict, where: str) -> None:
    """Refuse ``path`` unless its length and SHA-256 are ``expected``'s."""
    if not isinstance(expected, dict) or not isinstance(expected.get("bytes"), int) \
            or not isinstance(expected.get("sha256"), str):
        raise InputError(f"{where}: the manifest gives no length and digest of {path.name}")
    try:
        info = os.stat(path, follow_symlinks=False)
    except OSError as error:
        raise InputError(f"{where}: {path.name}: {error.strerror}") from None
    if not stat.S_ISREG(info.st_mode):
        raise InputError(f"{where}: {path.name} is not a file")
    if info.st_size != expected["bytes"] or info.st_size > STATE_LIMIT:
        raise InputError(f"{where}: {path.name} has {info.st_size} bytes, the manifest "
                         f"says {expected['bytes']} (damaged or changed)")
    digest = hashlib.sha256()
    with open(path, "rb") as stream:
        while chunk := stream.read(1 << 20):
            digest.update(chunk)
    if digest.hexdigest() != expected["sha256"]:
        raise InputError(f"{where}: {path.name} does not match its digest in the manifest "
                         "(damaged or changed)")


def manifest_of(folder: Path) -> dict:
    """The checked manifest of the checkpoint ``folder`` (format and dsim version)."""
    where = f"checkpoint {folder}"
    path = folder / "manifest.json"
    if not path.is_file() or path.is_symlink():
        raise InputError(f"{where}: no manifest.json (not a checkpoint, or one half made)")
    try:
        manifest = json.loads(bounded_bytes(path, MANIFEST_LIMIT, "a manifest"))
    except (ValueError, UnicodeDecodeError) as error:
        raise InputError(f"{where}: manifest.json is not JSON ({error})") from None
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
        raise InputError(f"{where}: not a checkpoint of this format (expected "
                         f"'{FORMAT}')")
    if manifest.get("dsim") != __version__:
        raise InputError(f"{where}: written by dsim {manifest.get('dsim')}, this is dsim "
                         f"{__version__}: a checkpoint is resumed by the version that "
                         "wrote it")
    if not isinstance(manifest.get("step"), int) or not isinstance(
            manifest.get("time"), (int, float)):
        raise InputError(f"{where}: the manifest gives no step and time")
    return manifest


def load_checkpoint(folder: Path) -> Checkpoint:
    """The checkpoint in ``folder`` (one ``step-`` folder), checked whole."""
    folder = Path(folder)
    where = f"checkpoint {folder}"
    manifest = manifest_of(folder)
    files = manifest.get("files") or {}
    for name in FILES:
        _digest(folder / name, files.get(name), where)
    try:
        tree = json.loads((folder / "state.json").read_bytes())
    except ValueError as error:
        raise InputError(f"{where}: state.json is not JSON ({error})") from None
    data = folder / "arrays.npz"
    try:
        with zipfile.ZipFile(data) as archive:
            members = archive.infolist()
        if any(m.compress_type != zipfile.ZIP_STORED for m in members) or \
                sum(m.file_size for m in members) > data.stat().st_size:
            raise InputError(f"{where}: arrays.npz holds packed members (dsim writes "
                             "them stored)")
        with np.load(data, allow_pickle=False) as arrays:
            state = decode(tree, _Arrays(arrays))
    except (zipfile.BadZipFile, OSError, ValueError) as error:
        if isinstance(error, InputError):
            raise
        raise InputError(f"{where}: {error}") from None
    return Checkpoint(folder, manifest, state)


class _Arrays:
    """An .npz's arrays by key, each loaded when asked for (StateError for a key it
    does not hold)."""

    def __init__(self, npz):
        self._npz = npz

    def __getitem__(self, key):
        if key not in self._npz.files:
            raise KeyError(key)
        return self._npz[key]


def find_checkpoint(path) -> Checkpoint:
    """The checkpoint at ``path``: a checkpoint (a ``step-`` folder), or a checkpoint
    folder, whose last whole checkpoint it is (a newer damaged one skipped, and said).
    InputError when there is none.  (A :class:`Checkpoint` is itself.)"""
    if isinstance(path, Checkpoint):
        return path
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: no such checkpoint or checkpoint folder")
    if not path.is_dir():
        raise InputError(f"{path}: not a checkpoint folder")
    if (path / "manifest.json").exists():
        try:
            return load_checkpoint(path)
        except StateError as error:
            raise InputError(f"checkpoint {path}: {error}") from None
    steps = sorted(((int(m.group(1)), entry) for entry in path.iterdir()
                    if (m := NAME.match(entry.name)) and entry.is_dir()
                    and not entry.is_symlink()), reverse=True)
    if not steps:
        raise InputError(f"{path}: holds no checkpoint (step-... folders)")
    skipped = []
    for _, folder in steps:
        try:
            found = load_checkpoint(folder)
        except (InputError, StateError) as error:
            skipped.append(str(error))
            continue
        found.skipped = skipped
        return found
    raise InputError(f"{path}: no whole checkpoint: {skipped[0]}")
