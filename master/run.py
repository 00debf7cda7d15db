"""The execution: check a scene, instantiate its FMUs, run the time loop with
observers (CSV recorder, progress, statistics), and always clean up.

Time is ``start + n * step`` (no drift); the last step is shortened to land on
the stop time exactly.
"""
from __future__ import annotations

import math
import time as clock
from dataclasses import dataclass, replace
from pathlib import Path

from master.assembly import assemble
from master.backends.inprocess import InProcessBackend
from master.errors import InputError, SimulationError
from master.fmu import FmuSubsystem, can_save_state
from master.explicit import ExplicitGluing
from master.gluing import TTGluing
from master.ports import component_ports, joint_port_dofs, variables_by_name
from master.results import CsvRecorder, RunStatistics
from master.start import check_start, consistent_start_forces
from master.scene import Scene
from master.ssp import load_scene


@dataclass
class Plan:
    """A checked scene, ready to instantiate."""

    scene: Scene
    layout: object
    joint_states: object
    interfaces: dict
    records: dict
    connections: list
    sides: dict
    ports: dict

    @property
    def non_matching(self) -> bool:
        """Whether a joint glues node sets of different sizes (needs positions)."""
        return any(len(a) != len(b) for a, b in self.sides.values())


def _records(scene: Scene, problems: list) -> dict[str, list[str]]:
    """Outputs to record per component: its declared output connectors, else
    every Real output of its FMU that is not port kinematics."""
    result = {}
    for component in scene.components:
        if not component.source.is_file():
            continue
        variables = variables_by_name(component.source)
        declared = [n for n, kind in component.connectors if kind == "output"]
        for name in declared:
            if name not in variables:
                problems.append(f"{component.location}: connector '{name}' is not a "
                                f"variable of {component.source.name}")
        result[component.path] = [n for n in declared if n in variables] or [
            n for n, v in variables.items() if v.causality == "output" and v.type == "Real"
            and not n.split(".")[-1][:2] in ("u_", "v_", "a_")]
    return result


def _check_parameters(scene: Scene, problems: list) -> None:
    for component in scene.components:
        if not component.source.is_file():
            continue
        variables = variables_by_name(component.source)
        for name in component.parameters:
            variable = variables.get(name)
            if variable is None:
                problems.append(f"{component.location}: parameter '{name}' is not a "
                                f"variable of {component.source.name}")
            elif variable.causality not in ("parameter", "input"):
                problems.append(f"{component.location}: '{name}' is a "
                                f"{variable.causality}, not a parameter")


def _connections(scene: Scene, problems: list) -> list:
    """Causal connections as (start component, start vr, end component, end vr,
    factor, offset)."""
    result = []
    for connection in scene.connections:
        ends = []
        for (path, name), role in ((connection.start, "output"), (connection.end, "input")):
            component = scene.component(path)
            variable = variables_by_name(component.source).get(name) \
                if component.source.is_file() else None
            if variable is None:
                problems.append(f"{connection.location}: '{path}' has no variable '{name}'")
            elif role == "input" and variable.causality not in ("input", "parameter"):
                problems.append(f"{connection.location}: '{path}.{name}' is not an input")
            else:
                ends.append(variable.valueReference)
        if len(ends) == 2:
            result.append((connection.start[0], ends[0], connection.end[0], ends[1],
                           connection.factor, connection.offset))
    return result


def plan(scene: Scene) -> Plan:
    """Check everything that can be checked without instantiating an FMU."""
    problems: list[str] = []
    master = scene.master
    if not (master.step > 0 and math.isfinite(master.step)):
        problems.append(f"{scene.file}: glue:Master: step must be positive, got {master.step}")
    if not scene.stop_time > scene.start_time:
        problems.append(f"{scene.file}: DefaultExperiment: stopTime {scene.stop_time} is not "
                        f"after startTime {scene.start_time}")
    if master.max_iterations < 1 or master.refresh_after < 1:
        problems.append(f"{scene.file}: glue:Master: maxIterations and refreshAfter must be >= 1")
    ports = component_ports(scene, problems)
    _check_parameters(scene, problems)
    records = _records(scene, problems)
    connections = _connections(scene, problems)
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
            if not can_save_state(scene.component(path).source):
                problems.append(f"{joint.location}: component '{path}' cannot save and "
                                "restore its state (canGetAndSetFMUstate is false), so it "
                                "cannot be iterated")
    if problems:
        raise InputError(list(dict.fromkeys(problems)))
    paths = [c.path for c in scene.components]
    layout, joint_states, interfaces = assemble(paths, list(scene.joints), sides)
    return Plan(scene, layout, joint_states, interfaces, records, connections, sides, ports)


def _with_positions(checked: Plan, subsystems, kinematics) -> None:
    """Assemble non-matching joints from the glued dofs' initial positions."""
    positions = {}
    for subsystem, (u, _, _) in zip(subsystems, kinematics):
        for port_dof, value in zip(checked.interfaces[subsystem.name], u):
            positions[(subsystem.name, port_dof.port, port_dof.dof)] = value
    paths = [c.path for c in checked.scene.components]
    try:
        checked.layout, checked.joint_states, _ = assemble(
            paths, list(checked.scene.joints), checked.sides, positions)
    except ValueError as error:
        raise InputError(f"{checked.scene.file}: non-matching joint: {error}") from None


def step_times(start: float, stop: float, step: float) -> list[float]:
    """Communication points start + n*step, the last one clipped to stop."""
    count = max(1, math.ceil((stop - start) / step - 1e-9))
    return [min(start + n * step, stop) for n in range(count + 1)]


def run(path, out: Path, stop: float | None = None, step: float | None = None,
        tolerance: float | None = None, observers=(), **overrides):
    """Run the scene at ``path``; write ``out`` (CSV) and its stats JSON beside it.

    Returns the :class:`RunStatistics`.  Raises InputError before anything
    runs, SimulationError when the run fails (converged steps stay in ``out``).
    """
    scene = load_scene(path)
    settings = {k: v for k, v in dict(step=step, tolerance=tolerance, **overrides).items()
                if v is not None}
    if stop is not None:
        scene = replace(scene, stop_time=float(stop))
    scene = replace(scene, master=replace(scene.master, **settings))
    checked = plan(scene)
    return execute(checked, Path(out), observers)


def _instantiate(checked: Plan) -> list[FmuSubsystem]:
    scene = checked.scene
    subsystems = []
    try:
        for component in scene.components:
            subsystems.append(FmuSubsystem(
                component.path, component.source, checked.interfaces[component.path],
                component.parameters, checked.records[component.path],
                scene.start_time, scene.stop_time, location=component.location))
    except Exception:
        InProcessBackend(subsystems).close()
        raise
    return subsystems


def _transfer(connections, by_name) -> None:
    """Causal connections, Jacobi style: outputs at the step start feed inputs."""
    for start, start_vr, end, end_vr, factor, offset in connections:
        value = by_name[start].get_reals([start_vr])[0]
        by_name[end].set_reals([end_vr], [factor * value + offset])


def execute(checked: Plan, out: Path, observers=()) -> "RunStatistics":
    """Instantiate, run and record a checked scene (see :func:`run`)."""
    scene, master = checked.scene, checked.scene.master
    times = step_times(scene.start_time, scene.stop_time, master.step)
    statistics = RunStatistics(scene, times)
    wall_start = clock.perf_counter()
    subsystems = _instantiate(checked)
    backend = InProcessBackend(subsystems)
    start_forces = None
    try:
        if master.start == "consistent":
            if checked.non_matching:
                _with_positions(checked, subsystems, backend.kinematics())
            start_forces, reported = consistent_start_forces(backend, checked.layout,
                                                             checked.joint_states)
        backend.finish_initialization()
        if start_forces is not None:
            check_start(backend, reported)
        if checked.non_matching and master.start != "consistent":
            _with_positions(checked, subsystems, backend.kinematics())
    except (InputError, SimulationError):
        backend.close()
        raise
    by_name = {s.name: s for s in subsystems}
    coupling = ExplicitGluing if master.coupling == "explicit" else TTGluing
    gluing = coupling(backend, checked.layout, checked.joint_states, master)
    columns = [f"{s.name}.{n}" for s in subsystems for n in s.output_names]
    recorder = CsvRecorder(out, columns + checked.layout.labels)
    try:
        gluing.start(backend.kinematics(), start_forces)
        recorder.write(times[0], backend.outputs(), gluing.forces)
        statistics.setup_seconds = clock.perf_counter() - wall_start
        for observer in observers:
            observer.start(times)
        for index in range(1, len(times)):
            _transfer(checked.connections, by_name)
            t = times[index - 1]
            report = gluing.step(t, times[index] - t, index)
            statistics.add_step(report)
            recorder.write(times[index], backend.outputs(), gluing.forces)
            for observer in observers:
                observer.step(index, times[index], report)
    except SimulationError as error:
        statistics.failure = str(error)
        raise
    except KeyboardInterrupt:
        statistics.failure = "interrupted by the user"
        raise
    finally:
        recorder.close()
        for observer in observers:
            observer.finish()
        try:
            backend.close()
        finally:
            statistics.finish(clock.perf_counter() - wall_start, gluing, subsystems)
            statistics.write(out.with_suffix(".stats.json"))
    return statistics
