"""Archives as untrusted input: the one place where dsim opens and unpacks a zip
archive (an .ssp scene, an FMU), shared by the command line, the Python API and
``dsim serve``'s upload checks.

* An archive is refused (one line) before anything is unpacked when it has more than
  :data:`MAX_MEMBERS` members, unpacks to more than :data:`MAX_UNPACKED` bytes, has
  members that overlap (their compressed data adds up to more than the file: the
  trick of the smallest zip bombs), unpacks to more than :data:`MAX_RATIO` times its
  own size (past :data:`RATIO_FLOOR`) or has a member that does (past
  :data:`MEMBER_RATIO_FLOOR`), names a member outside itself, or has a member
  name that is not valid UTF-8.  The sizes an archive declares can lie, so unpacking
  counts the bytes it really writes and stops at the declared size.
* Unpacked files go to a temporary folder named with the process id, holding a lock
  the process keeps for its life: a folder whose lock nobody holds (or, without a
  lock file, whose process is gone) belongs to a dead run and is removed by the next
  one (:func:`sweep_dead_folders`), because a killed process runs no cleanup.

The limits can be lowered (never raised past what the disk takes) with the
environment variables ``DSIM_MAX_UNPACKED`` (bytes) and ``DSIM_MAX_MEMBERS``.
"""
from __future__ import annotations

import atexit
import fcntl
import os
import re
import shutil
import stat
import tempfile
import zipfile
from pathlib import Path, PurePosixPath

from dsim.master.errors import InputError
from dsim.master.processes import process_alive
from dsim.master.recording.output_files import lock_is_free

#: largest unpacked size of an archive (its members added up), bytes
MAX_UNPACKED = 2 << 30
#: most members an archive may have
MAX_MEMBERS = 20000
#: largest ratio of unpacked size to archive size (deflate reaches ~1000 on zeros; a
#: scene of FMUs, which are compressed already, and XML stays far below 100)
MAX_RATIO = 200
#: unpacked size below which the ratio of an archive, and of one member, is not checked
#: (a small XML file compresses well)
RATIO_FLOOR = 16 << 20
MEMBER_RATIO_FLOOR = 1 << 20

#: prefix of every temporary folder dsim unpacks into
PREFIX = "dsim-"
_LOCK = ".dsim-lock"
_CHUNK = 1 << 20


def _limit(name: str, default: int) -> int:
    text = os.environ.get(name, "")
    return min(int(text), default) if text.isdigit() else default


def open_archive(path, what: str) -> zipfile.ZipFile:
    """The zip archive at ``path``; InputError (one line) when it is none."""
    try:
        return zipfile.ZipFile(path)
    except UnicodeDecodeError:  # flagged UTF-8, but is not: zipfile decodes names on opening
        raise InputError(f"{what} archive has a member name that is not valid UTF-8") \
            from None
    except (zipfile.BadZipFile, OSError, EOFError, ValueError) as error:
        raise InputError(f"not a readable {what} archive "
                         f"({getattr(error, 'strerror', None) or error})") from None


def check_archive(path, what: str, max_unpacked: int | None = None) -> list[str]:
    """Member names of a zip archive, refused (InputError, one line) when it is not
    one, is too big to unpack (see the module docstring) or names a member outside
    itself."""
    max_unpacked = _limit("DSIM_MAX_UNPACKED", MAX_UNPACKED if max_unpacked is None
                          else max_unpacked)
    max_members = _limit("DSIM_MAX_MEMBERS", MAX_MEMBERS)
    with open_archive(path, what) as archive:
        members = archive.infolist()
    if len(members) > max_members:
        raise InputError(f"{what} archive has {len(members)} members (at most {max_members})")
    total = sum(m.file_size for m in members)
    if total > max_unpacked:
        raise InputError(f"{what} archive unpacks to {total / 2**20:.0f} MiB "
                         f"(at most {max_unpacked / 2**20:.0f} MiB)")
    size = os.path.getsize(path)
    if sum(m.compress_size for m in members) > size:
        raise InputError(f"{what} archive has members that overlap (a zip bomb)")
    if total > RATIO_FLOOR and total > MAX_RATIO * size:
        raise InputError(f"{what} archive unpacks to {total / 2**20:.0f} MiB, "
                         f"{total / size:.0f} times its size (at most {MAX_RATIO}: a zip bomb)")
    for member in members:  # one bomb among real members: its own ratio gives it away
        if member.file_size > MEMBER_RATIO_FLOOR and \
                member.file_size > MAX_RATIO * max(member.compress_size, 1):
            raise InputError(f"{what} archive member '{member.filename}' unpacks to "
                             f"{member.file_size / 2**20:.0f} MiB, "
                             f"{member.file_size / max(member.compress_size, 1):.0f} times its "
                             f"compressed size (at most {MAX_RATIO}: a zip bomb)")
    for member in members:
        name = PurePosixPath(member.filename)
        if name.is_absolute() or ".." in name.parts or "\\" in member.filename:
            raise InputError(f"{what} archive member '{member.filename}' points outside the "
                             "archive")
    return [m.filename for m in members]


# --- temporary folders ---------------------------------------------------------------

_HELD: dict[str, int] = {}  # folder -> fd of its lock, open for the process's life


@atexit.register
def _remove_held() -> None:
    for folder in list(_HELD):
        remove_folder(folder)


def temporary_folder(kind: str) -> Path:  # kind: "ssp" or "fmu" (see _OURS)
    """A new private folder ``dsim-KIND-PID-XXXX`` in the temporary folder, locked for
    this process's life (removed at its exit, or by the next run if it is killed)."""
    sweep_dead_folders()
    folder = tempfile.mkdtemp(prefix=f"{PREFIX}{kind}-{os.getpid()}-")
    # the lock appears under its name already locked (made aside, then renamed): another
    # process's sweep never sees it free while this one lives (without a lock file it
    # asks whether the pid in the folder's name still runs)
    aside = os.path.join(folder, f"{_LOCK}.new")
    fd = os.open(aside, os.O_RDWR | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600)
    fcntl.flock(fd, fcntl.LOCK_EX)
    os.rename(aside, os.path.join(folder, _LOCK))
    _HELD[folder] = fd
    return Path(folder)


def remove_folder(folder) -> None:
    """Remove a folder of :func:`temporary_folder` and release its lock."""
    folder = str(folder)
    shutil.rmtree(folder, ignore_errors=True)
    fd = _HELD.pop(folder, None)
    if fd is not None:
        os.close(fd)


def _dead(folder: Path) -> bool:
    """Whether the run that made ``folder`` is provably gone: its lock is free, or it
    has no lock file and the process its name says is gone."""
    lock = folder / _LOCK
    if not os.path.lexists(lock):
        return not process_alive(int(_OURS.match(folder.name).group(1)))
    return lock_is_free(lock) is not None


#: the name of a folder of :func:`temporary_folder`: kind, then the process id
_OURS = re.compile(rf"{PREFIX}(?:ssp|fmu)-([0-9]+)-")

_SWEPT = False


def sweep_dead_folders(root=None) -> list[Path]:
    """Remove this user's ``dsim-ssp-PID-*`` and ``dsim-fmu-PID-*`` unpacking folders left
    by killed runs (once per process unless ``root`` is given); the folders removed."""
    global _SWEPT
    if root is None:
        if _SWEPT:
            return []
        _SWEPT = True
    root = Path(root or tempfile.gettempdir())
    removed = []
    try:
        entries = list(os.scandir(root))
    except OSError:
        return removed
    for entry in entries:
        if not _OURS.match(entry.name) or str(root / entry.name) in _HELD:
            continue  # only the folders temporary_folder makes (others have no lock)
        try:
            info = entry.stat(follow_symlinks=False)
        except OSError:
            continue
        if not stat.S_ISDIR(info.st_mode) or info.st_uid != os.getuid():
            continue
        folder = root / entry.name
        if _dead(folder):
            shutil.rmtree(folder, ignore_errors=True)
            removed.append(folder)
    return removed


def extract(path, what: str, kind: str, max_unpacked: int | None = None) -> Path:
    """Unpack the archive at ``path`` into a new :func:`temporary_folder` after
    :func:`check_archive`; InputError (one line, without the path: the caller names
    the file) if it cannot be, the folder then removed."""
    check_archive(path, what, max_unpacked)
    folder = temporary_folder(kind)
    try:
        with open_archive(path, what) as archive:
            for member in archive.infolist():
                _extract_member(archive, member, folder, what)
    except InputError:
        remove_folder(folder)
        raise
    except (OSError, zipfile.BadZipFile, EOFError, RuntimeError, NotImplementedError) as error:
        remove_folder(folder)
        raise InputError(f"cannot extract the {what} archive: "
                         f"{getattr(error, 'strerror', None) or error}") from None
    except BaseException:  # a signal while unpacking: no half-unpacked folder stays
        remove_folder(folder)
        raise
    return folder


def _extract_member(archive: zipfile.ZipFile, member: zipfile.ZipInfo, folder: Path,
                    what: str) -> None:
    """One member, written at most ``file_size`` bytes (a lying header cannot make it
    larger) into a file this call creates (never an existing path)."""
    target = folder.joinpath(*PurePosixPath(member.filename).parts)
    if member.is_dir():
        target.mkdir(parents=True, exist_ok=True)
        return
    target.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(target, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600)
    left = member.file_size
    with os.fdopen(fd, "wb") as out, archive.open(member) as source:
        while True:
            chunk = source.read(min(_CHUNK, left + 1))
            if not chunk:
                break
            if len(chunk) > left:
                raise InputError(f"{what} archive member '{member.filename}' unpacks to "
                                 f"more than the {member.file_size} bytes it declares")
            left -= len(chunk)
            out.write(chunk)
    if member.external_attr >> 16 & 0o111:  # a shared library must stay executable
        os.chmod(target, 0o700)


def is_lock_file(name: str) -> bool:
    """Whether ``name`` is the lock file of an unpacking folder (not scene content)."""
    return name == _LOCK


__all__ = ["MAX_UNPACKED", "MAX_MEMBERS", "MAX_RATIO", "check_archive", "extract",
           "open_archive", "remove_folder", "sweep_dead_folders", "temporary_folder"]
