"""Reading a small input file the user names (a parameter file, a scenario): its size
checked before it is read, its text decoded, each failure one line of bad input."""
from __future__ import annotations

from pathlib import Path

from dsim.master.errors import InputError


def bounded_bytes(path: Path, limit: int, what: str) -> bytes:
    """The bytes of ``path``, refused (InputError) when it cannot be read or holds more
    than ``limit`` bytes (``what``: the kind of file, for the message)."""
    try:
        size = path.stat().st_size
        if size > limit:
            raise InputError(f"{path}: {size} bytes: more than {what}'s {limit} bytes")
        return path.read_bytes()
    except OSError as error:
        raise InputError(f"{path}: cannot read: {error.strerror}") from None


def utf8_text(path: Path, data: bytes) -> str:
    """``data`` (read from ``path``) as text: UTF-8, a byte-order mark dropped."""
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(f"{path}: not UTF-8 text") from None
