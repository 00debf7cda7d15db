"""What FMU instances log, kept per instance name for the error messages: one store
for every FMI version (FMI 1.0 and 2.0 pass the instance name to a process-wide
logger; an FMI 3.0 instance gets a logger of its own that knows its name)."""
from __future__ import annotations

import ctypes

from fmpy import calloc, free
from fmpy.fmi1 import (fmi1CallbackAllocateMemoryTYPE, fmi1CallbackFreeMemoryTYPE,
                       fmi1CallbackFunctions, fmi1CallbackLoggerTYPE)
from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

#: instance name -> the last (status, one-line message) pairs it logged (the status
#: numbers of FMI 1.0, 2.0 and 3.0 agree up to Fatal: OK 0, Warning 1, Discard 2,
#: Error 3, Fatal 4)
_MESSAGES: dict[str, list[tuple[int, str]]] = {}
#: instance name -> how many messages of status Error or worse it logged
_ERRORS: dict[str, int] = {}


def record(name: str, status: int, message: bytes | str | None) -> None:
    """Keep one message an instance logged."""
    if isinstance(message, bytes):
        message = message.decode("utf-8", "replace")
    text = " ".join((message or "").split())
    _MESSAGES[name] = (_MESSAGES.get(name, []) + [(int(status), text)])[-20:]
    if status >= 3:
        _ERRORS[name] = _ERRORS.get(name, 0) + 1


def forget(name: str) -> None:
    """Drop what an instance logged so far (a new instance, or its cleanup begins)."""
    _MESSAGES.pop(name, None)
    _ERRORS.pop(name, None)


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
    record((instance or b"").decode("utf-8", "replace"), status, message)


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
        record(name, status, message)
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
