"""What FMU instances log, kept per instance name for the error messages: one store
for every FMI version (FMI 1.0 and 2.0 pass the instance name to a process-wide
logger; an FMI 3.0 instance gets a logger of its own that knows its name)."""
from __future__ import annotations

import ctypes
import sys
from collections import deque

from fmpy import calloc, free
from fmpy.fmi1 import (fmi1CallbackAllocateMemoryTYPE, fmi1CallbackFreeMemoryTYPE,
                       fmi1CallbackFunctions, fmi1CallbackLoggerTYPE)
from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

#: the messages kept per instance (the error messages quote them)
KEPT = 20
#: instance name -> the last (status, one-line message) pairs it logged (the status
#: numbers of FMI 1.0, 2.0 and 3.0 agree up to Fatal: OK 0, Warning 1, Discard 2,
#: Error 3, Fatal 4)
_MESSAGES: dict[str, deque] = {}
#: instance name -> how many messages of status Error or worse it logged
_ERRORS: dict[str, int] = {}
#: the instances whose every message is printed as it comes (``--fmu-log``)
_PRINTED: set[str] = set()
#: the status names every FMI version shares, by number (FMI 1.0, 2.0 and 3.0 agree)
STATUS = {0: "OK", 1: "Warning", 2: "Discard", 3: "Error", 4: "Fatal", 5: "Pending"}
#: the last status that is not a failure: a call that returns more failed
WARNING = 1
#: the words that mark a log category of what goes wrong (logStatusWarning,
#: logStatusError, ... in the categories FMI 3.0 recommends and most tools declare)
PROBLEM_WORDS = ("warning", "error", "fatal", "discard")


def record(name: str, status: int, message: bytes | str | None, category=None) -> None:
    """Keep one message an instance logged (the last :data:`KEPT`), printed to
    stderr as well for an instance run with ``--fmu-log``."""
    if isinstance(message, bytes):
        message = message.decode("utf-8", "replace")
    text = " ".join((message or "").split())
    kept = _MESSAGES.get(name)
    if kept is None:
        kept = _MESSAGES[name] = deque(maxlen=KEPT)
    kept.append((int(status), text))
    if status >= 3:
        _ERRORS[name] = _ERRORS.get(name, 0) + 1
    if name in _PRINTED:
        if isinstance(category, bytes):
            category = category.decode("utf-8", "replace")
        level = STATUS.get(status, status)
        print(f"dsim: fmu {name}: [{level}] {category or ''}: {text}", file=sys.stderr,
              flush=True)


def forget(name: str) -> None:
    """Drop what an instance logged so far (a new instance, or its cleanup begins)."""
    _MESSAGES.pop(name, None)
    _ERRORS.pop(name, None)
    _PRINTED.discard(name)


def problem_categories(categories) -> list[str]:
    """The log categories among ``categories`` that carry what goes wrong (warnings,
    discards, errors, fatal errors), by name."""
    return [c for c in categories if any(w in c.lower() for w in PROBLEM_WORDS)]


def ask_for_logging(fmu, name: str, categories, everything: bool = False) -> None:
    """Right after an FMI 2.0 or 3.0 instance is made with logging on: ask it for its
    warning and error categories only, when it declares such categories (an FMU that
    logs every event per step spends more time in its logger than in its model: 30
    messages a step, 68 % of a causal run's time, for OpenModelica's dual-mass
    oscillator); an FMU that declares none keeps every category on, since which of
    its messages matter cannot be told.  ``everything`` (``--fmu-log``): every
    category stays on and every message is printed as it comes."""
    if everything:
        _PRINTED.add(name)
        return
    chosen = problem_categories(categories)
    if chosen:
        fmu.setDebugLogging(True, chosen)


def errors_logged(name: str) -> int:
    """How many messages of status Error or worse the instance logged."""
    return _ERRORS.get(name, 0)


def logged_error(instance: str) -> str:
    """The first error an instance logged (Error before Fatal before Discard), or ''."""
    messages = _MESSAGES.get(instance, [])
    for level in (3, 4, 2):
        for status, text in messages:
            if status == level and text:
                return text
    return ""


def _log2(environment, instance, status, category, message):
    record((instance or b"").decode("utf-8", "replace"), status, message, category)


# One FMI 2.0 callbacks structure for the whole process, alive as long as it is: fmpy's
# proxy (which formats the variadic message) keeps a single global pointer to the logger.
CALLBACKS2 = fmi2CallbackFunctions()
CALLBACKS2.logger = fmi2CallbackLoggerTYPE(_log2)
CALLBACKS2.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
CALLBACKS2.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
try:
    from fmpy.logging import addLoggerProxy as _add_logger_proxy
    _add_logger_proxy(ctypes.byref(CALLBACKS2))
except Exception:  # pragma: no cover - the proxy is a compiled fmpy extra
    def _add_logger_proxy(callbacks):
        pass


def logger3(name: str):
    """An FMI 3.0 log message callback (Python side) that files messages under ``name``."""
    def log(environment, status, category, message):
        record(name, status, message, category)
    return log


# FMI 1.0's callbacks structure, set up as the FMI 2.0 one (the logger has the same
# arguments; stepFinished stays NULL: dsim's steps are synchronous)
CALLBACKS1 = fmi1CallbackFunctions()
CALLBACKS1.logger = fmi1CallbackLoggerTYPE(_log2)
CALLBACKS1.allocateMemory = fmi1CallbackAllocateMemoryTYPE(calloc)
CALLBACKS1.freeMemory = fmi1CallbackFreeMemoryTYPE(free)
CALLBACKS1.stepFinished = None
try:
    _add_logger_proxy(ctypes.byref(CALLBACKS1))
except Exception:  # pragma: no cover - the proxy is a compiled fmpy extra
    pass
