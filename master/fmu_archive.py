"""FMU files as untrusted input: checked before any instance is made.

An FMU is a zip archive with a modelDescription.xml and a shared library per
platform.  A corrupt or truncated archive, an FMI version or interface type dsim
does not run, or a library that cannot be loaded must each be one line of bad
input before the first step, never a traceback or a crashed process: a library
cut short can kill the process that maps it (SIGBUS), so it is first loaded in a
child process, where a crash is only a message.
"""
from __future__ import annotations

import hashlib
import subprocess
import sys
import zipfile
from pathlib import Path

from fmpy import platform, sharedLibraryExtension

from master.errors import InputError
from master.unpacking import check_archive, extract

_UNZIPPED: dict[Path, str] = {}

# Loads the library and returns; a crash shows as a negative return code.
_PROBE = "import ctypes, sys; ctypes.CDLL(sys.argv[1])"


def unzipped(path: Path) -> str:
    """Folder holding the extracted FMU (shared by every instance of the file): unpacked
    within the limits of :mod:`master.unpacking`, into a folder removed at exit (or by
    the next run, when this one is killed)."""
    path = Path(path)
    if path not in _UNZIPPED:
        _UNZIPPED[path] = str(extract(path, "FMU", "fmu"))
    return _UNZIPPED[path]


def _archive_problem(path: Path) -> str | None:
    try:
        check_archive(path, "FMU")  # before testzip, which inflates every member
    except InputError as error:
        return error.problems[0]
    try:
        with zipfile.ZipFile(path) as archive:
            broken = archive.testzip()
            names = set(archive.namelist())
    except (zipfile.BadZipFile, OSError, EOFError) as error:
        return f"not a readable FMU archive ({error})"
    if broken:
        return f"corrupt FMU archive (member '{broken}' fails its CRC check)"
    if "modelDescription.xml" not in names:
        return "not an FMU (no modelDescription.xml in the archive)"
    return None


def _description_problem(path: Path) -> str | None:
    from master.ports import model_description

    try:
        description = model_description(path)
    except Exception as error:  # fmpy raises several kinds for a broken description
        return f"unreadable modelDescription.xml ({' '.join(str(error).split())})"
    if description.fmiVersion != "2.0":
        return (f"an FMI {description.fmiVersion} FMU: dsim runs FMI 2.0 co-simulation "
                "FMUs")
    if description.coSimulation is None:
        return ("a Model Exchange FMU without co-simulation: dsim runs FMI 2.0 "
                "co-simulation FMUs")
    return None


def _library_problem(path: Path) -> str | None:
    from master.ports import model_description

    identifier = model_description(path).coSimulation.modelIdentifier
    member = f"binaries/{platform}/{identifier}{sharedLibraryExtension}"
    with zipfile.ZipFile(path) as archive:
        if member not in archive.namelist():
            found = sorted({n.split("/")[1] for n in archive.namelist()
                            if n.startswith("binaries/") and n.count("/") >= 2})
            return (f"no binary for this platform ({member} missing; the FMU has "
                    f"{', '.join(found) or 'no binaries'})")
    try:
        library = Path(unzipped(path)) / member
    except InputError as error:
        return error.problems[0]
    try:
        probe = subprocess.run([sys.executable, "-I", "-S", "-c", _PROBE, str(library)],
                               capture_output=True, text=True, timeout=120)
    except subprocess.TimeoutExpired:
        return f"its library {member} did not finish loading in 120 s"
    if probe.returncode < 0:
        import signal
        name = signal.Signals(-probe.returncode).name
        return f"its library {member} is corrupt: loading it crashed the process ({name})"
    if probe.returncode:
        last = (probe.stderr.strip().splitlines() or ["unknown error"])[-1]
        return f"its library {member} cannot be loaded: {last}"
    return None


_CHECKED: dict[str, str | None] = {}


def fmu_problem(path: Path) -> str | None:
    """What is wrong with the FMU file at ``path`` for dsim, or None (checked once per
    content: the same FMU extracted again from a scene archive is not probed again)."""
    path = Path(path)
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    if digest not in _CHECKED:
        _CHECKED[digest] = (_archive_problem(path) or _description_problem(path)
                            or _library_problem(path))
    return _CHECKED[digest]
