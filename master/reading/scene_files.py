"""Files of a scene that its String parameters name (``resources/meshes/plate.vtk``):
an FMU only knows its own resources, so the master hands it the absolute path of a
file of the scene (docs/ssp_support.md).  Shared by the SSP reader and the
parameters given for one run (:mod:`dsim.master.planning.parameters`)."""
from __future__ import annotations

from pathlib import Path

#: the prefix of a String parameter value that names a file of the scene
SCENE_RESOURCES = "resources/"


def scene_file(base: Path, name: str, value: str, where: str):
    """(the scene file a String value ``resources/...`` names, or None; the problem,
    or None): an FMU only knows its own resources, so the master hands it the
    absolute path of a file of the scene (docs/ssp_support.md)."""
    resources = base.resolve() / "resources"
    file = (base / value).resolve()
    if not file.is_relative_to(resources):
        return None, f"{where}: parameter '{name}' = '{value}' leaves the scene's resources folder"
    if not file.is_file():
        return None, f"{where}: parameter '{name}' = '{value}': the scene has no such file"
    return file, None
