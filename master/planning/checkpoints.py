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


def read_files(plan, settings: dict) -> dict[str, str]:
    """Path -> SHA-256 of every file the run of ``plan`` reads: the scene, each FMU, a
    scenario and an input table given as files."""
    paths = [Path(plan.scene.file)] + [Path(spec.path) for spec in plan.specs
                                       if spec.table is None]
    paths += [Path(settings[key]) for key in FILE_SETTINGS
              if isinstance(settings.get(key), (str, Path))]
    digests = {}
    for path in paths:
        key = str(path.resolve())
        if key not in digests and path.is_file():
            digests[key] = file_digest(path)
    return digests


def manifest_of_run(plan, request, settings: dict, every: float) -> dict:
    """What every checkpoint of a run says of it besides its step."""
    return {"dsim": __version__, "scene": plan.scene.name, "every": every,
            "request": request, "files": {},  # (the checkpoint's own, set when written)
            "read": read_files(plan, settings),
            "parameters": {spec.name: {name: repr(value)
                                       for name, value in sorted(spec.parameters.items())}
                           for spec in plan.specs}}


def check_files(manifest: dict, plan, settings: dict, where: str) -> None:
    """Refuse (one line) a checkpoint whose run read other files than ``plan`` reads
    now: a changed FMU, scene, scenario or table."""
    then = manifest.get("read") or {}
    now = read_files(plan, settings)
    for path, digest in now.items():
        if path in then and then[path] != digest:
            raise InputError(f"{where}: {path} changed since the checkpoint was written "
                             "(its SHA-256 differs): the saved states belong to the old one")
    fmus = {str(Path(spec.path).resolve()) for spec in plan.specs if spec.table is None}
    missing = sorted(p for p in fmus if p not in then)
    if missing and not any(Path(p).name == Path(q).name and then[q] == now.get(p)
                           for p in missing for q in then):
        raise InputError(f"{where}: the run read other FMUs ({missing[0]} is not among "
                         "the checkpoint's): another scene")


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
