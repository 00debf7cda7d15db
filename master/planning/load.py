"""A scene as a run uses it: read (:mod:`dsim.master.reading.ssp`, which keeps the
``glue:Master`` annotation as the file writes it) and its master settings converted
and checked by the one set of rules of :mod:`dsim.master.settings`.  ``dsim.load_scene``
is :func:`load_scene`."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from dsim.master.errors import InputError
from dsim.master.reading.ssp import read_scene
from dsim.master.settings import SETTINGS, convert, settings_from_annotation


def with_master_settings(scene):
    """``scene`` with ``master`` and ``step_from`` from its ``glue:Master`` attributes
    and, where those give no step, another tool's (OMSimulator, OSP); what is wrong with
    them is added to ``scene.problems`` (the default kept)."""
    problems = list(scene.problems)
    settings = settings_from_annotation(scene.master_annotation, scene.master_where, problems)
    step_from = "glue:Master" if "step" in scene.master_annotation else "dsim's default"
    if scene.other_step:
        text, where, origin = scene.other_step
        value, problem = convert(SETTINGS["step"], text.strip(), where)
        if problem:
            problems.append(problem)
        else:
            settings, step_from = replace(settings, step=value), origin
    return replace(scene, master=settings, step_from=step_from,
                   problems=tuple(dict.fromkeys(problems)))


def _folders(allow_outside) -> tuple:
    """``allow_outside`` as a tuple of existing folders (one path or several)."""
    if allow_outside is None:
        return ()
    if isinstance(allow_outside, (str, Path)):
        allow_outside = [allow_outside]
    folders = tuple(Path(folder) for folder in allow_outside)
    missing = [str(folder) for folder in folders if not folder.is_dir()]
    if missing:
        raise InputError(f"--allow-outside {missing[0]}: no such folder")
    return folders


def load_scene(path, parameter_sets=(), strict: bool = True, ssd: str | None = None,
               allow_outside=()):
    """Read and check an SSP system (.ssp, folder or .ssd) with its master settings;
    raise InputError listing every problem (or, not ``strict``, keep them in
    ``Scene.problems`` when the system could be read, so that the plan adds its own).
    ``parameter_sets``: parameter sets applied on top of every binding (an .ssv file of
    the scene, or a ParameterSet's name); ``ssd``: which .ssd of the archive or folder;
    ``allow_outside``: folders the scene may name files in besides its own
    (docs/security.md)."""
    scene = with_master_settings(read_scene(path, parameter_sets, strict=False, ssd=ssd,
                                            allow_outside=_folders(allow_outside)))
    if scene.problems and strict:
        error = InputError(list(scene.problems))
        error.warnings = list(scene.warnings)
        raise error
    return scene
