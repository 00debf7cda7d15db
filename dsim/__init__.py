"""dsim: a co-simulation master for mechanical systems (FMI 2.0 co-simulation FMUs,
SSP 1.0 systems, T-T gluing).

    import dsim
    result = dsim.simulate("build/ssp/spring_mass_nonlinear.ssp", stop=2.0, tolerance=1e-10)
    result.status, result["right.x[2]"], result.statistics["iterations"]

See docs/api.md.  ``dsim`` is the one installed package: the master is
``dsim.master``, the subsystem models ``dsim.fmus``, the FMU and scene builder
``dsim.build_fmus``, the web front end ``dsim.serve`` (docs/architecture.md).  This
module is the public face: each name below is the master's own object.

The names are imported when first used (PEP 562), so that ``import dsim.fmus...``
(or an FMU-side tool) does not load the whole master, and so that every module of
the package can be imported on its own, in any order.
"""
from importlib import import_module

from dsim.master import __version__

#: public name -> the module of dsim.master that defines it
_WHERE = {
    "prepare": "api", "simulate": "api",
    "BACKENDS": "running.backends", "Backend": "running.backends",
    "COUPLINGS": "running.couplings", "Coupling": "running.couplings",
    "StepReport": "running.couplings",
    "CONVERGENCE_TESTS": "running.couplings.convergence",
    "PREDICTORS": "running.couplings.predictors",
    "REFRESH_POLICIES": "running.couplings.refresh",
    "InputError": "errors", "SimulationError": "errors",
    "Execution": "running.execution",
    "CsvRecorder": "recording.observers", "MemoryRecorder": "recording.observers",
    "Observer": "recording.observers", "PlotWriter": "recording.observers",
    "ProgressBar": "recording.observers", "RunInfo": "recording.observers",
    "StatisticsWriter": "recording.observers", "StepRecord": "recording.observers",
    "Plan": "planning.plan",
    "RunResult": "recording.results", "read_columns": "recording.results",
    "read_csv": "recording.results",
    "load_scene": "planning.load",
}

__all__ = sorted(_WHERE) + ["__version__"]


def __getattr__(name: str):
    if name not in _WHERE:
        raise AttributeError(f"module 'dsim' has no attribute '{name}'")
    value = getattr(import_module(f"dsim.master.{_WHERE[name]}"), name)
    globals()[name] = value  # once: the next access is an ordinary attribute
    return value


def __dir__():
    return sorted(set(globals()) | set(_WHERE))
