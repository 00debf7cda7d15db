"""Elastic bodies described by FMU-style parameters, behind a fixed port layout (no FMI).

FMI 2.0 fixes an FMU's variable list when the FMU is built, but a finite-element body's
node count depends on its mesh. :class:`SlotBody` reconciles the two: it exposes the
fixed *slots* ``S[1] .. S[MAX_NODES]`` (x, y) of every port name ``S`` in :data:`PORTS`
and maps the first ``n_S`` slots of port S onto the ``n_S`` nodes of the body's node set
``S``. ``n_S`` is the parameter ``S.nodes`` of the scene: the master glues exactly those
slots, and the body checks here that its node set really has ``n_S`` nodes. A port with
``S.nodes = 0`` is unused: it is not part of the body (it changes neither the physics nor a
Craig-Bampton basis), its forces are ignored and its kinematics read zero.

:class:`PartSpec` holds the parameters; :func:`build_body` makes the :class:`ElasticBody`:
- the five ladder-frame parts of SCENES.md (``rail_left`` ... ``cross_rear``,
  :mod:`.frame`), at any element size; cross members also offer the one-node port
  ``center`` at their mid point (x_mid, 0.6), where frame_nested hangs the plate;
- ``part = "mesh"``: the user's own 2-D mesh file (any format meshio reads), its node sets
  given by strings (:func:`node_set_spec`), optional clamps, a sine point load and a probe.
Units SI: m, s, kg, N, Pa.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from ..interface import InterfaceCore
from .assembly import Material
from .core import ElasticBody, PointLoad
from .geometry import in_box, load_mesh, rectangle, resolve_node_set
from . import frame

#: Port names of the fixed layout, the frame's and a spare for point ports.
PORTS = ("left", "right", "front", "mid", "rear", "center")
#: Node slots per port (an edge of 1 m at 0.025 m has 41 nodes).
MAX_NODES = 41
DOFS = ("x", "y")
FRAME_PARTS = frame.COMPONENTS
PART_NAMES = FRAME_PARTS + ("mesh",)
#: y of the cross members' mid points (the ``center`` port).
CENTER_Y = 0.5 * (frame.RAIL_Y["left"][1] + frame.RAIL_Y["right"][0])


@dataclass
class PartSpec:
    """Everything the FMU's parameters say about one body (defaults: the frame's steel)."""

    part: str = "cross_front"
    element_size: float = frame.ELEMENT_SIZE
    mass: str = "consistent"
    modes: int = 0  # 0: the full mesh; N > 0: Craig-Bampton with N fixed-interface modes
    mesh_file: str = ""
    thickness: float = frame.THICKNESS
    youngs_modulus: float = 210e9
    poisson_ratio: float = 0.3
    density: float = 7850.0
    nodes: dict = field(default_factory=lambda: {port: 0 for port in PORTS})
    sets: dict = field(default_factory=lambda: {port: "" for port in PORTS})
    clamped: str = ""
    load_point: tuple = (0.0, 0.0)
    load_amplitude: tuple = (0.0, 0.0)  # N, x and y
    load_frequency: float = 0.0  # Hz
    probe: bool = False  # part "mesh": probe ``load`` at load_point


def node_set_spec(text: str, extent: float):
    """A node set from a string: ``"box x0 y0 x1 y1"`` (nodes in the box),
    ``"point x y"`` (the node nearest the point) or the name of a boundary stored in the
    mesh file. Coordinates in m; box tolerance 1e-6 of the mesh extent."""
    words = text.split()
    if words and words[0] in ("box", "point"):
        try:
            numbers = [float(w) for w in words[1:]]
        except ValueError:
            numbers = []
        if words[0] == "box" and len(numbers) == 4:
            return in_box(numbers[:2], numbers[2:], tolerance=1e-6 * extent)
        if words[0] == "point" and len(numbers) == 2:
            point = np.array(numbers)[:, None]
            return lambda x: np.arange(x.shape[1]) == np.argmin(np.sum((x - point) ** 2, axis=0))
        raise ValueError(f"node set '{text}': expected 'box x0 y0 x1 y1' or 'point x y'")
    return text


def frame_geometry(part: str, element_size: float = frame.ELEMENT_SIZE):
    """Mesh, node sets and port names of ladder-frame part ``part`` (as in :mod:`.frame`;
    cross members add the one-node set ``center`` at their mid point)."""
    kind, side = part.split("_")
    if kind == "rail":
        y0, y1 = frame.RAIL_Y[side]
        return (rectangle(0.0, frame.LENGTH, y0, y1, element_size), frame._rail_sets(side),
                ("front", "mid", "rear"))
    x0, x1 = frame.CROSS_X[side]
    sets = frame._cross_sets(side)
    sets["center"] = node_set_spec(f"point {0.5 * (x0 + x1)} {CENTER_Y}", 1.0)
    mesh = rectangle(x0, x1, frame.RAIL_Y["left"][1], frame.RAIL_Y["right"][0], element_size)
    return mesh, sets, ("left", "right", "center")


def frame_port_nodes(part: str, element_size: float = frame.ELEMENT_SIZE) -> dict[str, int]:
    """Node count of every port of frame part ``part``: the values of ``S.nodes``."""
    mesh, sets, ports = frame_geometry(part, element_size)
    return {port: len(resolve_node_set(mesh, port, sets[port])) for port in ports}


def _frame_body(spec: PartSpec, ports: list[str], material: Material) -> ElasticBody:
    """One ladder-frame part as in :mod:`.frame`, with the ports asked for."""
    mesh, sets, offered = frame_geometry(spec.part, spec.element_size)
    missing = [p for p in ports if p not in offered]
    if missing:
        raise ValueError(f"part '{spec.part}' has no port '{missing[0]}' (its ports: "
                         f"{', '.join(offered)}); set {missing[0]}.nodes = 0")
    options = dict(thickness=spec.thickness, mass=spec.mass, modes=spec.modes or None,
                   name=spec.part, node_sets=sets, ports=ports)
    if spec.part.startswith("rail"):
        return ElasticBody(mesh, material, clamped=["clamped"], **options)
    front = spec.part == "cross_front"
    return ElasticBody(mesh, material, loads=[frame.LOAD] if front else [],
                       probes={"load": frame.LOAD_POINT} if front else {}, **options)


def _mesh_body(spec: PartSpec, ports: list[str], material: Material,
               resources: Optional[Path]) -> ElasticBody:
    """The user's mesh file (relative to the FMU's resources folder)."""
    if not spec.mesh_file:
        raise ValueError("part 'mesh' needs the parameter mesh_file (a file in the FMU's "
                         "resources folder)")
    path = Path(spec.mesh_file)
    if not path.is_absolute() and resources is not None:
        path = Path(resources) / path
    try:
        mesh = load_mesh(path)
    except ValueError as error:  # name the file as the scene does, not the unzip folder
        raise ValueError(str(error).replace(str(path), f"'{spec.mesh_file}'")) from None
    if mesh.dim() != 2:
        raise ValueError(f"mesh file {spec.mesh_file}: a {mesh.dim()}-D mesh, this FMU is 2-D")
    extent = float(np.ptp(mesh.p, axis=1).max()) or 1.0
    sets = {port: node_set_spec(spec.sets[port], extent) for port in ports}
    for port in ports:
        if not spec.sets[port]:
            raise ValueError(f"port '{port}' has {port}.nodes = {spec.nodes[port]} but no "
                             f"node set: set the parameter {port}.set")
    clamped = []
    if spec.clamped:
        sets["clamped"] = node_set_spec(spec.clamped, extent)
        clamped = ["clamped"]
    omega = 2.0 * np.pi * spec.load_frequency
    loads = [PointLoad(spec.load_point, dof, amplitude=amplitude, omega=omega)
             for dof, amplitude in zip(DOFS, spec.load_amplitude) if amplitude]
    return ElasticBody(mesh, material, thickness=spec.thickness, mass=spec.mass,
                       node_sets=sets, clamped=clamped, ports=ports, loads=loads,
                       probes={"load": spec.load_point} if spec.probe else {},
                       modes=spec.modes or None, name=Path(spec.mesh_file).name)


def build_body(spec: PartSpec, resources: Optional[Path] = None) -> ElasticBody:
    """The body ``spec`` describes, with the ports whose ``S.nodes`` is positive.

    Raises ValueError, one line naming the parameter, for anything inconsistent.
    """
    if spec.part not in PART_NAMES:
        raise ValueError(f"parameter part = '{spec.part}' must be one of {', '.join(PART_NAMES)}")
    if spec.part != "mesh" and spec.mesh_file:
        raise ValueError(f"mesh_file = '{spec.mesh_file}' needs part = 'mesh' "
                         f"(part is '{spec.part}')")
    if spec.modes < 0:
        raise ValueError(f"parameter modes = {spec.modes} must be >= 0")
    for port, count in spec.nodes.items():
        if not 0 <= count <= MAX_NODES:
            raise ValueError(f"parameter {port}.nodes = {count} must be 0 .. {MAX_NODES}")
    material = Material(spec.youngs_modulus, spec.poisson_ratio, spec.density)
    ports = [port for port in PORTS if spec.nodes[port] > 0]
    if spec.part == "mesh":
        body = _mesh_body(spec, ports, material, resources)
    else:
        body = _frame_body(spec, ports, material)
    for port in ports:
        count = len(body.node_sets[port])
        if count != spec.nodes[port]:
            raise ValueError(f"port '{port}': its node set has {count} nodes but the parameter "
                             f"{port}.nodes is {spec.nodes[port]}")
    return body


def slot_interface() -> tuple[tuple[str, str], ...]:
    """Every (port, dof) slot of the fixed layout: ``left[1]`` x, y ... ``center[41]`` y."""
    return tuple((f"{port}[{k}]", dof) for port in PORTS for k in range(1, MAX_NODES + 1)
                 for dof in DOFS)


class SlotBody(InterfaceCore):
    """An :class:`ElasticBody` seen through the fixed slot layout (see module docstring).

    Forces on slots the body does not have are ignored; their kinematics are zero.
    """

    interface = slot_interface()
    output_names = ("load.u_x", "load.u_y")

    def __init__(self, body: ElasticBody):
        self.body = body
        index = {pair: i for i, pair in enumerate(self.interface)}
        self._slots = np.array([index[pair] for pair in body.interface], dtype=int)
        self._forces = np.zeros(len(self.interface))
        self._pushed = False
        self.time = body.time

    def initialize(self, start_time: float) -> None:
        self._push()
        self.body.initialize(start_time)
        self.time = self.body.time

    def set_interface_forces(self, forces: np.ndarray) -> None:
        self._forces = np.array(forces, dtype=float)
        self._pushed = False

    def _push(self) -> None:
        if not self._pushed:
            self.body.set_interface_forces(self._forces[self._slots])
            self._pushed = True

    def step(self, time: float, step_size: float) -> None:
        self._push()
        self.body.step(time, step_size)
        self.time = self.body.time

    def interface_kinematics(self):
        return tuple(self.interface_kinematic(kind) for kind in range(3))

    def interface_kinematic(self, kind: int) -> np.ndarray:
        full = np.zeros(len(self.interface))
        full[self._slots] = self.body.interface_kinematic(kind)
        return full

    def get_state(self) -> dict:
        return {"body": self.body.get_state(), "forces": self._forces.copy()}

    def set_state(self, state: dict) -> None:
        self.body.set_state(state["body"])
        self._forces = state["forces"].copy()
        self._pushed = True  # the body's state holds its own forces

    def outputs(self) -> dict[str, float]:
        values = self.body.outputs()
        return {name: float(values.get(name, 0.0)) for name in self.output_names}
