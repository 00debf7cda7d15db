"""The run settings: the one place where every setting is named, converted and checked.

The scene's ``glue:Master`` annotation, the command line (``dsim run --tolerance``) and
the Python API (``dsim.simulate(scene, tolerance=...)``) all pass through
:func:`resolve`, so a value is valid in one exactly when it is valid in the others,
and an invalid one is bad input (:class:`~dsim.master.errors.InputError`) that says which
values are valid.  The names that choose an implementation (coupling, predictor,
refresh policy, convergence test, start, backend) are checked against the registries that hold the
implementations, so a new entry in a registry is a valid setting at once.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

from dsim.master.errors import InputError
from dsim.master.running.backends import BACKENDS
from dsim.master.running.couplings import COUPLINGS
from dsim.master.running.couplings.convergence import CONVERGENCE_TESTS
from dsim.master.running.couplings.predictors import PREDICTORS
from dsim.master.running.couplings.refresh import REFRESH_POLICIES
from dsim.master.running.start import START_MODES
from dsim.master.scene import MasterSettings

#: the registry that holds the valid names of each setting that selects an
#: implementation (a new entry is a valid setting at once)
REGISTRIES = {"coupling": COUPLINGS, "predictor": PREDICTORS, "refresh": REFRESH_POLICIES,
              "convergence": CONVERGENCE_TESTS, "start": START_MODES, "backend": BACKENDS}


def _choices(setting: str) -> tuple[str, ...]:
    """Valid names of a setting that selects an implementation (from its registry)."""
    return tuple(REGISTRIES[setting])


@dataclass(frozen=True)
class Setting:
    """One setting: its Python keyword, ``glue:Master`` attribute, type and rule."""

    keyword: str
    attribute: str | None
    kind: type
    rule: str  # "positive", "non-negative", "at least 1", "choice" or "text"
    help: str

    @property
    def option(self) -> str:
        """The command-line option (``--max-iterations``)."""
        return "--" + self.keyword.replace("_", "-")


SETTINGS = {s.keyword: s for s in (
    Setting("stop", None, float, "positive", "stop time, s (default: the scene's "
            "DefaultExperiment stopTime)"),
    Setting("step", "step", float, "positive", "macro step H, s, or auto: chosen at "
            "every step from an error estimate, to --error-tolerance (docs/method.md)"),
    Setting("error_tolerance", "errorTolerance", float, "positive",
            "with --step auto: the error the run keeps to, weighted E + E |x| per "
            "interface quantity and connected value (default 1e-6)"),
    Setting("min_step", "minStep", float, "positive",
            "with --step auto: the smallest macro step, s (default: the output "
            "interval / 2**20)"),
    Setting("max_step", "maxStep", float, "positive",
            "with --step auto: the largest macro step, s (default: the output interval, "
            "which every step lands on)"),
    Setting("tolerance", "tolerance", float, "positive",
            "absolute interface tolerance, in the units of the joints' measure (m for "
            "displacement)"),
    Setting("relative_tolerance", "relativeTolerance", float, "non-negative",
            "tolerance relative to the size of the measure on both sides of a joint"),
    Setting("max_iterations", "maxIterations", int, "at least 1",
            "Newton iterations per macro step before the run fails"),
    Setting("refresh_after", "refreshAfter", int, "at least 1",
            "re-measure the interface flexibility after this many iterations of one step"),
    Setting("perturbation", "perturbation", float, "positive",
            "relative force perturbation that measures the interface flexibility"),
    Setting("step_cuts", "stepCuts", int, "non-negative",
            "times a macro step whose Newton iteration fails may be halved before the run "
            "fails (only where every glued FMU accepts variable steps; 0: never)"),
    Setting("predictor", "predictor", str, "choice",
            "first guess of the joint forces from past steps"),
    Setting("refresh", "refresh", str, "choice",
            "when to re-measure the interface flexibility"),
    Setting("convergence", "convergence", str, "choice",
            "when Newton may stop: residual (within the tolerance) or forces (the "
            "residual, and the force correction still to come, times each dof's own "
            "compliance)"),
    Setting("coupling", "coupling", str, "choice",
            "iterative: T-T Newton with rollback; explicit: one trial per step (a "
            "baseline); causal: no joints, causal connections only; strong: the "
            "connections between FMUs that can roll back iterated to convergence, around "
            "the joints' Newton"),
    Setting("start", "start", str, "choice",
            "start forces: auto (flexible joints from their law), consistent (fixed "
            "joints too, from acceleration compatibility) or rest (zero)"),
    Setting("backend", None, str, "choice",
            "where the subsystems run: here, in Ray workers (a local instance or the "
            "cluster at --address), or one local worker process per FMU (isolated)"),
    Setting("address", None, str, "text",
            "the Ray cluster of --backend ray: HOST:PORT of its head (`ray start --head` "
            "prints it) or auto; without it dsim starts a local Ray instance for the run"),
    Setting("call_timeout", None, float, "positive",
            "seconds a worker of the ray or isolated backend may take to answer one call "
            "(a step of its FMUs); past it the worker is stopped and the run ends (exit 1) "
            "naming its components; default: no limit"),
    Setting("restarts", None, int, "non-negative",
            "workers of the ray or isolated backend started again, at most, when one is "
            "lost (killed, or gone with its node): its FMUs go on from the last converged "
            "step on a node that is left; 0: a lost worker ends the run (exit 1); and, "
            "with --checkpoint-every, times dsim run's process is started again from the "
            "last checkpoint when it dies (docs/checkpoints.md); default: 3"),
    Setting("parameter_set", None, str, "text",
            "a parameter set of the scene applied on top of its bindings: an .ssv file's "
            "path in the scene or a ParameterSet's name"),
    Setting("ssd", None, str, "text",
            "the system structure to read, when the archive or folder holds several .ssd "
            "files (dsim info lists them; default SystemStructure.ssd)"),
)}

#: glue:Master attribute -> setting
BY_ATTRIBUTE = {s.attribute: s for s in SETTINGS.values() if s.attribute}


def choices(keyword: str) -> tuple[str, ...]:
    """The valid values of a setting that names an implementation."""
    return _choices(keyword)


def convert(setting: Setting, value, label: str) -> tuple[object, str | None]:
    """``value`` (text from a file or the command line, or a Python value) as the
    setting's type, and the problem with it, which starts with ``label`` (None when
    the value is valid)."""
    if setting.rule == "text":
        return str(value), None
    if setting.kind is str:
        valid = choices(setting.keyword)
        if str(value) not in valid:
            return value, f"{label} '{value}' is not one of: {', '.join(valid)}"
        return str(value), None
    try:
        if isinstance(value, bool):
            raise ValueError
        number = float(value) if isinstance(value, str) else value
        if setting.kind is int and not float(number).is_integer():
            raise ValueError
        converted = setting.kind(number)
    except (TypeError, ValueError, OverflowError):
        article = "an integer" if setting.kind is int else "a number"
        return value, f"{label} '{value}' is not {article}"
    valid = {"positive": math.isfinite(converted) and converted > 0,
             "non-negative": math.isfinite(converted) and converted >= 0,
             "at least 1": converted >= 1}[setting.rule]
    if not valid:
        wanted = {"positive": "a finite number greater than 0",
                  "non-negative": "a finite number >= 0", "at least 1": "at least 1"}
        return value, f"{label} must be {wanted[setting.rule]}, got {value}"
    return converted, None


#: the step setting's word for an error-controlled macro step
AUTO = "auto"


def is_auto(keyword: str, value) -> bool:
    """Whether ``value`` of setting ``keyword`` asks for the error-controlled step
    (``step="auto"``, any case, spaces around)."""
    return keyword == "step" and isinstance(value, str) and value.strip().lower() == AUTO


def convert_setting(keyword: str, value, label: str) -> tuple[object, str | None]:
    """:func:`convert` of the setting ``keyword``, where ``step`` may also be ``auto``."""
    if is_auto(keyword, value):
        return AUTO, None
    return convert(SETTINGS[keyword], value, label)


#: the settings that only an error-controlled run takes
STEP_CONTROL = ("error_tolerance", "min_step", "max_step")


def step_control_problems(settings: MasterSettings, where: str,
                          attributes: bool = False) -> list[str]:
    """What is wrong with the error-control settings together, one line each, starting
    with ``where`` and naming the settings as keywords (or as ``glue:Master``
    ``attributes``)."""
    def name(keyword):
        return SETTINGS[keyword].attribute if attributes else keyword
    problems = []
    if not settings.adaptive:
        problems += [f"{where} {name(k)}: only an error-controlled step takes it (step auto, "
                     f"--step auto), and the step is fixed at {settings.step:g} s"
                     for k in STEP_CONTROL if getattr(settings, k) is not None]
    elif (settings.min_step is not None and settings.max_step is not None
          and settings.min_step > settings.max_step):
        problems.append(f"{where} {name('min_step')} {settings.min_step:g} s is larger than "
                        f"{name('max_step')} {settings.max_step:g} s")
    return problems


def settings_from_annotation(attributes: dict, where: str, problems: list) -> MasterSettings:
    """The master settings of a ``glue:Master`` element's attributes (text); each
    problem is appended to ``problems`` and its default kept."""
    values = {}
    for attribute, text in attributes.items():
        setting = BY_ATTRIBUTE.get(attribute)
        if setting is not None and is_auto(setting.keyword, text):
            values["adaptive"] = True
            continue
        if setting is None:
            problems.append(f"{where}: unknown attribute '{attribute}' (known: "
                            f"{', '.join(sorted(BY_ATTRIBUTE))})")
            continue
        value, problem = convert(setting, text, f"{where}: {attribute}")
        if problem:
            problems.append(problem)
        else:
            values[setting.keyword] = value
    settings = MasterSettings(**values)
    problems += step_control_problems(settings, f"{where}:", attributes=True)
    return settings


def resolve(master: MasterSettings, overrides: dict) -> tuple[MasterSettings, dict]:
    """Apply keyword ``overrides`` (None means: keep the scene's value) to the scene's
    settings.  Returns the master settings and the run options that are not master
    settings (``stop``, ``backend``); raises InputError listing every invalid value."""
    problems, values, run_options = [], {}, {}
    master_fields = {f.name for f in fields(MasterSettings)}
    for keyword, value in overrides.items():
        if value is None:
            continue
        setting = SETTINGS.get(keyword)
        if setting is None:
            problems.append(f"unknown setting '{keyword}' (known: {', '.join(SETTINGS)})")
            continue
        if is_auto(keyword, value):
            values["adaptive"] = True
            continue
        converted, problem = convert(setting, value, f"setting {keyword}")
        if problem:
            problems.append(problem)
        elif keyword in master_fields:
            values[keyword] = converted
        else:
            run_options[keyword] = converted
    if "step" in values:  # a fixed step for this run: the scene's error control goes
        values["adaptive"] = False
        values.update({k: None for k in STEP_CONTROL if k not in values})
    if problems:
        raise InputError(problems)
    master = replace(master, **values)
    problems = step_control_problems(master, "setting")
    if problems:
        raise InputError(problems)
    return master, run_options


#: Largest number of macro steps: beyond 2**52 steps of one span, start + n * step
#: no longer gives distinct times in double precision.
MAX_STEPS = 2 ** 52


def check_span(start: float, stop: float, step: float, where: str) -> list[str]:
    """Problems with a run from ``start`` to ``stop`` (s) in steps of ``step`` (s)."""
    problems = []
    if not (math.isfinite(start) and math.isfinite(stop)):
        problems.append(f"{where}: start time {start:g} and stop time {stop:g} must be finite")
    elif not stop > start:
        problems.append(f"{where}: stop time {stop:g} is not after the start time {start:g}")
    elif math.isfinite(step) and step > 0 and (stop - start) / step > MAX_STEPS:
        problems.append(f"{where}: {(stop - start) / step:.3g} steps of {step:g} s from "
                        f"{start:g} to {stop:g} s: more than {MAX_STEPS:.3g}, the times would "
                        "not be distinct in double precision")
    return problems
