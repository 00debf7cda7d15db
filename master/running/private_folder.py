"""A folder of this user's under a shared temporary directory that no one else can
write into: where a Ray worker lands shipped FMUs and leaves its crash report, and
where the driver keeps what Ray's processes said (docs/security.md).

Those folders have names fixed by the user id, so that the workers of one node share
one copy of a file; in a shared ``/tmp`` another user could make the folder first, or
put a link there, and have a worker load an FMU of theirs or write through the link.
So a folder is used only when it is a real folder (not a link), owned by this user,
that no one else may write to; anything else there is left alone, and this process
uses a new folder of its own instead (made as :func:`tempfile.mkdtemp` makes one).
"""
from __future__ import annotations

import os
import stat
import tempfile
from pathlib import Path

#: the folder used instead of one that was not safe, per folder asked for
_instead: dict[Path, Path] = {}


def safe(path: Path) -> bool:
    """Whether ``path`` is a folder (not a link) owned by this user that neither its
    group nor others may write to."""
    try:
        info = os.lstat(path)
    except OSError:
        return False
    return (stat.S_ISDIR(info.st_mode) and info.st_uid == os.geteuid()
            and not info.st_mode & (stat.S_IWGRP | stat.S_IWOTH))


def private_folder(path) -> Path:
    """``path``, made with mode 0700 when it does not exist, when it is :func:`safe`;
    else a new folder of this process's next to it (``NAME-XXXXXXXX``), the same one
    for every later call with this path."""
    path = Path(path)
    if path in _instead:
        return _instead[path]
    try:
        path.mkdir(mode=0o700, parents=False)
    except OSError:  # there already, or not ours to make: the check below says
        pass
    if safe(path):
        return path
    _instead[path] = Path(tempfile.mkdtemp(prefix=f"{path.name}-", dir=path.parent))
    return _instead[path]
