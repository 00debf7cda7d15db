"""``dsim info``: what a scene is made of, as text: its span and master settings, each
component (FMU, capabilities, whether it is glued, ports, scene files, what it records,
what a run may set) and each joint, from the checked plan
(:func:`dsim.master.api.prepare`)."""
from __future__ import annotations

from dsim.master.api import prepare
from dsim.master.planning.parameters import free_settable, joint_coefficients
from dsim.master.reading.fmi_description import CO_SIMULATION, describe
from dsim.master.running.fmi.integrator import solver_summary

#: how dsim info names an interface
INTERFACE_WORDS = {"CoSimulation": "co-simulation", "ModelExchange": "Model Exchange"}
from dsim.master.reading.ssp import ssd_files


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


def settable_lines(plan, index: int, every: bool = False, shown: int = 12) -> list[str]:
    """``dsim info``'s table of what a run may set in component ``index`` of ``plan``
    (name, type, unit, start, min..max, causality and variability, description);
    inputs the master writes itself (glued port forces, connected inputs) are left
    out, and past ``shown`` inputs the rest is counted unless ``every``."""
    spec = plan.specs[index]
    found = free_settable(plan, index)
    inputs = [v for v in found if v.causality == "input"]
    listed = [v for v in found if v.causality != "input"] + (
        inputs if every else inputs[:shown])
    if not listed:
        return ["can be set: nothing"]
    bound = plan.scene.component(spec.name).parameters
    width = max(len(v.name) for v in listed)

    def short(value) -> str:
        text = "-" if value in (None, "") else str(value)
        return text if len(text) <= 16 else text[:13] + "..."

    lines = [f"can be set (--set {spec.name}.NAME=VALUE; start: the FMU's, scene: what the "
             "scene binds):"]
    for v in listed:
        limits = f" [{v.min or '-inf'}, {v.max or 'inf'}]" if v.min or v.max else ""
        if v.items:
            limits = " {" + ", ".join(f"{name}={value}" for name, value in v.items) + "}"
        scene = f" scene {short(bound[v.name][1])}" if v.name in bound else ""
        lines.append(f"  {v.name:<{width}}  {v.type:<7} {v.unit or '-':<6} "
                     f"{v.causality}/{v.variability}  start {short(v.start)}{scene}{limits}"
                     + (f"  ({v.description})" if v.description else ""))
    if len(inputs) > len(listed) - (len(found) - len(inputs)):
        hidden = len(inputs) - (len(listed) - (len(found) - len(inputs)))
        lines.append(f"  ... {hidden} more inputs no joint or connection writes "
                     "(dsim info --all lists them)")
    return lines


def scene_info(scene_file, ssd: str | None = None, every: bool = False) -> list[str]:
    """The lines ``dsim info`` prints for ``scene_file`` (an .ssp archive, a scene folder
    or an .ssd file; ``ssd``: which system structure of it; ``every``: list every input
    a run may set).  Raises InputError as a run would."""
    lines: list[str] = []
    say = lines.append
    checked = prepare(scene_file, ssd=ssd)
    scene = checked.scene
    structures = ssd_files(scene_file)
    if len(structures) > 1:
        say(f"system structures: {', '.join(structures)} (this is "
            f"{ssd or 'SystemStructure.ssd'}; --ssd NAME reads another)")
    say(f"scene {scene.name}: {scene.start_time:g} .. {scene.stop_time:g} s"
        + ("" if scene.experiment else " (no DefaultExperiment: dsim's default span)"))
    say(f"SSP version {scene.ssp_version or 'not declared'}")
    m = scene.master
    say(f"master: {checked.coupling} coupling, step {m.step:g} s (from {scene.step_from}), "
        f"tolerance {m.tolerance:g} (relative {m.relative_tolerance:g}), maxIterations "
        f"{m.max_iterations}, predictor {m.predictor}, refresh {m.refresh} (after "
        f"{m.refresh_after}), start {m.start}, perturbation {m.perturbation:g}")
    say(f"components ({len(scene.components)}):")
    glued = set(checked.glued)  # looked up per component: a set, not the plan's tuple
    records_of: dict[str, list[str]] = {}
    for path, name in checked.recorded:
        records_of.setdefault(path, []).append(name)
    for index, component in enumerate(scene.components):
        description = describe(component.source)
        spec = checked.specs[index]
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
        role = ("glued: iterated with rollback" if index in glued
                else "free: one doStep per macro step, never rolled back")
        if checked.coupling == "strong":
            role = ("iterated: its connections solved at each step, with rollback"
                    if index in glued else "free: one doStep per macro step, its "
                    "inputs from the step's start (it cannot roll back)")
        port_text = port_summary(checked.ports[component.path])
        say(f"  {component.path}: {component.source.name} "
            f"[{description.modelName}, FMI {description.fmiVersion} "
            f"{INTERFACE_WORDS[spec.interface]}; {', '.join(flags)}]")
        say(f"      {role}")
        if component.path in scene.placements:
            say(f"      placed on Ray resource {scene.placements[component.path]} "
                "(--backend ray)")
        say(f"      ports: {port_text or 'none'}")
        for name, file in component.files.items():
            say(f"      scene file: {name} = {component.parameters[name][1]} "
                f"({file.stat().st_size} bytes)")
        records = records_of.get(component.path, [])
        say(f"      records: {', '.join(records) or 'nothing'}")
        for line in settable_lines(checked, index, every):
            say(f"      {line}")
    say(f"joints ({len(scene.joints)}):")
    for joint in scene.joints:
        law = ""
        if joint.kind == "flexible":
            law = f" k0={joint.k0} k1={joint.k1} c0={joint.c0} c1={joint.c1}"
        if joint.measure == "penalized":
            law += f" xi={joint.xi} omega={joint.omega}"
        settable = joint_coefficients(joint)
        say(f"  {joint.name}: {'.'.join(joint.a)} -> {'.'.join(joint.b)} dofs "
            f"{' '.join(joint.dofs)}, {joint.kind}, {joint.measure}{law}"
            + (f" (--set {joint.name}.{settable[0]}=VALUE: {' '.join(settable)})"
               if settable else ""))
    say(f"causal connections: {len(scene.connections)}" + _connection_roles(checked))
    for number, loop in enumerate(checked.loops, 1):
        say(f"  algebraic loop {number}: {loop.label} (solved at each communication point)")
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
