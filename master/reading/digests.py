"""SHA-256 of the files dsim reads, computed once per version of a file."""
from __future__ import annotations

import hashlib
from pathlib import Path

#: (file, its identity on disk) -> SHA-256 of its bytes: a file used by 10,000
#: components is read and hashed once; written again (another size, time or inode),
#: it is hashed again
_DIGESTS: dict[tuple, str] = {}


def file_digest(path: Path) -> str:
    """SHA-256 (hex) of the file's bytes, computed once per version of the file."""
    path = Path(path)
    status = path.stat()
    key = (str(path), status.st_ino, status.st_size, status.st_mtime_ns, status.st_ctime_ns)
    if key not in _DIGESTS:
        _DIGESTS[key] = hashlib.sha256(path.read_bytes()).hexdigest()
    return _DIGESTS[key]
