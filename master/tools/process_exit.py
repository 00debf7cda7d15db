"""How a dsim command process ends: without the native libraries' exit handlers.

The FMU libraries a run loads stay in the process until it exits, whatever dsim
does: an instance that returned fmi2Fatal may not be freed (FMI 2.0 allows no
further call on it), and a library that is freed may not be unloaded either
(pythonfmu's, for one, defines STB_GNU_UNIQUE symbols, so glibc never unmaps it
and fmpy's dlclose does nothing).  A normal exit then runs their exit handlers,
which dsim cannot vouch for: pythonfmu 0.7 releases the interpreter state it
shares between its instances both from a C++ static destructor (an exit handler)
and from a destructor function that ``_dl_fini`` runs after it, on the freed block
(valgrind: invalid read in ``finalizePythonInterpreter``), which now and then
aborts the process with ``corrupted double-linked list`` after dsim has printed
its result (dsim now has pythonfmu drop that state when the last instance of its
library is freed, ``library._release_python_state``, which mends a normal exit; not
that of an instance that was never freed); a library left with a fatal instance is
in a state nobody knows.

So :func:`end_process` ends the command with ``os._exit``: first what the
interpreter's own exit would do for Python code (wait for non-daemon threads, run
``atexit``: extracted FMUs and scenes removed, Ray shut down, logging flushed),
then stdout and stderr flushed; dsim's own result files are closed before the
command returns.  Only the interpreter's teardown and the native exit handlers are
skipped, and neither has anything left to do for a command that has finished.

A process that uses dsim as a library (``dsim.simulate`` in a script, the tests)
keeps its normal exit: that is its owner's to choose (one script in thirty that ran
a pythonfmu FMU aborted at its exit before the release above; none in a hundred
after it).  The workers of the ray and
isolated backends are ended by the master with ``ray.kill``, which runs no exit
handler either.
"""
from __future__ import annotations

import atexit
import os
import sys
import threading
from typing import NoReturn


def end_process(code: int | None) -> NoReturn:
    """End this process with exit status ``code`` (None: 0, as for ``sys.exit``; see the
    module's docstring)."""
    for thread in threading.enumerate():
        if thread is not threading.current_thread() and not thread.daemon:
            thread.join()
    atexit._run_exitfuncs()  # what sys.exit would run; os._exit runs nothing
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe or stream: nothing left to say
            pass
    os._exit(code or 0)
