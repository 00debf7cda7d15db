"""Python's cyclic garbage collector paused over work that makes millions of
long-lived objects and few cycles: reading and planning a scene of 10,000
components, instantiating its FMUs.  Each of the collector's passes walks every
object alive, so that such work spent as much time in the collector as in itself;
whatever the work left in a cycle is collected after, once the collector runs again."""
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
