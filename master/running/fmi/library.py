"""One binding of an FMU library's functions, shared by every instance of the file.

fmpy binds the FMI functions of a library to an instance by inspecting every method
of its class (``inspect.signature`` of each, argument and return types set on each
function): about 6 ms per instance, ten times what instantiating a small FMU costs,
repeated for each of 10,000 instances of one FMU file.  The operating system maps a
library once however often it is opened; :func:`sharing` gives fmpy's classes a
binding made once per (class, library) and handed to the next instance, each of
which still opens (and at its end closes) the library itself, as fmpy does.

The binding is dropped when the last instance that holds it closes the library: a
library closed by all is unmapped, and opened again it may lie elsewhere.  fmpy has
no way to pass a bound library to a new instance, hence this subclass (written here:
fmpy's own ``_loadFunctions`` is what it calls once).

The binding also holds what the master's time loop passes to those functions and is
the same for every instance (:func:`raw`, :func:`shared`): a function object of the
library without fmpy's argument conversion, the value-reference arrays of a batch.
Made per instance they cost about 6 kB each (59 MB at 10,000 components) and one
more object a call reaches in memory.
"""
from __future__ import annotations

import ctypes

#: (fmpy class, library file) -> [its functions by name, instances holding them,
#: what the instances share besides (raw functions, constant ctypes arguments)]
_BOUND: dict[tuple, list] = {}
_CLASSES: dict[type, type] = {}


class _Shared:
    """Mixin over an fmpy FMU class: functions bound once per library file."""

    _binding = None

    def _loadFunctions(self) -> None:
        key = (type(self), self.dll._name)
        entry = _BOUND.get(key)
        if entry is None:
            super()._loadFunctions()
            entry = _BOUND[key] = [self._functions, 0, {}]
        else:
            self._functions = entry[0]
        entry[1] += 1
        self._binding = key

    def freeLibrary(self) -> None:
        key, self._binding = self._binding, None
        entry = _BOUND.get(key)
        if entry is not None:
            entry[1] -= 1
            if entry[1] <= 0:
                del _BOUND[key]
                _release_python_state(self.dll)
        super().freeLibrary()


#: what a pythonfmu library exports to drop the interpreter state its instances share
PYTHONFMU_RELEASE = "finalizePythonInterpreter"


def _release_python_state(dll) -> None:
    """Let a pythonfmu library (one that exports :data:`PYTHONFMU_RELEASE`) drop its
    shared interpreter state now that no instance of it is left in this process.

    pythonfmu 0.7 keeps that state in a global ``std::shared_ptr``
    that it releases twice when the process exits: a C++ static destructor destroys
    the pointer, then the library's destructor function (run by ``_dl_fini`` after it:
    glibc never unloads the library) assigns null to the destroyed pointer and so
    releases its block a second time.  About one script in thirty that ran a pythonfmu
    FMU through ``dsim.simulate`` then aborted after its last line with ``corrupted
    double-linked list`` (exit code 134).  Released here, while the library is
    loaded and nothing runs in it, the pointer is null when the process exits and both
    releases do nothing; an instance made later makes a new state, as the first did.
    The function takes no argument and returns nothing; a library without it is not
    pythonfmu's and is left alone."""
    try:
        release = dll[PYTHONFMU_RELEASE]
    except AttributeError:
        return
    release.argtypes, release.restype = [], None
    release()


def sharing(fmpy_class: type) -> type:
    """The subclass of an fmpy FMU class (``FMU2Slave``, ``FMU3Model``, ...) whose
    instances share one binding of their library's functions."""
    if fmpy_class not in _CLASSES:
        # the same name: fmpy's _loadFunctions picks the functions' prefix (fmi1, fmi2,
        # fmi3) from the class's name
        _CLASSES[fmpy_class] = type(fmpy_class.__name__, (_Shared, fmpy_class), {
            "__doc__": f"fmpy's {fmpy_class.__name__}, its functions bound once per library "
                       "(dsim.master.running.fmi.library)"})
    return _CLASSES[fmpy_class]


def raw(fmu, name: str):
    """FMI function ``name`` of ``fmu``'s library as a ctypes function that returns an
    int status and converts no argument (the caller passes ctypes objects): one object
    for every instance of the file that shares the binding, a new one for an instance
    that does not (an fmpy class not made by :func:`sharing`)."""
    return shared(fmu, ("function", name), lambda: _status_function(fmu, name))


def _status_function(fmu, name: str):
    function = fmu.dll[name]  # a new function object: fmpy's keeps its argtypes
    function.restype = ctypes.c_int
    return function


def shared(fmu, key, make):
    """The object stored under ``key`` in the binding ``fmu`` holds, made by ``make()``
    on first use: something every instance of the file may use and none changes (a
    function of the library, an array of value references).  It goes with the binding,
    when the last instance closes the library; without a binding it is made anew."""
    entry = _BOUND.get(getattr(fmu, "_binding", None))
    if entry is None:
        return make()
    kept = entry[2]
    if key not in kept:
        kept[key] = make()
    return kept[key]


def bindings() -> int:
    """How many library bindings are held now (one per FMU file and class in use)."""
    return len(_BOUND)


def binds(fmpy_class: type, library: str) -> int:
    """How many live instances share the binding of ``library`` by ``fmpy_class``'s
    subclass (0: none is held)."""
    entry = _BOUND.get((sharing(fmpy_class), str(library)))
    return entry[1] if entry else 0
