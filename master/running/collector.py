"""Python's cyclic garbage collector paused over work that makes millions of
long-lived objects and few cycles: reading and planning a scene of 10,000
components, instantiating its FMUs.  Each of the collector's passes walks every
object alive, so that such work spent as much time in the collector as in itself;
whatever the work left in a cycle is collected after, once the collector runs again.

What such a set-up makes lives as long as the run, and the collector would still walk
it: a full pass over the million objects of 10,000 FMU instances, made whenever enough
new objects survive (twice in ten steps of a chain of 10,000: 15% of the steps' time).
:func:`freeze` moves every object alive at the end of a set-up out of the collector's
reach (``gc.freeze``) until :func:`thaw` at the run's end."""
from __future__ import annotations

import gc
from contextlib import contextmanager


@contextmanager
def collector_paused():
    """Pause the cyclic garbage collector for the ``with`` block (nested pauses and a
    collector already off are left as they were)."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


#: runs holding the objects frozen (the first freezes, the last to thaw gives them back)
_FROZEN = [0]


def freeze() -> None:
    """Objects alive now ignored by the collector until the last :func:`thaw`
    (``gc.freeze``: overlapping runs keep every run's objects frozen until the last
    one thaws).
    Frozen objects that become garbage are still freed by their reference counts;
    only cycles among them wait for the thaw."""
    gc.freeze()  # (every object alive: the runs before's again, and this one's)
    _FROZEN[0] += 1


def thaw() -> None:
    """End one :func:`freeze`: the last gives the frozen objects back to the collector
    (``gc.unfreeze``)."""
    if _FROZEN[0] > 0:
        _FROZEN[0] -= 1
        if _FROZEN[0] == 0:
            gc.unfreeze()
