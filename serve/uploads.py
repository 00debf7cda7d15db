"""Uploads: an FMU or an .ssp archive becomes a stored model or scene, after dsim's
own checks of untrusted input, run in a child process (:mod:`dsim.serve.inspect`).

A file is told apart by its content (a zip archive with a modelDescription.xml is
an FMU, one with a SystemStructure.ssd at its root a scene), never by the name it
was uploaded under; that name is kept only to be shown.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import zipfile
from pathlib import Path

from dsim.serve.jobs import child_env
from dsim.serve.store import Store

#: seconds an inspection may take
INSPECT_TIMEOUT = 300

#: inspections at once: each is a Python process, and uploads arrive in parallel
#: (20 at once were seen); the others wait their turn rather than crowd the machine
INSPECTIONS = threading.BoundedSemaphore(2 * (os.cpu_count() or 1))


class UploadError(Exception):
    """The file is refused: ``problems``, one line each."""

    def __init__(self, problems):
        self.problems = [problems] if isinstance(problems, str) else list(problems)
        super().__init__("\n".join(self.problems))


def inspect_file(kind: str, path: Path, max_unpacked: int, shown: str,
                 given: str | None = None) -> dict:
    """The description :mod:`dsim.serve.inspect` makes of a file in a child process
    (``kind``: fmu, ssp, or parameters with ``given``, JSON text, on its standard
    input); UploadError with its problems, the temporary path in them replaced by
    ``shown``."""
    try:
        with INSPECTIONS:
            child = subprocess.run([sys.executable, "-m", "dsim.serve.inspect", kind,
                                    str(path), str(max_unpacked)], capture_output=True,
                                   text=True, timeout=INSPECT_TIMEOUT, env=child_env(),
                                   input=given)
    except subprocess.TimeoutExpired:
        raise UploadError(f"{shown}: checking it took longer than {INSPECT_TIMEOUT} s") from None
    if child.returncode < 0:
        name = signal.Signals(-child.returncode).name
        raise UploadError(f"{shown}: checking it crashed the checker ({name})")
    try:
        answer = json.loads(child.stdout.strip().splitlines()[-1])
    except (IndexError, json.JSONDecodeError):
        last = (child.stderr.strip().splitlines() or ["no answer"])[-1]
        raise UploadError(f"{shown}: the checker failed: {last}") from None
    if not answer["ok"]:
        raise UploadError([f"{shown}: {p.replace(str(path), shown)}"
                           for p in answer["problems"]])
    return answer["description"]


def sniff(path: Path) -> str:
    """``fmu`` or ``ssp`` from the file's content; UploadError for anything else."""
    try:
        with zipfile.ZipFile(path) as archive:
            names = set(archive.namelist())
    except (zipfile.BadZipFile, OSError, EOFError):
        raise UploadError("neither an FMU nor an SSP archive (not a zip archive)") from None
    except UnicodeDecodeError:  # flagged UTF-8 by the zip format, but it is not
        raise UploadError("not a readable archive: a member's name is not valid UTF-8") \
            from None
    if "modelDescription.xml" in names:
        return "fmu"
    if "SystemStructure.ssd" in names:
        return "ssp"
    raise UploadError("neither an FMU (no modelDescription.xml) nor an SSP archive (no "
                      "SystemStructure.ssd at its root)")


def display_name(filename: str | None) -> str:
    """The uploaded file's name as shown: its last part, printable, at most 120
    characters (it never names a file on this machine)."""
    name = (filename or "upload").replace("\\", "/").rsplit("/", 1)[-1]
    name = "".join(c for c in name if c.isprintable())[:120]
    return name or "upload"


def store_scene(store: Store, path: Path, filename: str, max_unpacked: int,
                origin: str = "uploaded", parent_id: int | None = None) -> int:
    """Check and keep an .ssp file (moved into the store), its FMUs as models; the
    scene's id."""
    description = inspect_file("ssp", path, max_unpacked, filename)
    models = {}
    with zipfile.ZipFile(path) as archive:
        for member, fmu in description.pop("fmus").items():
            try:
                data = archive.read(member)
            except KeyError:  # the checker names members as the archive does: never
                raise UploadError(f"{filename}: no member '{member}' in the archive") \
                    from None
            sha, size = store.keep_bytes(data)
            model_id = store.add_model(sha, size, member.rsplit("/", 1)[-1],
                                       fmu["description"])
            for component in description["components"]:
                if component["fmu"] == member:
                    component["model_id"] = model_id
                    component["model_sha256"] = sha
                    models[component["path"]] = model_id
    sha, size = store.keep(path)
    return store.add_scene(sha, size, filename, description, models, origin, parent_id)


def store_upload(store: Store, path: Path, filename: str | None,
                 max_unpacked: int) -> tuple[str, int]:
    """Check and keep an uploaded file: ("model" or "scene", its id).  The file at
    ``path`` is moved into the store or removed."""
    shown = display_name(filename)
    try:
        try:
            kind = sniff(path)
        except UploadError as error:
            raise UploadError([f"{shown}: {p}" for p in error.problems]) from None
        if kind == "fmu":
            description = inspect_file("fmu", path, max_unpacked, shown)
            sha, size = store.keep(path)
            return "model", store.add_model(sha, size, shown, description)
        return "scene", store_scene(store, path, shown, max_unpacked)
    finally:
        path.unlink(missing_ok=True)
