"""What a run with checkpoints is checked against (docs/checkpoints.md): which of its
FMUs cannot serialize their state, the request a checkpoint records so that
``--resume`` can make the same run again, the digests of the files it read (a changed
FMU, scene, scenario or input table refuses the checkpoint), and which changed
parameters a run started from a checkpoint (``--from``) may set on top of the saved
states."""
from __future__ import annotations

import math
from pathlib import Path

from dsim.master import __version__
from dsim.master.errors import InputError
from dsim.master.reading.digests import file_digest
from dsim.master.reading.fmi_description import describe
from dsim.master.running.fmi import serialization_problem

#: settings a resumed run may give anew: where it runs, not what it computes
WHERE_IT_RUNS = ("backend", "address", "call_timeout", "restarts")
#: settings that name files the run reads (their digests are checked)
FILE_SETTINGS = ("scenario", "inputs")


def checkpoint_problems(plan) -> list[str]:
    """One line per component whose state cannot be written to a checkpoint."""
    return [problem for spec in plan.specs if (problem := serialization_problem(spec))]


def checked_every(every) -> float:
    """``--checkpoint-every`` as seconds of simulated time (a positive finite number)."""
    try:
        value = float(every)
    except (TypeError, ValueError):
        raise InputError(f"checkpoint_every: '{every}' is not a number of seconds") from None
    if not math.isfinite(value) or value <= 0:
        raise InputError(f"checkpoint_every: {every} s: give a positive number of seconds "
                         "of simulated time")
    return value


def _plain(value):
    """``value`` as JSON holds it, or raise TypeError (a DataFrame, a loaded scene)."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, Path):
        return str(value.resolve())
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, dict) and all(isinstance(k, str) for k in value):
        return {k: _plain(v) for k, v in value.items()}
    raise TypeError(type(value).__name__)


def request_of(scene, settings: dict, outputs: dict) -> dict | None:
    """What ``--resume`` needs to make the same run again: the scene's file, the
    settings and the output files, as JSON; None when something was given as an
    object and not a file (the API's DataFrame, a loaded scene): such a run is resumed
    by calling :func:`~dsim.master.api.simulate` with the same arguments."""
    try:
        if not isinstance(scene, (str, Path)):
            return None
        files = {key: _plain(settings[key]) for key in FILE_SETTINGS
                 if isinstance(settings.get(key), (str, Path))}
        return {"scene": str(Path(scene).resolve()),
                "settings": {**_plain({k: v for k, v in settings.items()}), **files},
                "outputs": {k: str(Path(v).resolve()) if isinstance(v, (str, Path)) else
                            _plain(v) for k, v in outputs.items()}}
    except TypeError:
        return None


def read_files(plan, settings: dict) -> dict:
    """The SHA-256 of what the run of ``plan`` reads: its scene file, each component's
    FMU (by component: an archive's FMUs are unpacked to a new place every run), and
    a scenario and an input table given as files (by path)."""
    scene = Path(plan.scene.file)
    return {"scene": file_digest(scene) if scene.is_file() else None,
            "fmus": {spec.name: file_digest(spec.path) for spec in plan.specs
                     if spec.table is None},
            "files": {str(Path(settings[key]).resolve()): file_digest(settings[key])
                      for key in FILE_SETTINGS
                      if isinstance(settings.get(key), (str, Path))
                      and Path(settings[key]).is_file()}}


def manifest_of_run(plan, request, settings: dict, every: float) -> dict:
    """What every checkpoint of a run says of it besides its step."""
    return {"dsim": __version__, "scene": plan.scene.name, "every": every,
            "request": request, "read": read_files(plan, settings),
            "parameters": {spec.name: {name: repr(value)
                                       for name, value in sorted(spec.parameters.items())}
                           for spec in plan.specs}}


def check_files(manifest: dict, plan, settings: dict, where: str,
                fresh: bool = False) -> None:
    """Refuse (one line) a checkpoint whose run read another scene or FMU than ``plan``
    reads now (or the same files changed since); a resumed run (not ``fresh``) also
    another scenario or input table."""
    then, now = manifest.get("read") or {}, read_files(plan, settings)
    if then.get("scene") != now["scene"]:
        raise InputError(f"{where}: {plan.scene.file} is not the scene of the checkpoint's "
                         "run, or it changed since the checkpoint was written (its SHA-256 "
                         "differs)")
    for name, digest in now["fmus"].items():
        if (then.get("fmus") or {}).get(name) != digest:
            raise InputError(f"{where}: component '{name}': its FMU is not the one the "
                             "checkpoint's run read, or it changed since (its SHA-256 "
                             "differs): the saved state belongs to that one")
    if not fresh:
        for path, digest in now["files"].items():
            if (then.get("files") or {}).get(path) != digest:
                raise InputError(f"{where}: {path} changed since the checkpoint was written "
                                 "(its SHA-256 differs)")


def resumed_settings(manifest: dict, given: dict, where: str) -> tuple[str, dict, dict]:
    """The scene, settings and outputs of the run a checkpoint belongs to, with what
    ``given`` says of where it runs (the backend and its options)."""
    request = manifest.get("request")
    if not request:
        raise InputError(f"{where}: its run was given objects, not files (a DataFrame, a "
                         "loaded scene): resume it from Python with the same arguments")
    changed = sorted(k for k, v in given.items() if v is not None and k not in
                     WHERE_IT_RUNS and request["settings"].get(k) != v)
    if changed:
        raise InputError(f"{where}: a resumed run goes on with its own settings; "
                         f"{', '.join(changed)} cannot change (start a new run from the "
                         "checkpoint with --from)")
    settings = dict(request["settings"])
    settings.update({k: v for k, v in given.items() if k in WHERE_IT_RUNS and v is not None})
    return request["scene"], settings, request.get("outputs") or {}


def changed_parameters(manifest: dict, plan, where: str) -> list[tuple[int, tuple, tuple]]:
    """For a run started from a checkpoint (``--from``): the values it gives that differ
    from the checkpoint's run, as (component index, names, values) to set on top of the
    saved states; refused (one line) where the variable is no tunable parameter or
    input (a fixed parameter's value is part of the saved state)."""
    then = manifest.get("parameters") or {}
    entries = []
    for index, spec in enumerate(plan.specs):
        old = then.get(spec.name, {})
        names, values = [], []
        for name, value in sorted(spec.parameters.items()):
            if old.get(name) == repr(value):
                continue
            variable = describe(spec.path).by_name.get(name) if spec.table is None else None
            if variable is None or not (variable.causality == "input" or (
                    variable.causality == "parameter" and variable.variability == "tunable")):
                raise InputError(f"{where}: '{spec.name}.{name}' differs from the "
                                 "checkpoint's run, and it is no tunable parameter nor input: "
                                 "its value is part of the saved state")
            names.append(name)
            values.append(value[1] if isinstance(value, tuple) else value)
        if names:
            entries.append((index, tuple(names), tuple(values)))
    return entries
