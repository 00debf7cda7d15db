"""dsim: a co-simulation master for mechanical systems (FMI 2.0 co-simulation FMUs,
SSP 1.0 systems, T-T gluing).

    import dsim
    result = dsim.simulate("build/ssp/spring_mass_nonlinear.ssp", stop=2.0, tolerance=1e-10)
    result.status, result["right.x[2]"], result.statistics["iterations"]

See docs/api.md.  The implementation lives in the ``master`` package; this one is
its public face.
"""
from master import __version__
from master.api import prepare, simulate
from master.backends import BACKENDS, Backend
from master.couplings import COUPLINGS, Coupling, StepReport
from master.couplings.convergence import CONVERGENCE_TESTS
from master.couplings.predictors import PREDICTORS
from master.couplings.refresh import REFRESH_POLICIES
from master.errors import InputError, SimulationError
from master.execution import Execution
from master.observers import (CsvRecorder, MemoryRecorder, Observer, PlotWriter, ProgressBar,
                              RunInfo, StatisticsWriter, StepRecord)
from master.plan import Plan
from master.results import RunResult, read_columns, read_csv
from master.ssp import load_scene

__all__ = ["BACKENDS", "Backend", "COUPLINGS", "CONVERGENCE_TESTS", "Coupling", "CsvRecorder",
           "Execution", "InputError", "MemoryRecorder", "Observer", "PREDICTORS", "Plan",
           "PlotWriter", "ProgressBar", "REFRESH_POLICIES", "RunInfo", "RunResult",
           "SimulationError", "StatisticsWriter", "StepRecord", "StepReport", "load_scene",
           "prepare", "read_columns", "read_csv", "simulate", "__version__"]
