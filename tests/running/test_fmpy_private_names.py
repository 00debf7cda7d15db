"""The fmpy names dsim relies on that fmpy does not promise (running/fmi/library.py,
the only module that uses them): a new fmpy that renames or reshapes them fails
here, by name, rather than somewhere inside a run.  pyproject.toml bounds fmpy
below its next minor version for the same reason."""
import ctypes
import ctypes.util
import inspect
import re

import fmpy
import pytest
from fmpy.fmi1 import FMU1Slave
from fmpy.fmi2 import FMU2Model, FMU2Slave
from fmpy.fmi3 import FMU3Model, FMU3Slave

from tests.support.paths import ROOT

CLASSES = [FMU1Slave, FMU2Slave, FMU2Model, FMU3Slave, FMU3Model]


@pytest.mark.parametrize("fmpy_class", CLASSES, ids=lambda c: c.__name__)
def test_each_fmpy_class_binds_its_functions_in_load_functions(fmpy_class):
    """library._Shared overrides ``_loadFunctions`` and reads ``_functions`` (the
    functions it bound, by name) and the instance's ``dll``; fmpy picks the prefix
    of the functions from the class's name, which sharing() keeps."""
    load = getattr(fmpy_class, "_loadFunctions", None)
    assert callable(load), f"{fmpy_class.__name__} has no _loadFunctions any more"
    assert list(inspect.signature(load).parameters) == ["self"]
    source = "".join(inspect.getsource(c) for c in fmpy_class.__mro__
                     if c.__module__.startswith("fmpy"))
    assert re.search(r"self\._functions\b", source), "fmpy no longer keeps _functions"
    assert re.search(r"self\.dll\b", source), "fmpy no longer keeps the library as dll"
    assert "freeLibrary" in dir(fmpy_class)


def test_a_ctypes_library_knows_its_file_name():
    """The binding is keyed by ``dll._name``, ctypes' name of the file it opened."""
    library = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
    assert isinstance(library._name, str) and library._name


def test_the_fmpy_installed_is_within_the_bound_pyproject_gives():
    """The bound and the installed fmpy agree, so that this file tests the fmpy a
    user of the bound gets."""
    text = (ROOT / "pyproject.toml").read_text()
    low, high = re.search(r'"fmpy>=([\d.]+),<([\d.]+)"', text).groups()
    version = tuple(int(p) for p in re.findall(r"\d+", fmpy.__version__)[:3])
    assert tuple(map(int, low.split("."))) <= version < tuple(map(int, high.split(".")))
