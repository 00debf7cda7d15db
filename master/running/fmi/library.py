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
"""
from __future__ import annotations

#: (fmpy class, library file) -> [its functions by name, instances holding them]
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
            entry = _BOUND[key] = [self._functions, 0]
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
        super().freeLibrary()


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


def bindings() -> int:
    """How many library bindings are held now (one per FMU file and class in use)."""
    return len(_BOUND)


def binds(fmpy_class: type, library: str) -> int:
    """How many live instances share the binding of ``library`` by ``fmpy_class``'s
    subclass (0: none is held)."""
    entry = _BOUND.get((sharing(fmpy_class), str(library)))
    return entry[1] if entry else 0
