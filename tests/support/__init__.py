"""What the tests share: helpers, fixtures and the C FMUs they compile.  Test modules
import from here (``from tests.support.scene_files import ssd``), never from one another;
benchmarks/ imports from here too.

- paths: the repository's root (ROOT) and the ``dsim`` command line (DSIM)
- scene_files: SSD text, scene folders and .ssp archives written by tests
- scenes: the scenes several test modules share
- interop: SSD parts as other tools write them (bindings, connectors, mappings)
- closed_forms: the closed forms of the C test models (bouncing ball, two masses)
- runs: comparing runs bit for bit, and a command's one-line errors
- ender: a C FMU that ends the simulation itself
- hung_fmu: the C oscillator that hangs in a step, as a scene fixture
- distributed: what the Ray tests share (a free port, the authentication hint)
- gluing: in-process cores glued by the master's T-T algorithm
- kernel_check: the runs a kernel test makes in a process of its own
- serve_fixtures: ``dsim serve`` applications and processes
- third_party: the plain-C FMUs (sources and builders)"""
