"""FMU files as untrusted input: checked before any instance is made.

An FMU is a zip archive with a modelDescription.xml and a shared library per
platform.  A corrupt or truncated archive, an FMI version or interface type dsim
does not run, or a library that cannot be loaded must each be one line of bad
input before the first step, never a traceback or a crashed process: a library
cut short can kill the process that maps it (SIGBUS), so it is first loaded in a
child process, where a crash is only a message.
"""
from __future__ import annotations

import signal
import struct
import subprocess
import sys
import zipfile
from pathlib import Path

from dsim.master.errors import InputError
from dsim.master.reading.digests import file_digest
from dsim.master.reading.fmi_description import (chosen_interface, describe, library_folder,
                                                library_members)
from dsim.master.reading.input_tables import is_table, is_table_file, table_problem
from dsim.master.reading.unpacking import check_archive, extract

_UNZIPPED: dict[Path, str] = {}

# Loads the library and returns; a crash shows as a negative return code.
_PROBE = "import ctypes, sys; ctypes.CDLL(sys.argv[1])"


def unzipped(path: Path) -> str:
    """Folder holding the extracted FMU (shared by every instance of the file): unpacked
    within the limits of :mod:`dsim.master.reading.unpacking`, into a folder removed at exit (or by
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


#: the start of the problem of a description fmpy cannot read or refuses
UNREADABLE = "unreadable modelDescription.xml"


def _description_problem(path: Path) -> str | None:
    try:
        description = describe(path)
    except Exception as error:  # fmpy raises several kinds for a broken description
        return f"{UNREADABLE} ({' '.join(str(error).split())})"
    if description.major not in (1, 2, 3):
        return (f"an FMI {description.fmiVersion} FMU: dsim runs FMI 1.0, 2.0 and 3.0 "
                "FMUs")
    try:
        chosen_interface(description)
    except ValueError as error:
        return str(error)
    clocks = [name for name, kind in description.unsupported.items() if kind == "Clock"]
    if clocks:
        return (f"variable '{clocks[0]}' is a Clock: dsim does not run clocked FMI 3.0 "
                "FMUs (clocks and clocked partitions)")
    return None


def _no_binary_here(path: Path) -> str | None:
    """Whether the FMU lacks a library for this platform, read from its description
    without fmpy's checks: the most fundamental blocker, said before any complaint
    about the description itself (one error for one cause; an unreadable description
    is said by :func:`_description_problem`)."""
    try:
        members = library_members(path, checked=False)
        with zipfile.ZipFile(path) as archive:
            names = archive.namelist()
    except Exception:  # fmpy raises several kinds for a broken description
        return None
    return _missing_binary(members, names)


def _missing_binary(members, names) -> str | None:
    """The first of the library ``members`` not among the archive's ``names``, said
    with the platforms the FMU has, or None."""
    for member in members:
        if member not in names:
            found = sorted({n.split("/")[1] for n in names
                            if n.startswith("binaries/") and n.count("/") >= 2})
            return (f"no binary for this platform ({member} missing; the FMU has "
                    f"{', '.join(found) or 'no binaries'})")
    return None


def _library_problem(path: Path) -> str | None:
    """Whether the library (there, and whole as bytes: :func:`_library_bytes_problem`)
    loads: in a child process, where a crash is only a message."""
    for member in library_members(path):
        problem = _one_library_problem(path, member)
        if problem:
            return problem
    return None


def _one_library_problem(path: Path, member: str) -> str | None:
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
        name = signal.Signals(-probe.returncode).name
        return f"its library {member} is corrupt: loading it crashed the process ({name})"
    if probe.returncode:
        last = (probe.stderr.strip().splitlines() or ["unknown error"])[-1]
        return f"its library {member} cannot be loaded: {last}"
    return None


#: ELF class and e_machine of each Linux platform of FMI 2.0
ELF_MACHINES = {"linux64": (2, 62), "linux32": (1, 3), "x86_64-linux": (2, 62),
                "x86-linux": (1, 3), "aarch64-linux": (2, 183)}  # (ELF class, e_machine)



def _elf_problem(data: bytes, platform: str) -> str | None:
    """What keeps ``data`` from being a whole ELF shared object for ``platform``,
    from its headers alone (nothing is loaded or run): a library cut short or made
    for another machine is refused here rather than at its first run."""
    if data[:4] != b"\x7fELF":
        return "is not an ELF shared library"
    expected = ELF_MACHINES.get(platform)
    if expected is None:
        return None
    bits, machine = expected
    if data[4] != bits or data[5] != 1:  # class, little-endian
        return f"is not a little-endian {32 * bits}-bit library"
    if bits == 2:
        if len(data) < 64:
            return "is cut short (no whole ELF header)"
        kind, found, phoff, shoff = struct.unpack_from("<HH12xQQ", data, 16)
        phentsize, phnum, shentsize, shnum = struct.unpack_from("<HHHH", data, 54)
    else:
        if len(data) < 52:
            return "is cut short (no whole ELF header)"
        kind, found, phoff, shoff = struct.unpack_from("<HH8xII", data, 16)
        phentsize, phnum, shentsize, shnum = struct.unpack_from("<HHHH", data, 42)
    if kind != 3:
        return "is not a shared object (ELF type %d)" % kind
    if found != machine:
        return f"is built for another machine (ELF machine {found})"
    if phoff + phnum * phentsize > len(data) or shoff + shnum * shentsize > len(data):
        return "is cut short (its headers point past its end)"
    return None


def _library_bytes_problem(path: Path) -> str | None:
    """The libraries of this platform that an FMU names are in the archive and look
    whole (:func:`_elf_problem`), read as bytes, never loaded."""
    folder = library_folder(describe(path))
    members = library_members(path)
    with zipfile.ZipFile(path) as archive:
        names = archive.namelist()
        missing = _missing_binary(members, names)
        if missing:
            return missing
        for member in members:
            problem = _elf_problem(archive.read(member), folder) \
                if member.endswith(".so") else None
            if problem:
                return f"its library {member} {problem}"
    return None


_CHECKED: dict[tuple[str, bool], str | None] = {}


def _first_blocker(path: Path) -> str | None:
    """What keeps a readable archive from running here, the most fundamental first: a
    kind of FMU dsim does not run (no binary would help), then no binary for this
    platform (before any complaint about the description: one error for one cause),
    then the description, then the library's bytes."""
    described = _description_problem(path)
    if described and not described.startswith(UNREADABLE):
        return described
    return _no_binary_here(path) or described or _library_bytes_problem(path)


def fmu_problem(path: Path, load: bool = True) -> str | None:
    """What is wrong with the FMU file at ``path`` for dsim, or None (checked once per
    content: the same FMU extracted again from a scene archive is not probed again).
    Its library is read as bytes (:func:`_library_bytes_problem`) and, with ``load``,
    loaded in a child process; without, nothing of the FMU runs (``dsim validate``,
    uploads to ``dsim serve``: an FMU's library runs its constructors when loaded)."""
    path = Path(path)
    if is_table_file(path):  # an SSP table component or --input: no FMU to check
        return table_problem(path)
    digest = file_digest(path)
    if (digest, False) not in _CHECKED:  # what reading the files finds, nothing loaded
        _CHECKED[digest, False] = _archive_problem(path) or _first_blocker(path)
    if load and (digest, True) not in _CHECKED:
        _CHECKED[digest, True] = _CHECKED[digest, False] or _library_problem(path)
    return _CHECKED[digest, load]


def descriptions(components) -> dict:
    """FMU file -> its description (:mod:`dsim.master.reading.fmi_description`), for the
    components' FMUs that pass every check made without loading them (archive limits,
    CRCs, a readable description of a version and interface dsim runs, a whole library
    for this platform); the others the plan reports."""
    result: dict = {}
    for component in components:
        source = component.source
        if source in result or not (source.is_file() or is_table(source)):
            continue
        if fmu_problem(source, load=False) is None:
            result[source] = describe(source)
    return {path: found for path, found in result.items() if found is not None}
