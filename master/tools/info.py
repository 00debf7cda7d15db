"""``dsim info``: what a scene is made of, as text, from the checked plan
(:func:`dsim.master.api.prepare`).

By default a summary that fits a screen whatever the scene's size: its span and
master settings, one line per distinct FMU file (FMI version, interface,
capabilities, how many components use it), one line per component up to
:data:`LISTED` (role, ports, what it records, how many of its variables a run may
set), the joints likewise, the connections and algebraic loops, and what can be set,
counted.  ``every`` (``dsim info --all``): each component in full, with the table of
every variable a run may set (name, type, unit, start, the scene's value, limits,
description).  Array entries past the size the scene gives a component's arrays are
left out of both (:func:`dsim.master.planning.parameters.array_size`)."""
from __future__ import annotations

import math
import numbers

from dsim.master.api import prepare
from dsim.master.planning.inputs import INPUT_COMPONENT
from dsim.master.planning.parameters import (JOINT_COEFFICIENTS, array_size, free_settable,
                                             joint_coefficients)
from dsim.master.reading.fmi_description import CO_SIMULATION, describe
from dsim.master.reading.input_tables import read_table
from dsim.master.reading.ssp import ssd_files
from dsim.master.running.fmi.integrator import solver_summary

#: how dsim info names an interface
INTERFACE_WORDS = {"CoSimulation": "co-simulation", "ModelExchange": "Model Exchange"}
#: components and joints the summary lists one per line; past these it counts them
LISTED = 12


def number_text(value) -> str:
    """A value as a person reads it: a float to 10 significant digits (``14.14``, not
    ``14.139999999999999``), a sequence of equal numbers as one, of different ones as
    ``[1e+06 2e+06]``, anything else as text."""
    if isinstance(value, (list, tuple)):
        texts = [number_text(v) for v in value]
        if not texts:
            return "[]"
        return texts[0] if len(set(texts)) == 1 else "[" + " ".join(texts) + "]"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, numbers.Integral):
        return str(value)
    if isinstance(value, numbers.Real):
        return format(float(value), ".10g") if math.isfinite(value) else str(value)
    return str(value)


def port_summary(ports: dict) -> str:
    """The ports a joint can glue (a force input on every dof), a node set's slots
    S[1] .. S[n] as one entry: ``P(x), port1[1..5](x y)``."""
    slots: dict[str, list[int]] = {}
    dofs_of: dict[str, str] = {}
    for port, dofs in ports.items():
        if not dofs or not all("f" in kinds for kinds in dofs.values()):
            continue  # outputs only (a probe): nothing to glue
        base, bracket, index = port.partition("[")
        key = base if bracket and index[:-1].isdigit() else port
        slots.setdefault(key, [])
        if key != port:
            slots[key].append(int(index[:-1]))
        dofs_of[key] = " ".join(sorted(dofs))
    return ", ".join(
        (f"{key}[{min(numbers)}..{max(numbers)}]" if numbers else key) + f"({dofs_of[key]})"
        for key, numbers in sorted(slots.items()))


def _short(value) -> str:
    text = "-" if value in (None, "") else number_text(value)
    return text if len(text) <= 16 else text[:13] + "..."


def settable_lines(plan, index: int, every: bool = False, shown: int = 12) -> list[str]:
    """``dsim info --all``'s table of what a run may set in component ``index`` of
    ``plan`` (name, type, unit, start, the scene's value, min..max, causality and
    variability, description); inputs the master writes itself (glued port forces,
    connected inputs) and array entries past the scene's size are left out, and
    past ``shown`` inputs the rest is counted unless ``every``."""
    spec = plan.specs[index]
    found = free_settable(plan, index)
    inputs = [v for v in found if v.causality == "input"]
    listed = [v for v in found if v.causality != "input"] + (
        inputs if every else inputs[:shown])
    if not listed:
        return ["can be set: nothing"]
    bound = plan.scene.component(spec.name).parameters
    width = max(len(v.name) for v in listed)
    units = max([4] + [len(v.unit or "-") for v in listed])
    lines = [f"can be set (--set {spec.name}.NAME=VALUE; start: the FMU's, scene: what the "
             "scene binds):",
             f"  {'name':<{width}}  {'type':<7} {'unit':<{units}}  causality/variability  values"]
    for v in listed:
        limits = f" [{v.min or '-inf'}, {v.max or 'inf'}]" if v.min or v.max else ""
        if v.items:
            limits = " {" + ", ".join(f"{name}={value}" for name, value in v.items) + "}"
        scene = f" scene {_short(bound[v.name][1])}" if v.name in bound else ""
        lines.append(f"  {v.name:<{width}}  {v.type:<7} {v.unit or '-':<{units}}  "
                     f"{v.causality}/{v.variability}  start {_short(v.start)}{scene}{limits}"
                     + (f"  ({v.description})" if v.description else ""))
    hidden = len(found) - len(listed)
    if hidden:
        lines.append(f"  ... {hidden} more inputs no joint or connection writes "
                     "(dsim info --all lists them)")
    return lines


def _flags(spec, description) -> str:
    """``FMI 2.0 co-simulation; state yes, serialize yes, variable step yes``; for a
    table component, its rows, columns and time span (docs/inputs.md)."""
    if spec.table is not None:
        times = spec.table.times
        return (f"a table of {len(times)} rows, {len(description.modelVariables)} columns, "
                f"t = {times[0]:g} .. {times[-1]:g} s (run by dsim, no FMU)")
    found = description.interface(spec.interface)
    flags = [f"state {'yes' if found.canGetAndSetFMUstate else 'NO'}",
             f"serialize {'yes' if found.canSerializeFMUstate else 'no'}"]
    if spec.interface == CO_SIMULATION:
        flags.append("variable step "
                     + ("yes" if found.canHandleVariableCommunicationStepSize else "no"))
    else:
        flags.append(f"integrated by dsim ({solver_summary(spec.solver)}); rollback "
                     + ("by FMU state" if found.canGetAndSetFMUstate
                        else "by its continuous states"))
    return (f"{description.modelName}, FMI {description.fmiVersion} "
            f"{INTERFACE_WORDS[spec.interface]}; {', '.join(flags)}")


def _substeps_note(spec) -> str:
    """``; 4 substeps per macro step, inputs extrapolated`` for a component that takes
    several (--substeps, glue:Substeps); "" for one that takes one."""
    if spec.substeps < 2:
        return ""
    return (f"; {spec.substeps} substeps per macro step, inputs "
            + ("extrapolated (input derivatives)" if spec.input_derivatives else "held"))


def _role(plan, index: int, brief: bool = False, glued_set=None) -> str:
    """How the master moves component ``index``: glued (iterated with rollback) or free
    (``glued_set``: the plan's glued indices as a set, for a caller asking of every
    component)."""
    glued = index in (plan.glued if glued_set is None else glued_set)
    if brief:
        return "glued" if glued else "free"
    if plan.coupling == "strong":
        return ("iterated: its connections solved at each step, with rollback" if glued
                else "free: one doStep per macro step, its inputs from the step's start "
                "(it cannot roll back)")
    return ("glued: iterated with rollback" if glued
            else "free: one doStep per macro step, never rolled back")


def _names(names: list[str], most: int = 6) -> str:
    return ", ".join(names[:most]) + (f", ... ({len(names)})" if len(names) > most else "")


def _joint_line(joint) -> str:
    """A joint: its sides, dofs, kind, measure, law coefficients (numbers)."""
    law = " ".join(f"{key}={number_text(getattr(joint, key))}"
                   for key in joint_coefficients(joint))
    return (f"{joint.name}: {'.'.join(joint.a)} -> {'.'.join(joint.b)} dofs "
            f"{' '.join(joint.dofs)}, {joint.kind}, {joint.measure}"
            + (f" {law}" if law else ""))


def _header(scene_file, ssd, checked) -> list[str]:
    """The scene's system structures, span, SSP version and master settings."""
    lines = []
    scene = checked.scene
    structures = ssd_files(scene_file)
    if len(structures) > 1:
        lines.append(f"system structures: {', '.join(structures)} (this is "
                     f"{ssd or 'SystemStructure.ssd'}; --ssd NAME reads another)")
    lines.append(f"scene {scene.name}: {scene.start_time:g} .. {scene.stop_time:g} s"
                 + ("" if scene.experiment else " (no DefaultExperiment: dsim's default span)"))
    lines.append(f"SSP version {scene.ssp_version or 'not declared'}")
    m = scene.master
    lines.append(
        f"master: {checked.coupling} coupling, step {m.step:g} s (from {scene.step_from}), "
        f"tolerance {m.tolerance:g} (relative {m.relative_tolerance:g}), maxIterations "
        f"{m.max_iterations}, predictor {m.predictor}, refresh {m.refresh} (after "
        f"{m.refresh_after}), start {m.start}, perturbation {m.perturbation:g}")
    return lines


def _connections(checked) -> list[str]:
    lines = [f"causal connections: {len(checked.scene.connections)}"
             + _connection_roles(checked)]
    for number, loop in enumerate(checked.loops, 1):
        lines.append(f"  algebraic loop {number}: {loop.label} (solved at each communication "
                     "point)")
    return lines


def scene_info(scene_file, ssd: str | None = None, every: bool = False,
               allow_outside=None, scenario=None, inputs=None,
               events: str = "point") -> list[str]:
    """The lines ``dsim info`` prints for ``scene_file`` (an .ssp archive, a scene folder
    or an .ssd file; ``ssd``: which system structure of it): a summary that fits a
    screen, or with ``every`` each component in full with every variable a run may
    set; ``allow_outside``: folders trusted besides the scene, as :func:`dsim.prepare`
    takes them; ``scenario``: a scenario file, whose events are listed at the end with
    the communication point each takes effect at (docs/scenarios.md); ``inputs``: an
    input table, summarised at the end (its columns, their ranges, its time span and
    the input each feeds: docs/inputs.md).  Raises InputError as a run would."""
    table = None if inputs is None else read_table(inputs)
    checked = prepare(scene_file, ssd=ssd, allow_outside=allow_outside, scenario=scenario,
                      events=events,
                      inputs=table)
    lines = _header(scene_file, ssd, checked)
    lines += _details(checked) if every else _summary(checked)
    if checked.scenario is not None:
        lines += checked.scenario.lines()
    if table is not None:
        lines += _input_lines(checked, table)
    return lines


def _input_lines(checked, table) -> list[str]:
    """The input table's summary, each column with the input it feeds (held or
    interpolated) and whether the run covers more than the table's span."""
    lines = table.lines()
    index = {spec.name: i for i, spec in enumerate(checked.specs)}
    source = checked.specs[index[INPUT_COMPONENT]]
    held = dict(zip(source.reads, source.table.held))
    feeds = {c.start[1]: ".".join(c.end) for c in checked.scene.connections
             if c.start[0] == INPUT_COMPONENT}
    for k, name in enumerate(table.names, start=1):
        lines[k] += (f" -> {feeds.get(name, '?')} "
                     f"({'held' if held.get(name) else 'interpolated'})")
    first, last = table.span
    scene = checked.scene
    if scene.start_time < first or scene.stop_time > last:
        lines.append(f"  the run ({scene.start_time:g} .. {scene.stop_time:g} s) holds the "
                     "first value before the table's span and the last after it")
    return lines


def _summary(checked) -> list[str]:
    """The one-screen summary: FMU files, components, joints, connections, counts."""
    scene = checked.scene
    say_lines: list[str] = []
    say = say_lines.append
    groups: dict = {}
    settable_counts = []
    sized = {}
    for index, component in enumerate(scene.components):
        spec = checked.specs[index]
        key = (str(component.source), spec.interface, solver_summary(spec.solver)
               if spec.interface != CO_SIMULATION else "")
        groups.setdefault(key, (component, spec, []))[2].append(component.path)
        settable_counts.append(len(free_settable(checked, index)))
        sizes = array_size(describe(component.source), component.parameters)
        if sizes is not None:
            sized.setdefault(sizes, []).append(component.path)
    say(f"FMUs ({len(groups)} file{'s' * (len(groups) != 1)} for {len(scene.components)} "
        f"component{'s' * (len(scene.components) != 1)}):")
    for (source, _, _), (component, spec, paths) in groups.items():
        say(f"  {component.source.name}: {_flags(spec, describe(component.source))} "
            f"({len(paths)}: {_names(paths)})")
    glued = len(checked.glued)
    say(f"components ({len(scene.components)}; {glued} glued, "
        f"{len(scene.components) - glued} free):")
    for index, component in enumerate(scene.components[:LISTED]):
        records = [name for path, name in checked.recorded if path == component.path]
        files = ", ".join(f"{name} = {component.parameters[name][1]}"
                          for name in component.files)
        placed = scene.placements.get(component.path)
        say(f"  {component.path}: {component.source.name}, {_role(checked, index, True)}; "
            f"ports: {port_summary(checked.ports[component.path]) or 'none'}; "
            f"records: {_names(records) or 'nothing'}; can be set: {settable_counts[index]}"
            + (f"; scene file: {files}" if files else "")
            + (f"; placed on Ray resource {placed} (--backend ray)" if placed else "")
            + _substeps_note(checked.specs[index]))
    if len(scene.components) > LISTED:
        say(f"  ... {len(scene.components) - LISTED} more components (dsim info --all "
            "lists every one)")
    say(f"joints ({len(scene.joints)}):")
    for joint in scene.joints[:LISTED]:
        say(f"  {_joint_line(joint)}")
    if len(scene.joints) > LISTED:
        say(f"  ... {len(scene.joints) - LISTED} more joints (dsim info --all lists every "
            "one)")
    say_lines += _connections(checked)
    coefficients = sum(len(joint_coefficients(j)) for j in scene.joints)
    names = [k for k in JOINT_COEFFICIENTS if any(k in joint_coefficients(j)
                                                  for j in scene.joints)]
    say(f"can be set: {sum(settable_counts)} variables of {len(scene.components)} "
        f"component{'s' * (len(scene.components) != 1)} (--set COMPONENT.NAME=VALUE), "
        f"{coefficients} joint law coefficient{'s' * (coefficients != 1)}"
        + (f" (--set JOINT.NAME=VALUE: {' '.join(names)})" if names else "")
        + "; dsim info --all lists them with type, unit, start and limits")
    for sizes, paths in sized.items():
        say(f"  {_names(paths)}: {sizes.text(paths[0] if len(paths) == 1 else 'COMPONENT')}")
    return say_lines


def _details(checked) -> list[str]:
    """``dsim info --all``: each component and joint in full."""
    scene = checked.scene
    lines: list[str] = []
    say = lines.append
    say(f"components ({len(scene.components)}):")
    glued = set(checked.glued)  # looked up per component: a set, not the plan's tuple
    records_of: dict[str, list[str]] = {}
    for path, name in checked.recorded:
        records_of.setdefault(path, []).append(name)
    for index, component in enumerate(scene.components):
        spec = checked.specs[index]
        say(f"  {component.path}: {component.source.name} "
            f"[{_flags(spec, describe(component.source))}]")
        say(f"      {_role(checked, index, glued_set=glued)}")
        if component.path in scene.placements:
            say(f"      placed on Ray resource {scene.placements[component.path]} "
                "(--backend ray)")
        say(f"      ports: {port_summary(checked.ports[component.path]) or 'none'}")
        for name, file in component.files.items():
            say(f"      scene file: {name} = {component.parameters[name][1]} "
                f"({file.stat().st_size} bytes)")
        records = records_of.get(component.path, [])
        say(f"      records: {', '.join(records) or 'nothing'}")
        sizes = array_size(describe(component.source), component.parameters)
        if sizes is not None:
            say(f"      {sizes.text(component.path)}")
        for line in settable_lines(checked, index, every=True):
            say(f"      {line}")
    say(f"joints ({len(scene.joints)}):")
    for joint in scene.joints:
        settable = joint_coefficients(joint)
        say(f"  {_joint_line(joint)}"
            + (f" (--set {joint.name}.{settable[0]}=VALUE: {' '.join(settable)})"
               if settable else ""))
        for key in settable:
            say(f"      {key}: {JOINT_COEFFICIENTS[key][1]}")
    lines += _connections(checked)
    return lines


def _connection_roles(plan) -> str:
    """How the connections move: exchanged once per step, or iterated (which)."""
    if not plan.scene.connections:
        return ""
    if plan.coupling != "strong":
        return " (exchanged once per step: values from the step's start, held)"
    iterated = {plan.specs[i].name for i in plan.glued}
    count = sum(1 for c in plan.scene.connections if c.end[0] in iterated)
    return (f" ({count} into iterated components, solved to convergence at each step; "
            f"{len(plan.scene.connections) - count} exchanged once per step)")
