"""How many communication steps each component takes per macro step (``--substeps``,
the API's ``substeps=``, a component's ``glue:Substeps`` annotation), and which of
them get their Real inputs extrapolated with derivatives over those substeps.

Only a component exchanged once per step takes substeps: not one in a joint, nor one
whose connections the strong coupling iterates.  What counts, lowest first: ``auto``
(every component, from its FMU's DefaultExperiment stepSize), the scene's
``glue:Substeps`` of a component, a count given for that component (command line or
API).
"""
from __future__ import annotations

import math
from dataclasses import replace

from dsim.master.reading.fmi_description import describe
from dsim.master.running.fmi.input_slopes import extrapolated_places
from dsim.master.scene import Scene

#: why a component in a joint or an iterated connection takes none
STEPPED = ("is stepped with the others in a joint or an iterated connection; substeps are "
           "for a component exchanged once per step")


def whole_count(value) -> int:
    """``value`` (a number or its text) as a whole number >= 1, or 0 when it is none."""
    try:
        if isinstance(value, bool) or float(value) != int(float(value)):
            raise ValueError
        count = int(float(value))
    except (TypeError, ValueError, OverflowError):
        return 0
    return max(count, 0)


def _automatic(scene: Scene, stepped: set) -> dict:
    """component path -> its count from its FMU's DefaultExperiment stepSize (the
    macro step over it, rounded up), for every component not ``stepped`` whose FMU
    gives a step shorter than the macro step."""
    chosen = {}
    for index, component in enumerate(scene.components):
        step = None if index in stepped else getattr(
            describe(component.source).defaultExperiment, "stepSize", None)
        if step and 0 < float(step) < scene.master.step:
            chosen[component.path] = math.ceil(scene.master.step / float(step) - 1e-9)
    return chosen


def _annotated(scene: Scene, stepped: set, problems: list) -> dict:
    """component path -> the count of its ``glue:Substeps`` annotation; a count that is
    not a whole number >= 1, or one on a component that cannot take substeps, is a
    problem naming the file, the element and its line."""
    chosen = {}
    for index, component in enumerate(scene.components):
        if not component.substeps:
            continue
        text, where = component.substeps
        count = whole_count(text)
        if text is None:
            problems.append(f"{where}: attribute 'count' missing (a whole number >= 1)")
        elif count < 1:
            problems.append(f"{where}: count '{text}': give a whole number >= 1")
        elif index in stepped:
            problems.append(f"{where}: the component {STEPPED}")
        else:
            chosen[component.path] = count
    return chosen


def _asked(scene: Scene, asked: dict, stepped: set, problems: list) -> dict:
    """component path -> the count given for it on the command line or in the API."""
    position = {c.path: i for i, c in enumerate(scene.components)}
    chosen = {}
    for name, value in asked.items():
        if name == "*" or str(value).strip().lower() == "auto":
            problems.append(f"substeps: '{name}={value}': auto is for every component "
                            "(--substeps auto)")
            continue
        if name not in position:
            paths = list(position)
            problems.append(f"substeps: no component '{name}' (components: "
                            f"{', '.join(paths[:8])}{', ...' if len(paths) > 8 else ''})")
            continue
        count = whole_count(value)
        if count < 1:
            problems.append(f"substeps: '{name}={value}': give a whole number >= 1")
        elif position[name] in stepped:
            problems.append(f"substeps: component '{name}' {STEPPED}")
        else:
            chosen[name] = count
    return chosen


def choose_substeps(scene: Scene, asked, glued, iterated, specs, problems: list) -> tuple:
    """``specs`` with their substeps: those ``asked`` (component path -> a whole number
    >= 1, or ``"auto"``: every component exchanged once per step, from its FMU's
    DefaultExperiment stepSize) on top of the scene's ``glue:Substeps`` annotations,
    and, where a component takes several, whether its Real inputs get derivatives
    (:func:`input_derivatives`); what is wrong is appended to ``problems``."""
    if isinstance(asked, str):
        asked = {"*": asked}
    if asked and not isinstance(asked, dict):
        problems.append(f"substeps: give COMPONENT=N pairs or auto, not {asked!r}")
        asked = {}
    asked = dict(asked or {})
    stepped = set(glued) | set(iterated)
    chosen = {}
    every = asked.pop("*", None)
    if every is not None:
        if str(every).strip().lower() == "auto":
            chosen.update(_automatic(scene, stepped))
        else:
            asked["*"] = every  # said to be wrong below
    chosen.update(_annotated(scene, stepped, problems))
    chosen.update(_asked(scene, asked, stepped, problems))
    if not chosen:
        return specs
    return tuple(replace(spec, substeps=chosen.get(spec.name, 1),
                         input_derivatives=input_derivatives(spec, chosen.get(spec.name, 1)))
                 for spec in specs)


def input_derivatives(spec, substeps: int) -> bool:
    """Whether the component of ``spec``, taking ``substeps`` communication steps per
    macro step, gets its connected Real inputs extrapolated with their slope over
    them: more than one substep, an FMI 2.0 co-simulation FMU that declares
    canInterpolateInputs, and a connected continuous Real input."""
    if substeps < 2 or spec.interface != "CoSimulation" or \
            not spec.fmi_version.startswith("2"):
        return False
    description = describe(spec.path)
    if not getattr(description.coSimulation, "canInterpolateInputs", False):
        return False
    return bool(extrapolated_places(description.by_name, spec.writes))
