"""dsim: a co-simulation master for mechanical systems (FMI 2.0 co-simulation FMUs,
SSP 1.0 systems, T-T gluing).

    import dsim
    result = dsim.simulate("build/ssp/spring_mass_nonlinear.ssp", stop=2.0, tolerance=1e-10)
    result.status, result["right.x[2]"], result.statistics["iterations"]

See docs/api.md.  The implementation lives in the ``master`` package; this one is
its public face.
"""
from dsim.master import __version__
from dsim.master.api import prepare, simulate
from dsim.master.errors import InputError, SimulationError
from dsim.master.planning.plan import Plan
from dsim.master.reading.ssp import load_scene
from dsim.master.recording.observers import (CsvRecorder, MemoryRecorder, Observer, PlotWriter,
                                             ProgressBar, RunInfo, StatisticsWriter, StepRecord)
from dsim.master.recording.results import RunResult, read_columns, read_csv
from dsim.master.running.backends import BACKENDS, Backend
from dsim.master.running.couplings import COUPLINGS, Coupling, StepReport
from dsim.master.running.couplings.convergence import CONVERGENCE_TESTS
from dsim.master.running.couplings.predictors import PREDICTORS
from dsim.master.running.couplings.refresh import REFRESH_POLICIES
from dsim.master.running.execution import Execution

__all__ = ["BACKENDS", "Backend", "COUPLINGS", "CONVERGENCE_TESTS", "Coupling", "CsvRecorder",
           "Execution", "InputError", "MemoryRecorder", "Observer", "PREDICTORS", "Plan",
           "PlotWriter", "ProgressBar", "REFRESH_POLICIES", "RunInfo", "RunResult",
           "SimulationError", "StatisticsWriter", "StepRecord", "StepReport", "load_scene",
           "prepare", "read_columns", "read_csv", "simulate", "__version__"]
