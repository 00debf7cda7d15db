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
    "MissingColumn": "recording.results",  # result["missing"]: a KeyError naming the closest
    "read_csv": "recording.results",
    "read_units": "recording.results",  # column -> unit of a results CSV (its statistics)
    "load_scene": "planning.load",
    # what a front end needs besides a run (dsim serve, serve/, imports only these names)
    "validate": "checks.validate",  # dsim validate's checks of a scene: a Validation
    "compare_files": "checks.compare",  # dsim compare RESULT BASELINE: a Comparison
    "SETTINGS": "settings",  # every run setting by keyword: option, help, kind, rule
    "choices": "settings",  # the valid names of a setting that chooses an implementation
    "resolve": "settings",  # keyword settings applied to a MasterSettings, checked
    "MasterSettings": "scene",
    "describe": "reading.fmi_description",  # an FMU's modelDescription: an FmuDescription
    "fmu_problem": "reading.fmu_archive",  # what is wrong with an FMU file (None: nothing)
    "conventional_ports": "reading.ports",  # an FMU's ports, from its variables' names
    "check_archive": "reading.unpacking",  # a zip's members, checked as untrusted input
    "MAX_UNPACKED": "reading.unpacking",  # the most bytes an archive may unpack to
    "free_settable": "planning.parameters",  # what --set may set in a plan's component
    "joint_coefficients": "planning.parameters",  # what --set may set in a joint
    "mat_bytes": "recording.results",  # columns as a MATLAB .mat file (dsim run --mat)
    "plot_signals": "recording.results", "plot_overlay": "recording.results",
    "Sweep": "sweeps.sweep", "sweep_of": "sweeps.sweep", "run_sweep": "sweeps.sweep",
    "check": "sweeps.sweep",  # a Sweep checked as dsim sweep checks a sweep file
    "unrecorded_columns": "sweeps.sweep",  # a sweep's KPIs and columns a scene lacks
    "mark_pareto": "sweeps.sweep",  # mark the points no other beats in error and time
    "cheapest": "sweeps.sweep",  # a sweep's fastest stable point within a target error
    "TIGHTEST": "sweeps.sweep",  # a sweep's reference: its tightest point
    "DESIGNS": "sweeps.design",  # the designs of experiments dsim sweep draws
    "parse_vary": "sweeps.design",  # one --vary NAME=SPEC as a sweep's factor
    "Point": "sweeps.table",  # one point of a sweep, as sweep.csv holds it
    "read_table": "sweeps.table",  # a sweep.csv: (varied names, KPI labels, points)
    "read_sensitivity": "sweeps.folder",  # a sweep folder's sensitivity.csv rows
    "Index": "sweeps.sensitivity",  # one sensitivity index of a KPI to a factor
    "ranking": "sweeps.sensitivity",  # the factors of a KPI, most influential first
    "ranking_text": "sweeps.sensitivity",  # the same as text, indices spanning 0 marked ~0
    "read_scenario": "reading.scenario_files",  # a scenario file (libcosim's, ECOS's)
    "EVENT_MODES": "planning.scenario",  # when a scenario's events take effect (--events)
    "end_process": "tools.process_exit",  # exit without the FMU libraries' exit handlers
    "process_alive": "processes",  # whether a process (the one started then) still runs
    "process_start_time": "processes",  # a process's start time, as process_alive takes it
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
