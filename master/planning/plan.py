"""The checked plan of a run: everything that can be known and checked about a
scene and its settings before any FMU is instantiated.

:func:`make_plan` reads each FMU's modelDescription once, resolves ports and
joints, chooses the variables each component reads after every step (recorded
outputs and causal connection sources) and writes (causal inputs), resolves the
causal connections into index arrays, decides which components are glued (in a
joint: iterated with rollback) and which are free (one doStep per macro step),
and collects every problem into one :class:`~dsim.master.errors.InputError`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from dsim.master.errors import InputError
from dsim.master.planning.assembly import assemble
from dsim.master.planning.inputs import INPUT_COMPONENT
from dsim.master.planning.loops import find_loops
from dsim.master.planning.parameters import written_by_master
from dsim.master.planning.substeps import choose_substeps
from dsim.master.planning.tables import table_data, with_table_inputs
from dsim.master.reading.fmu_archive import fmu_problem
from dsim.master.reading.input_tables import is_table
from dsim.master.reading.fmi_description import (CO_SIMULATION, MODEL_EXCHANGE,
                                                can_roll_back, chosen_interface, describe,
                                                description_warning)
from dsim.master.reading.ports import NEEDED, component_ports, joint_port_dofs
from dsim.master.reading.ssp_values import TYPES
from dsim.master.reading.units import (column_display_units, column_units, conversion,
                                       fmu_units, joint_unit_problem, variable_unit)
from dsim.master.recording.selection import record_every, select_columns
from dsim.master.running.backends import BACKENDS
from dsim.master.running.connections import (Transfer, build_text_transfer, build_transfer,
                                             check_connections)
from dsim.master.running.fmi import SubsystemSpec
from dsim.master.running.fmi.integrator import solver_problem
from dsim.master.running.step_control import DEFAULT_TOLERANCE, StepControl
from dsim.master.running.timeline import is_whole, span_note
from dsim.master.scene import Scene
from dsim.master.settings import check_span

#: variable types a recorded column can carry
NUMERIC = ("Real", "Integer", "Enumeration", "Boolean")


@dataclass(frozen=True)
class Plan:
    """A checked scene, ready to run (immutable: every run makes its own state)."""

    scene: Scene
    coupling: str
    backend: str
    specs: tuple[SubsystemSpec, ...]
    #: recorded outputs as (component path, variable), and where each is in the
    #: run's flat output vector
    recorded: tuple[tuple[str, str], ...]
    record_index: np.ndarray
    transfer: Transfer
    #: indices of the components in a joint (the glued ones)
    glued: tuple[int, ...]
    sides: dict
    ports: dict
    #: every connection (fixed parameters too), carried at initialization in
    #: ``start_passes`` read-and-write passes (dependency order)
    start_transfer: Transfer = None
    start_passes: int = 0
    #: what the run should say before it starts (a default it assumed, for one)
    warnings: tuple[str, ...] = ()
    #: the explicit coupling glues a component that cannot save its state: the
    #: interface flexibility comes from the start accelerations (no rollback)
    flexibility_at_start: bool = False
    #: String outputs recorded (component, variable), where each is in the run's flat
    #: list of String values, and the String connections (applied at every step)
    text_recorded: tuple[tuple[str, str], ...] = ()
    text_index: tuple[int, ...] = ()
    text_transfer: object = None
    #: every glued FMU accepts a communication step other than the nominal one
    #: (canHandleVariableCommunicationStepSize): a failed macro step may be cut
    variable_steps: bool = False
    #: what the backend is given besides the specs (``address`` of a Ray cluster)
    backend_options: dict = None
    #: the recorded numeric columns (outputs, then joint forces) chosen by ``outputs``,
    #: as indices into the full row; None: every one (dsim.master.recording.selection)
    selected: np.ndarray | None = None
    #: rows are recorded every this many macro steps (``output_interval``), and at
    #: the last converged step
    record_every: int = 1
    #: what the run was asked to record (the statistics say it)
    outputs: tuple[str, ...] = ()
    output_interval: float | None = None
    #: the algebraic loops of the connections (:mod:`dsim.master.planning.loops`) and,
    #: for each, where its inputs are in ``transfer``'s flat values
    loops: tuple = ()
    loop_positions: tuple = ()
    #: the components whose connections the strong coupling iterates (they can roll
    #: back and take part in a connection moved every step)
    iterated: tuple[int, ...] = ()
    #: the unit of every numeric column (``time``, outputs, joint forces; '' where the
    #: FMU declares none), as the FMUs declare them
    units: dict = None
    #: the output columns whose FMU variable declares a display unit: column ->
    #: {"unit", "factor", "offset"} (plots show value * factor + offset in it)
    display_units: dict = None
    #: an error-controlled run's settings (``step="auto"``; the scene's step is then
    #: the output interval), or None: a fixed step
    step_control: StepControl | None = None
    #: the scenario's events resolved against this plan
    #: (:class:`~dsim.master.planning.scenario.ScenarioPlan`), or None: no scenario
    scenario: object = None
    #: the checkpoint a new run starts from (``--from``: a
    #: :class:`~dsim.master.reading.checkpoint_files.Checkpoint`; the scene's start time
    #: is its time), or None
    start_from: object = None
    #: values that run sets on top of the saved states: (component index, names,
    #: values) of the tunable parameters and inputs given anew
    start_values: tuple = ()

    @property
    def text_columns(self) -> tuple[str, ...]:
        """CSV columns of the recorded String outputs (after every numeric column)."""
        return tuple(f"{path}.{name}" for path, name in self.text_recorded)

    @property
    def columns(self) -> tuple[str, ...]:
        """CSV columns of the recorded outputs (``component.variable``)."""
        return tuple(f"{path}.{name}" for path, name in self.recorded)

    @property
    def read_names(self) -> tuple[str, ...]:
        """``component.variable`` of every value the run reads after a step (recorded
        outputs and connection sources), in the order of its flat outputs."""
        return tuple(f"{spec.name}.{name}" for spec in self.specs for name in spec.reads)

    @property
    def sources(self) -> np.ndarray:
        """Where in the flat outputs each value that a connection moves every step is,
        each once, in order."""
        return np.unique(self.transfer.gather) if self.transfer is not None else \
            np.zeros(0, int)

    @property
    def non_matching(self) -> bool:
        """Whether a joint glues node sets of different sizes (needs positions)."""
        return any(len(a) != len(b) for a, b in self.sides.values())

    def assemble(self, positions=None):
        """A fresh gluing layout and joint states (``positions``: initial positions
        of the glued dofs, needed by non-matching joints)."""
        paths = [spec.name for spec in self.specs]
        layout, joints, _ = assemble(paths, list(self.scene.joints), self.sides, positions)
        return layout, joints

    @property
    def inputs(self) -> list:
        """Files the run reads (a run must never write over one of them)."""
        files = [self.scene.file] + [spec.path for spec in self.specs]
        return files + list(self.scene.inputs)

    @property
    def input_table(self) -> dict | None:
        """``--input``'s table for the statistics: where it came from and, per input it
        feeds (``component.variable``), its column; None without one."""
        table = next((c for c in self.scene.components if c.path == INPUT_COMPONENT), None)
        if table is None:
            return None
        return {"table": table.location.removesuffix(" (--input)"),
                "fed": {".".join(c.end): c.start[1] for c in self.scene.connections
                        if c.start[0] == INPUT_COMPONENT}}


def _usable(scene: Scene, problems: list, warnings: list, chosen: dict,
            load_libraries: bool = True) -> dict:
    """component path -> its variables by name, for the components whose FMU can be
    used; every other component gets one problem line (``load_libraries``: also load
    each library in a child process, see :func:`dsim.master.reading.fmu_archive.fmu_problem`).
    ``chosen`` receives each usable component's interface (CoSimulation or
    ModelExchange: what the SSD's ``implementation`` asks for, else co-simulation
    where the FMU has it)."""
    usable = {}
    jointed = {path for joint in scene.joints for path in (joint.a[0], joint.b[0])}
    for component in scene.components:
        table = is_table(component.source)  # a table component, or --input's
        if not (table or component.source.is_file()):
            continue  # the reader has said so
        problem = fmu_problem(component.source, load_libraries)
        where = f"{component.location}: {'table' if table else 'FMU'} {component.source.name}"
        if problem:
            problems.append(f"{where}: {problem}")
            continue
        description = scene.descriptions.get(component.source) or describe(component.source)
        try:
            chosen[component.path] = chosen_interface(description, component.implementation)
        except ValueError as error:
            problems.append(f"{where}: {error}")
            continue
        why = _needs_rollback(scene.master, component.path in jointed)
        asked = component.implementation in (CO_SIMULATION, MODEL_EXCHANGE)
        if why and not asked and _model_exchange_rolls_back(
                component.source, chosen[component.path]):
            chosen[component.path] = MODEL_EXCHANGE
            warnings.append(f"{where}: cannot save its state in co-simulation "
                            f"(canGetAndSetFMUstate is false), and {why} takes steps back: "
                            "it runs through its Model Exchange interface, which dsim "
                            "integrates (implementation=\"CoSimulation\" on the component "
                            "keeps co-simulation)")
        usable[component.path] = description.by_name
        tolerated = description_warning(component.source)
        if tolerated:
            warnings.append(f"{where}: {tolerated}")
        binary = [name for name, kind in description.unsupported.items() if kind == "Binary"]
        if binary:
            warnings.append(f"{where}: {len(binary)} Binary variable(s) ({', '.join(binary[:3])}"
                            f"{', ...' if len(binary) > 3 else ''}) are neither recorded nor "
                            "connectable: dsim exchanges numbers and strings")
    return usable


def _records(scene: Scene, usable: dict) -> tuple[dict, dict]:
    """Outputs to record per component, numeric and String: its declared output
    connectors, else every output of its FMU that is not port kinematics."""
    numbers, texts = {}, {}
    for component in scene.components:
        variables = usable.get(component.path)
        if variables is None:
            continue
        if component.path == INPUT_COMPONENT:  # --input's columns: inputs, not recorded
            numbers[component.path], texts[component.path] = [], []
            continue
        declared = [c.name for c in component.connectors
                    if c.kind == "output" and c.name in variables]
        chosen = declared or [n for n, v in variables.items() if v.causality == "output"
                              and n.split(".")[-1][:2] not in ("u_", "v_", "a_")]
        numbers[component.path] = [n for n in chosen if variables[n].type in NUMERIC]
        texts[component.path] = [n for n in chosen if variables[n].type == "String"]
    return numbers, texts


def _check_connectors(scene: Scene, usable: dict, problems: list, warnings: list) -> None:
    """Every declared connector of a component is a variable of its FMU, of the same
    causality, type and (where both say one) unit dimension.  Connectors that name no
    variable and that no connection uses (Dymola declares ``_x_start``,
    ``fmi_StartTime``, ... beside the model's) change nothing: dropped, with one warning
    per component; a connection through one is refused where the connections are
    checked (one error for one cause).  A connector declared Real for an Integer
    variable, or Integer for a Real one, is read as the variable is, with a warning."""
    connected = {end for c in scene.connections for end in (c.start, c.end)}
    for component in scene.components:
        variables = usable.get(component.path)
        if variables is None:
            continue
        units = None
        dropped = [c.name for c in component.connectors if c.name not in variables
                   and (component.path, c.name) not in connected]
        if dropped:
            warnings.append(f"{component.location}: {len(dropped)} connector(s) name no "
                            f"variable of {component.source.name} and are connected to "
                            f"nothing: dropped ({', '.join(dropped[:3])}"
                            f"{', ...' if len(dropped) > 3 else ''})")
        for connector in component.connectors:
            where = f"{component.location}: connector '{connector.name}'"
            variable = variables.get(connector.name)
            if variable is None:
                continue  # dropped above, or refused with its connection
            if connector.kind and connector.kind != variable.causality:
                problems.append(f"{where} is declared {connector.kind}, but the FMU's "
                                f"variable is {variable.causality}")
            kind = TYPES.get(variable.type, variable.type)
            if connector.type and connector.type != kind:
                mismatch = (f"{where} is declared {connector.type}, but the FMU's "
                            f"variable is {variable.type}")
                if {connector.type, kind} == {"Real", "Integer"}:
                    warnings.append(f"{mismatch}: read as {variable.type}")
                else:
                    problems.append(mismatch)
            declared = variable_unit(variable)
            if connector.unit and declared and connector.unit != declared:
                units = units or {**fmu_units(component.source), **scene.units}
                known = (units.get(connector.unit), units.get(declared))
                try:
                    if None not in known:
                        conversion(*known)
                    warnings.append(f"{where} has unit '{connector.unit}', its FMU variable "
                                    f"'{declared}': connections convert from the "
                                    "connector's unit")
                except ValueError as error:
                    problems.append(f"{where}: its unit and the FMU variable's: {error}")


def _with_files(component, variables: dict) -> dict:
    """The component's parameter values with each scene file it names (a String
    ``resources/...``) given as the file's absolute path, and each enumeration item
    name (SSP 1.0 .ssv) as its item's value; names that are no variable of its FMU are
    left out (:func:`_check_parameters` warned about them)."""
    return {name: _item_value(value, variables[name]) for name, value in {
        **component.parameters,
        **{name: ("String", str(file)) for name, file in component.files.items()}}.items()
        if name in variables}


def _item_value(value: tuple, variable):
    """An enumeration value given by its item's name, as ("Integer", the item's
    value); any other value as it is (:func:`_check_parameters` refused unknown names)."""
    kind, given = value
    if kind != "Enumeration":
        return value
    return "Integer", dict(variable.items).get(given, 0)


def _check_parameters(scene: Scene, usable: dict, problems: list, warnings: list) -> None:
    """Every parameter value must reach a variable that FMI 2.0 lets a master set
    before initialization: variability not constant, and an input, a parameter or a
    variable with initial="exact" or "approx".  A value naming no variable is a
    warning (SSP ignores it; a set may carry values for other tools, such as CAD
    geometry): it is not applied."""
    for component in scene.components:
        variables = usable.get(component.path)
        if variables is None:
            continue
        for name in component.parameters:
            where = component.origins.get(name, component.location)
            variable = variables.get(name)
            if variable is None:
                warnings.append(f"{where}: parameter '{name}' is not a variable of component "
                                f"'{component.path}' ({component.source.name}): not applied")
                continue
            kind, value = component.parameters[name]
            if kind == "Enumeration" and value not in dict(variable.items):
                items = ", ".join(item for item, _ in variable.items) or "none: " + (
                    f"'{name}' is a {variable.type}, not an Enumeration")
                problems.append(f"{where}: parameter '{name}' = '{value}' is no item of "
                                f"'{component.path}.{name}' (its items: {items})")
            elif variable.variability == "constant" or not (
                    variable.causality in ("parameter", "input")
                    or variable.initial in ("exact", "approx")):
                problems.append(f"{where}: '{component.path}.{name}' is a "
                                f"{variable.variability} {variable.causality} with initial="
                                f"{variable.initial}: FMI 2.0 lets no master set it")


def _sides(scene: Scene, ports: dict, problems: list, chosen: dict) -> dict:
    sides = {}
    for joint in scene.joints:
        if joint.a[0] not in ports or joint.b[0] not in ports:
            continue
        a = joint_port_dofs(joint, "a", ports[joint.a[0]], problems)
        b = joint_port_dofs(joint, "b", ports[joint.b[0]], problems)
        if a and b and len(a) != len(b) and not set(joint.dofs) <= {"x", "y", "z"}:
            problems.append(f"{joint.location}: node sets of {len(a) // len(joint.dofs)} and "
                            f"{len(b) // len(joint.dofs)} nodes can be glued by moving least "
                            "squares on translations only (dofs x y z)")
        sides[joint.name] = (a, b)
        for path in (joint.a[0], joint.b[0]):
            if path in chosen and not can_roll_back(scene.component(path).source,
                                                    chosen[path]) and (
                    scene.master.coupling != "explicit"):
                problems.append(f"{joint.location}: component '{path}' cannot save and "
                                "restore its state (" + _why_no_rollback(
                                    scene.component(path).source, chosen[path])
                                + "), so it cannot be iterated in a joint: it can take part "
                                "through causal connections, or in a joint with the explicit "
                                "coupling (coupling='explicit', no rollback)")
    return sides


def _check_joint_units(scene: Scene, sides: dict, usable: dict, problems: list) -> None:
    """Both sides of every joint in one unit per exchanged quantity (a joint converts
    nothing): one line per joint that mixes units."""
    known: dict = {}
    for joint in scene.joints:
        if joint.name not in sides:
            continue
        for path in (joint.a[0], joint.b[0]):
            if path not in known:
                known[path] = {**fmu_units(scene.component(path).source), **scene.units}
        problem = joint_unit_problem(joint, *sides[joint.name], usable, known)
        if problem:
            problems.append(problem)


def _why_no_rollback(source, interface: str) -> str:
    """Why an FMU cannot go back to a saved state, in its FMI version's words."""
    description = describe(source)
    if description.major == 1:
        return "an FMI 1.0 co-simulation FMU: FMI 1.0 has no FMU state"
    return "canGetAndSetFMUstate is false"


def _capabilities(scene: Scene, usable: dict, problems: list, chosen: dict) -> None:
    """What an FMU's co-simulation capabilities forbid this run: a shortened last step
    for an FMU that needs a fixed one, two instances of an FMU that allows one."""
    step = scene.master.step
    uneven = not is_whole(scene.start_time, scene.stop_time, step)
    users: dict = {}
    for component in scene.components:
        if component.path not in usable:
            continue
        cs = describe(component.source).interface(chosen[component.path])
        if uneven and cs.kind == CO_SIMULATION and not \
                cs.canHandleVariableCommunicationStepSize:
            problems.append(f"{component.location}: FMU {component.source.name} needs a fixed "
                            "communication step (canHandleVariableCommunicationStepSize="
                            f"false), but {scene.start_time:g} .. {scene.stop_time:g} s is "
                            f"not a whole number of {step:g} s steps (the last would be "
                            "shorter)")
        if cs.canBeInstantiatedOnlyOncePerProcess:
            users.setdefault(cs.modelIdentifier, []).append(component)
    for identifier, components in users.items():
        if len(components) > 1:
            problems.append(f"{components[1].location}: FMU '{identifier}' can be instantiated "
                            "only once per process (canBeInstantiatedOnlyOncePerProcess), and "
                            f"{len(components)} components use it: "
                            f"{', '.join(c.path for c in components)}")


def _needs_rollback(master, jointed: bool) -> str:
    """What in the run takes a component's steps back (the strong coupling, an
    error-controlled step, an iterated joint, where ``jointed``), in words; '' when
    nothing does."""
    if master.adaptive:
        return "the error-controlled step (step auto)"
    if master.coupling == "strong":
        return "the strong coupling"
    if master.coupling != "explicit" and jointed:
        return "its joint's Newton iteration"
    return ""


def _model_exchange_rolls_back(source, interface: str) -> bool:
    """Whether a component chosen to run in co-simulation cannot go back to a saved
    state there, and its FMU offers Model Exchange (FMI 2.0 or 3.0), which can."""
    description = describe(source)
    return (interface == CO_SIMULATION and not can_roll_back(source, interface)
            and description.major >= 2 and description.interface(MODEL_EXCHANGE) is not None)


def _iterated(scene: Scene, links, chosen: dict) -> tuple[int, ...]:
    """The components whose connections the strong coupling iterates: those that can
    roll back and take part in a connection moved every step."""
    connected = {path for link in links if link.every_step
                 for path in (link.start[0], link.end[0])}
    return tuple(i for i, c in enumerate(scene.components) if c.path in connected
                 and can_roll_back(c.source, chosen[c.path]))


def _loop_positions(loops, paths: list[str], writes: dict) -> tuple:
    """For each loop, where its inputs are in the flat values of the every-step
    transfer (component by component, each in its ``writes`` order)."""
    offsets, position = {}, 0
    for path in paths:
        offsets[path] = position
        position += len(writes[path])
    return tuple(tuple(offsets[path] + writes[path].index(name) for path, name in loop.inputs)
                 for loop in loops)


def _start_without_loops(paths: list[str], loops, moves: dict, specs, links) -> tuple:
    """The specs, links and transfer of the initialization passes with the connections
    into the algebraic loops' inputs left out: passed around a loop, pass after pass,
    start values are a fixed-point iteration that may run far from the FMUs' start
    values (OMSimulator's equationPair: x1 from 4 to -7048
    in two passes, and Newton then finds the other root); left out, each loop input
    keeps its start value, its guess, until the loop solver solves the loop after
    initialization."""
    solved = {name for loop in loops for name in loop.inputs}
    kept = [link for link in links if link.end not in solved]
    transfer, writes = build_transfer(paths, moves["reads"],
                                      [link for link in kept if link.kind != "String"])
    specs = tuple(replace(spec, start_writes=tuple(writes[spec.name])) for spec in specs)
    return specs, kept, transfer


def takes_any_step(source, interface: str) -> bool:
    """Whether a component takes communication steps of any size (Model Exchange: the
    master integrates it, so always)."""
    found = describe(source).interface(interface)
    return found.kind != CO_SIMULATION or found.canHandleVariableCommunicationStepSize


def _kinds(scene: Scene) -> dict[str, tuple[bool, bool, bool]]:
    """component path -> the kinematic kinds (u, v, a) its joints read each iteration:
    a fixed joint its measure's; a flexible one all three (its law, or its integrated
    extension, starts from the ports' motion)."""
    result: dict[str, list[bool]] = {}
    for joint in scene.joints:
        wanted = [True] * 3 if joint.kind == "flexible" else [
            k in NEEDED[joint.measure] for k in ("u", "v", "a")]
        for path in (joint.a[0], joint.b[0]):
            current = result.setdefault(path, [False] * 3)
            result[path] = [x or y for x, y in zip(current, wanted)]
    return {path: tuple(flags) for path, flags in result.items()}


def _passes(paths: list[str], links) -> int:
    """How many read-and-write passes carry start values along every chain of
    connections: the longest chain of components (a cycle: every component once)."""
    feeds: dict[str, set] = {p: set() for p in paths}
    for link in links:
        if link.start[0] != link.end[0]:
            feeds[link.start[0]].add(link.end[0])
    depth, active = {}, set()

    def longest(node) -> int:
        if node in active:  # a cycle
            raise RecursionError
        if node not in depth:
            active.add(node)
            depth[node] = 1 + max((longest(n) for n in feeds[node]), default=0)
            active.discard(node)
        return depth[node]

    try:
        return max((longest(p) for p in paths), default=0) - 1
    except RecursionError:
        return len(paths)


def _step_control(scene: Scene, output_interval) -> tuple[Scene, StepControl | None]:
    """An error-controlled scene (``step="auto"``) with its step made the output
    interval (``output_interval``, default the scene's step: the grid every macro step
    lands on), and what it asks of the controller; a fixed-step scene as it is."""
    master = scene.master
    if not master.adaptive:
        return scene, None
    interval = master.step
    if output_interval is not None:
        try:
            interval = float(output_interval)
        except (TypeError, ValueError):
            return scene, None  # record_every says what is wrong with it
        if not (math.isfinite(interval) and interval > 0):
            return scene, None
    control = StepControl(tolerance=master.error_tolerance or DEFAULT_TOLERANCE,
                          min_step=master.min_step, max_step=master.max_step,
                          first_step=min(master.step, interval))
    return replace(scene, master=replace(master, step=interval)), control


def _step_control_problems(scene: Scene, backend: str, chosen: dict, problems: list) -> None:
    """What an error-controlled run cannot do with this scene: a backend that keeps no
    snapshots, an FMU that cannot go back to a saved state or take steps of any size,
    a smallest step longer than the output interval."""
    master = scene.master
    if not master.adaptive:
        return
    if not BACKENDS[backend].snapshots:
        problems.append(f"{scene.file}: step auto (an error-controlled step) cannot run on "
                        f"the {backend} backend: it keeps no snapshot of its FMUs' states")
    if master.min_step is not None and master.min_step > master.step:
        problems.append(f"{scene.file}: min_step {master.min_step:g} s is longer than the "
                        f"output interval {master.step:g} s that every step lands on")
    for component in scene.components:
        path = component.path
        if path not in chosen:
            continue
        if not can_roll_back(component.source, chosen[path]):
            problems.append(f"{component.location}: component '{path}' cannot save and "
                            "restore its state (" + _why_no_rollback(component.source,
                                                                     chosen[path])
                            + "), so an error-controlled step (step auto) cannot take its "
                            "steps again: give a fixed step (--step)")
        elif not takes_any_step(component.source, chosen[path]):
            problems.append(f"{component.location}: component '{path}' takes only a fixed "
                            "communication step (canHandleVariableCommunicationStepSize="
                            "false), so an error-controlled step (step auto) cannot size "
                            "its steps: give a fixed step (--step)")


def _checked(scene: Scene, backend: str, backend_options: dict, load_libraries: bool,
             strict: bool, output_interval) -> dict:
    """Every check that needs no FMU instance; what the plan is built from (usable
    variables, interfaces, ports, records, links, joint sides, warnings, record
    interval).  InputError listing every problem."""
    problems = list(scene.problems) + check_span(
        scene.start_time, scene.stop_time, scene.master.step, f"{scene.file}: DefaultExperiment")
    problems += BACKENDS[backend].problems(**backend_options)
    every, problem = record_every(output_interval, scene.master.step)
    if problem:
        problems.append(problem)
    if scene.joints and scene.master.coupling == "causal":
        problems.append(f"{scene.file}: coupling 'causal' cannot glue the scene's "
                        f"{len(scene.joints)} joints: use iterative or explicit")
    warnings = list(scene.warnings)
    chosen: dict = {}
    usable = _usable(scene, problems, warnings, chosen, load_libraries)
    ports = component_ports(scene, problems, usable)
    _check_connectors(scene, usable, problems, warnings)
    _check_parameters(scene, usable, problems, warnings)
    _capabilities(scene, usable, problems, chosen)
    _step_control_problems(scene, backend, chosen, problems)
    for component in scene.components:
        problems += [f"{component.location}: {problem}" for problem in
                     (solver_problem(name, value) for name, value in component.solver) if problem]
    records, text_records = _records(scene, usable)
    links = check_connections(scene, usable, problems, warnings)
    _fed_once(scene, links, problems)
    sides = _sides(scene, ports, problems, chosen)
    _glued_forces_unfed(scene, links, sides, usable, problems)
    _check_joint_units(scene, sides, usable, problems)
    uneven = span_note(scene.start_time, scene.stop_time, scene.master.step)
    if uneven:  # the run's summary would say "step 20 s" of a run that took 10 s
        warnings.append(f"{scene.file}: {uneven}")
    if not scene.components and not problems:
        # (a parameter setup exported alone: connectors, .ssv and .ssm, nothing to run)
        warnings.append(f"{scene.file}: the scene has no FMU component: a run records "
                        "only its time column")
    if not scene.experiment:
        warnings.append(f"{scene.file}: no DefaultExperiment: the run goes from "
                        f"{scene.start_time:g} to {scene.stop_time:g} s (dsim's default; "
                        "--stop sets the stop time)")
    warnings = list(dict.fromkeys(warnings))
    if strict:
        problems += [f"{warning} (a warning; refused with --strict)" for warning in warnings]
        warnings = []
    _refuse(problems, warnings)
    return dict(usable=usable, chosen=chosen, ports=ports, records=records,
                text_records=text_records, links=links, sides=sides, warnings=warnings,
                every=every)


def _glued_forces_unfed(scene: Scene, links, sides: dict, usable: dict,
                        problems: list) -> None:
    """No connection (nor an input table's column) may feed a glued port's force: its
    joint sets it every step.  The forces are the joints' own port dofs, so a port map's
    force variables and a node set's members count as the conventional names do."""
    forces = {(dof.component, dof.force) for a_dofs, b_dofs in sides.values()
              for dof in (*a_dofs, *b_dofs)}
    by_end = {c.end: c for c in scene.connections}
    for link in links:
        variable = usable.get(link.end[0], {}).get(link.end[1])
        if variable is None or variable.type != "Real" or \
                (link.end[0], variable.valueReference) not in forces:
            continue
        connection = by_end.get(link.end)
        where = connection.location if connection is not None else scene.file
        problems.append(f"{where}: '{'.'.join(link.end)}' is a glued port's force: its "
                        "joint sets it every step, no connection or input table may feed it")


def _fed_once(scene: Scene, links, problems: list) -> None:
    """No input may be fed by two connections."""
    fed: dict = {}
    for link in links:
        if link.end in fed:
            problems.append(f"{scene.file}: '{'.'.join(link.end)}' is fed twice, by "
                            f"'{'.'.join(fed[link.end])}' and '{'.'.join(link.start)}'")
        fed[link.end] = link.start


def _refuse(problems: list, warnings: list) -> None:
    """Raise the problems found so far as one InputError (with the warnings)."""
    if problems:
        error = InputError(list(dict.fromkeys(problems)))
        error.warnings = warnings
        raise error


def _moves(paths: list[str], links, records: dict, text_records: dict) -> dict:
    """What each component reads after every step (its records, then the sources of
    its outgoing connections) and the transfers that move the connections' values:
    every step, at initialization (fixed parameters too), and String values."""
    numbers = [link for link in links if link.kind != "String"]
    texts = [link for link in links if link.kind == "String"]
    reads = {p: list(records[p]) for p in paths}
    text_reads = {p: list(text_records[p]) for p in paths}
    for link in links:
        read = text_reads if link.kind == "String" else reads
        if link.start[1] not in read[link.start[0]]:
            read[link.start[0]].append(link.start[1])
    transfer, writes = build_transfer(paths, reads, [link for link in numbers
                                                     if link.every_step])
    start_transfer, start_writes = build_transfer(paths, reads, numbers)
    text_transfer, text_writes = build_text_transfer(paths, text_reads, texts)
    return dict(numbers=numbers, reads=reads, text_reads=text_reads, transfer=transfer,
                writes=writes, start_transfer=start_transfer, start_writes=start_writes,
                text_transfer=text_transfer, text_writes=text_writes)


def _specs(scene: Scene, interfaces: dict, checked: dict, moves: dict,
           problems: list) -> tuple:
    """The picklable spec of every component's subsystem (a table component's with its
    data: :func:`~dsim.master.planning.tables.table_data`)."""
    kinds = _kinds(scene)
    tables = {c.path: table_data(c, moves["reads"][c.path], moves["numbers"],
                                 checked["usable"], problems)
              for c in scene.components if is_table(c.source)}
    return tuple(SubsystemSpec(
        name=c.path, path=c.source, port_dofs=tuple(interfaces[c.path]),
        parameters=_with_files(c, checked["usable"][c.path]),
        reads=tuple(moves["reads"][c.path]), writes=tuple(moves["writes"][c.path]),
        start_time=scene.start_time, stop_time=scene.stop_time, location=c.location,
        kinds=kinds.get(c.path, (False, False, False)),
        start_writes=tuple(moves["start_writes"][c.path]),
        text_reads=tuple(moves["text_reads"][c.path]),
        text_writes=tuple(moves["text_writes"][c.path]),
        placement=scene.placements.get(c.path, ""), files=tuple(c.files),
        interface=checked["chosen"][c.path],
        fmi_version=(scene.descriptions.get(c.source) or describe(c.source)).fmiVersion,
        solver=c.solver, table=tables.get(c.path)) for c in scene.components)


def _recorded(paths: list[str], reads: dict, records: dict) -> tuple[list, list]:
    """The recorded (component, variable) pairs and where each is in the flat outputs."""
    recorded, index, offset = [], [], 0
    for path in paths:
        for i, name in enumerate(reads[path]):
            if name in records[path]:
                recorded.append((path, name))
                index.append(offset + i)
        offset += len(reads[path])
    return recorded, index


def _coupled(scene: Scene, glued: tuple, numbers, chosen: dict, warnings: list):
    """The coupling that runs, the glued subsystems and, for the strong coupling, the
    ones whose connections it iterates (saying which connected ones cannot roll back)."""
    coupling = scene.master.coupling
    if coupling != "strong":
        return (coupling if scene.joints else "causal"), glued, ()
    iterated = _iterated(scene, numbers, chosen)
    connected = {p for link in numbers if link.every_step for p in (link.start[0],
                                                                      link.end[0])}
    exchanged = [c.path for i, c in enumerate(scene.components)
                 if c.path in connected and i not in iterated and i not in glued]
    if exchanged:
        warnings.append(f"{scene.file}: coupling 'strong': {', '.join(exchanged[:5])}"
                        f"{', ...' if len(exchanged) > 5 else ''} cannot roll back: "
                        "their connections' values are exchanged once per step")
    return coupling, (glued if scene.joints else iterated), iterated


def make_plan(scene: Scene, backend: str = "in-process", backend_options=None,
              load_libraries: bool = True, strict: bool = False, outputs=None,
              output_interval=None, substeps=None) -> Plan:
    """Check everything that can be checked without instantiating an FMU; raise
    InputError listing every problem.  ``load_libraries=False``: no FMU library is
    loaded, not even in a child process (its bytes are checked).  ``strict``: every
    warning is a problem too.  ``outputs``, ``output_interval``: what to record
    (:mod:`dsim.master.recording.selection`); ``substeps``: communication steps per
    macro step of components exchanged once per step
    (:func:`~dsim.master.planning.substeps.choose_substeps`)."""
    backend_options = {k: v for k, v in (backend_options or {}).items() if v is not None}
    scene, step_control = _step_control(scene, output_interval)
    checked = _checked(scene, backend, backend_options, load_libraries, strict,
                       output_interval)
    chosen, warnings = checked["chosen"], checked["warnings"]
    paths = [c.path for c in scene.components]
    layout, _, interfaces = assemble(paths, list(scene.joints), checked["sides"])
    moves = _moves(paths, checked["links"], checked["records"], checked["text_records"])
    recorded, record_index = _recorded(paths, moves["reads"], checked["records"])
    problems = []
    specs = _specs(scene, interfaces, checked, moves, problems)
    text_reads, text_records = moves["text_reads"], checked["text_records"]
    text_recorded = tuple((p, n) for p in paths for n in text_reads[p] if n in text_records[p])
    text_offsets, offset = {}, 0
    for path in paths:
        text_offsets[path] = offset
        offset += len(text_reads[path])
    text_index = [text_offsets[p] + text_reads[p].index(n) for p, n in text_recorded]
    columns = [f"{path}.{name}" for path, name in recorded] + list(layout.labels)
    selected, text_selected, selection_problems = select_columns(
        outputs, columns, [f"{path}.{name}" for path, name in text_recorded])
    problems += selection_problems
    problems += written_by_master(scene, specs, checked["usable"])
    _refuse(problems, warnings)
    if text_selected is not None:
        text_recorded = tuple(text_recorded[i] for i in text_selected)
        text_index = [text_index[i] for i in text_selected]
    joined = tuple(i for i, c in enumerate(scene.components) if interfaces[c.path])
    coupling, glued, iterated = _coupled(scene, joined, moves["numbers"], chosen, warnings)
    problems = []
    if strict:  # the coupling's own warnings (those of the checks are refused already)
        problems += [f"{warning} (a warning; refused with --strict)" for warning in warnings]
        warnings = []
    specs = choose_substeps(scene, substeps, glued, iterated if coupling == "strong" else (),
                            specs, problems)
    _refuse(problems, warnings)
    specs = with_table_inputs(scene, specs, moves["numbers"], chosen, coupling)
    loops = find_loops(scene, moves["numbers"], chosen)
    start_links, start_transfer = checked["links"], moves["start_transfer"]
    if loops:
        specs, start_links, start_transfer = _start_without_loops(paths, loops, moves, specs,
                                                                  start_links)
    components = scene.components
    return Plan(
        scene=scene, coupling=coupling, backend=backend, specs=specs,
        recorded=tuple(recorded), record_index=np.array(record_index, dtype=int),
        transfer=moves["transfer"], glued=glued, sides=checked["sides"],
        ports=checked["ports"], start_transfer=start_transfer,
        start_passes=_passes(paths, start_links), warnings=tuple(warnings),
        flexibility_at_start=bool(scene.joints) and coupling == "explicit" and any(
            not can_roll_back(components[i].source, chosen[components[i].path])
            for i in glued),
        text_recorded=text_recorded, text_index=tuple(text_index),
        text_transfer=moves["text_transfer"],
        variable_steps=all(takes_any_step(components[i].source, chosen[components[i].path])
                           for i in glued),
        backend_options=backend_options, selected=selected, record_every=checked["every"],
        outputs=tuple([outputs] if isinstance(outputs, str) else outputs or ()),
        output_interval=None if output_interval is None else float(output_interval),
        loops=loops, loop_positions=_loop_positions(loops, paths, moves["writes"]),
        iterated=iterated, step_control=step_control,
        units=column_units(checked["usable"], recorded, layout.labels,
                                              layout.joint_of, checked["sides"]),
        display_units=column_display_units(checked["usable"], recorded,
                                           {c.path: c.source for c in components}))
