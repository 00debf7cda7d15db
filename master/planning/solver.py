"""The Model Exchange integrator settings given for a run (``--solver``,
``dsim.simulate(solver=...)``), applied over what the SSD's annotations say
(:mod:`dsim.master.reading.ssp_solver`); the plan checks each value
(:func:`dsim.master.running.fmi.integrator.solver_problem`)."""
from __future__ import annotations

from dataclasses import replace

from dsim.master.planning.parameters import require_mapping
from dsim.master.running.fmi.integrator import SOLVER_KEYS


def with_solver(scene, solver):
    """``scene`` with the run's ``solver`` settings (NAME or COMPONENT.NAME -> value)
    on its components; a name that reaches no component is a problem of the scene."""
    given = require_mapping(solver)
    if not given:
        return scene
    paths = {c.path for c in scene.components}
    every, per_component, problems = [], {}, []
    for key, value in given.items():
        key = str(key).strip()
        path, _, name = key.rpartition(".")
        if not path and name in SOLVER_KEYS:
            every.append((name, value))
        elif path in paths and name in SOLVER_KEYS:
            per_component.setdefault(path, []).append((name, value))
        else:
            problems.append(f"solver setting '{key}': give NAME or COMPONENT.NAME with NAME "
                            f"one of {', '.join(SOLVER_KEYS)} and COMPONENT a component of "
                            "the scene")
    components = tuple(
        replace(c, solver=_merged(c.solver, every, per_component.get(c.path, [])))
        for c in scene.components)
    return replace(scene, components=components,
                   problems=tuple(scene.problems) + tuple(problems))


def _merged(*layers) -> tuple:
    """Settings as (name, value) pairs, a later layer's name winning."""
    merged: dict = {}
    for layer in layers:
        merged.update(dict(layer))
    return tuple(merged.items())
