"""A process that ran a pythonfmu FMU exits without releasing pythonfmu's shared
interpreter state twice (dsim.master.running.fmi.library._release_python_state).

pythonfmu 0.7 releases that state from a C++ static destructor and again from its
library's destructor function, on the freed block: about one script in thirty that
ran dsim.simulate on a pythonfmu FMU aborted after its last line ("corrupted
double-linked list", exit code 134).  The abort depends on the allocator's state;
valgrind sees the second release every time, so the test runs the same short script
under valgrind twice: as dsim runs it, and with the release switched off (the
control, which shows the test can fail)."""
from __future__ import annotations

import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import pytest

#: instantiate and free one instance the way dsim does (its shared binding), then exit
SCRIPT = """
import sys
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from dsim.master.running.fmi import library
if sys.argv[2] == "off":
    library._release_python_state = lambda dll: None
folder = extract(sys.argv[1])
description = read_model_description(sys.argv[1])
fmu = library.sharing(FMU2Slave)(guid=description.guid, unzipDirectory=folder,
                                 modelIdentifier=description.coSimulation.modelIdentifier,
                                 instanceName="one")
fmu.instantiate()
fmu.freeInstance()
print("freed")
"""


def _memcheck(fmu, release: str) -> str:
    """valgrind's report of the script's process, exit included."""
    done = subprocess.run(["valgrind", "--error-exitcode=0", "--undef-value-errors=no", sys.executable, "-c", SCRIPT,
                           str(fmu), release], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0 and "freed" in done.stdout, done.stderr[-2000:]
    return done.stderr


def test_a_process_that_ran_a_pythonfmu_fmu_exits_without_a_second_release(built):
    if shutil.which("valgrind") is None:
        pytest.skip("no valgrind (Debian package valgrind)")
    fmu = built["fmus"] / "SpringMass.fmu"
    with ThreadPoolExecutor(2) as pool:
        released, control = pool.map(lambda how: _memcheck(fmu, how), ("on", "off"))
    # the control: pythonfmu reads its freed pointer at exit
    assert "Invalid read" in control and "finalizePythonInterpreter" in control
    assert "finalizePythonInterpreter" not in released, released[-3000:]
