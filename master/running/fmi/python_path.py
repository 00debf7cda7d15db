"""What an FMU that embeds Python adds to ``sys.path``, held while it lives.

pythonfmu's C side puts the FMU's ``resources`` folder at the front of ``sys.path`` each
time it makes an instance, and never takes it out: chain_10000 left 10,000 copies, a
sweep run in one process one more per instance of every point, and every import of a
module not loaded yet walks them all (an import that finds nothing took about 1 ms with
200 copies).

So dsim keeps each such entry once while any instance that added it lives, and takes it
out when the last one is freed.  Written by hand: no library tracks what a foreign
library inserted into ``sys.path``.
"""
from __future__ import annotations

import sys
import threading
from collections import Counter

_lock = threading.Lock()
#: entry -> live instances that added it
_held: Counter = Counter()


def watch() -> list[str]:
    """``sys.path`` now, to give to :func:`adopt` after the instantiation."""
    return list(sys.path)


def adopt(before: list[str]) -> tuple[str, ...]:
    """The entries the instantiation added to ``sys.path`` since ``before`` was taken
    (:func:`watch`), each now held once more and present once (the copy nearest the
    front kept); what :func:`release` gives back when the instance is freed."""
    with _lock:
        added = tuple((Counter(sys.path) - Counter(before)).keys())
        for entry in added:
            places = [i for i, path in enumerate(sys.path) if path == entry]
            for place in reversed(places[1:]):
                del sys.path[place]
            _held[entry] += 1
        return added


def release(entries: tuple[str, ...]) -> None:
    """An instance that added ``entries`` is freed: each entry no live instance holds
    any more leaves ``sys.path``."""
    with _lock:
        for entry in entries:
            _held[entry] -= 1
            if _held[entry] > 0:
                continue
            del _held[entry]
            sys.path[:] = [path for path in sys.path if path != entry]
