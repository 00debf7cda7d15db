"""An elastic body described by data: a mesh file and FMU-style parameters (no FMI here).

:class:`BodySpec` holds what the generic ``ElasticBody`` FMU's parameters say: the mesh
file (any format meshio reads, linear tri/quad/tet/hex), element order, material,
thickness (2-D), mass, Rayleigh damping, fidelity (full, Craig-Bampton, rigid), clamps,
ports, a sine point load and probes. :func:`build_body` makes the
:class:`~dsim.fmus.elastic.core.ElasticBody`; :class:`SlotBody` shows it through the fixed
variable layout an FMU needs (FMI 2.0 fixes the variable list at build time, a mesh
decides how many nodes a port has):

- node-set ports ``port1`` .. ``port4``: slots ``portK[1]`` .. ``portK[41]``, dofs x y z
  (2-D bodies: x y); the Integer parameter ``portK.nodes`` says how many slots the scene
  glues and must equal the size of the node set ``portK.set``;
- rigid ports ``rigid1`` .. ``rigid4``: a node set following one reference point
  (``rigidK.point``, default the set's centroid), dofs x y z rx ry rz (2-D: x y rz);
- a point load ``load.F0_c + load.F_c sin(2 pi load_frequency t)`` (N) at ``load.point``;
- probes ``probe1`` .. ``probe4`` at ``probeK.point`` and ``load`` at the load point
  (``load.probe = 1``): outputs ``probeK.u_x`` ... (m, interpolated in the element).

Node sets are strings (:func:`node_set_spec`): ``box x0 y0 x1 y1`` (3-D: ``box x0 y0 z0
x1 y1 z1``), ``point x y [z]`` (the nearest node), or the name of a boundary stored in the
mesh file; ``;`` joins several into one set. Units SI: m, s, kg, N, Pa, Hz.

Without a mesh file (``mesh_file`` empty, the FMU's default) the body is a built-in
beam, ``DEFAULT_BEAM``, so that the FMU simulates alone in any FMI tool.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional
from urllib.parse import unquote, urlparse

import numpy as np

from ..interface import InterfaceCore
from .assembly import Material
from .core import ElasticBody, PointLoad
from .geometry import in_box, load_mesh, rectangle

NODE_PORTS = ("port1", "port2", "port3", "port4")
#: Node slots per node-set port (an edge of 1 m at 0.025 m has 41 nodes).
MAX_NODES = 41
RIGID_PORTS = ("rigid1", "rigid2", "rigid3", "rigid4")
PROBES = ("probe1", "probe2", "probe3", "probe4")
DOFS = ("x", "y", "z")
RIGID_DOFS = ("x", "y", "z", "rx", "ry", "rz")
FIDELITIES = ("full", "craig_bampton", "rigid")
#: The body of an empty ``mesh_file``: a 1 m x 0.1 m plane-stress beam of 20 x 2 bilinear
#: quadrilaterals (arguments of :func:`~dsim.fmus.elastic.geometry.rectangle`, m)
DEFAULT_BEAM = dict(x0=0.0, x1=1.0, y0=0.0, y1=0.1, element_size=0.05)


@dataclass
class BodySpec:
    """Everything the FMU's parameters say about one body (defaults: steel, full FE)."""

    mesh_file: str = ""
    order: int = 1  # 1: linear elements; 2: quadratic (mid-side nodes added)
    thickness: float = 0.01  # m, 2-D (plane stress) only
    youngs_modulus: float = 210e9
    poisson_ratio: float = 0.3
    density: float = 7850.0
    mass: str = "consistent"
    rayleigh_alpha: float = 0.0  # 1/s: C = alpha M + beta K
    rayleigh_beta: float = 0.0  # s
    fidelity: str = "full"
    modes: int = 0  # Craig-Bampton fixed-interface modes (fidelity craig_bampton)
    clamped: str = ""
    nodes: dict = field(default_factory=lambda: {port: 0 for port in NODE_PORTS})
    sets: dict = field(default_factory=lambda: {port: "" for port in NODE_PORTS + RIGID_PORTS})
    rigid_points: dict = field(default_factory=lambda: {port: "" for port in RIGID_PORTS})
    probes: dict = field(default_factory=lambda: {probe: "" for probe in PROBES})
    load_point: str = ""
    load_constant: list = field(default_factory=lambda: [0.0, 0.0, 0.0])  # N, x y z
    load_amplitude: list = field(default_factory=lambda: [0.0, 0.0, 0.0])  # N, x y z
    load_frequency: float = 0.0  # Hz
    load_probe: int = 0  # 1: the probe ``load`` at load_point


def _parameters() -> dict[str, tuple[str, str, tuple]]:
    """FMU parameter name -> (FMI type, description, where in BodySpec: (attribute,) or
    (attribute, key))."""
    table = {
        "mesh_file": ("String", "mesh file (meshio formats), relative to the FMU's "
                      "resources folder, or an absolute path or file: URI (empty: a "
                      "built-in 1 m x 0.1 m beam of 20 x 2 quadrilaterals)", ("mesh_file",)),
        "order": ("Integer", "element order: 1 linear, 2 quadratic (mid-side nodes)",
                  ("order",)),
        "thickness": ("Real", "thickness of a 2-D (plane stress) body, m", ("thickness",)),
        "youngs_modulus": ("Real", "Young's modulus, Pa", ("youngs_modulus",)),
        "poisson_ratio": ("Real", "Poisson ratio, -", ("poisson_ratio",)),
        "density": ("Real", "density, kg/m^3", ("density",)),
        "mass": ("String", "consistent or lumped (lumped needs order 1)", ("mass",)),
        "rayleigh_alpha": ("Real", "Rayleigh damping C = alpha M + beta K: alpha, 1/s",
                           ("rayleigh_alpha",)),
        "rayleigh_beta": ("Real", "Rayleigh damping C = alpha M + beta K: beta, s",
                          ("rayleigh_beta",)),
        "fidelity": ("String", "full, craig_bampton (with modes) or rigid", ("fidelity",)),
        "modes": ("Integer", "fidelity craig_bampton: fixed-interface modes", ("modes",)),
        "clamped": ("String", "clamped node set ('box ...', 'point ...' or a boundary; "
                    "';' joins)", ("clamped",)),
        "load.point": ("String", "sine load (and probe 'load') point 'x y [z]', m",
                       ("load_point",)),
        "load_frequency": ("Real", "frequency of the sine point load, Hz",
                           ("load_frequency",)),
        "load.probe": ("Integer", "1 adds the probe 'load' at load.point", ("load_probe",)),
    }
    for i, dof in enumerate(DOFS):
        table[f"load.F0_{dof}"] = ("Real", "constant load, N", ("load_constant", i))
        table[f"load.F_{dof}"] = ("Real", "sine load amplitude, N", ("load_amplitude", i))
    for probe in PROBES:
        table[f"{probe}.point"] = ("String", f"point 'x y [z]' of probe {probe}, m",
                                   ("probes", probe))
    for port in NODE_PORTS:
        table[f"{port}.nodes"] = ("Integer", f"nodes of port {port} the scene glues (0: "
                                  f"unused; at most {MAX_NODES}); must equal its set's size",
                                  ("nodes", port))
        table[f"{port}.set"] = ("String", f"node set of port {port}", ("sets", port))
    for port in RIGID_PORTS:
        table[f"{port}.set"] = ("String", f"node set of rigid port {port} (empty: unused)",
                                ("sets", port))
        table[f"{port}.point"] = ("String", f"reference point 'x y [z]' of {port}, m "
                                  "(empty: the set's centroid)", ("rigid_points", port))
    return table


#: Every parameter of the ElasticBody FMU: name -> (FMI type, description, place).
PARAMETERS = _parameters()
_CONVERT = {"Real": float, "Integer": int, "String": str}


def get_parameter(spec: "BodySpec", name: str):
    """The value of FMU parameter ``name`` in ``spec``."""
    kind, _, place = PARAMETERS[name]
    value = getattr(spec, place[0])
    return _CONVERT[kind](value if len(place) == 1 else value[place[1]])


def set_parameter(spec: "BodySpec", name: str, value) -> None:
    """Set FMU parameter ``name`` of ``spec`` (KeyError for an unknown name)."""
    kind, _, place = PARAMETERS[name]
    value = _CONVERT[kind](value)
    if len(place) == 1:
        setattr(spec, place[0], value)
    else:
        getattr(spec, place[0])[place[1]] = value


def spec_from_parameters(values: dict) -> "BodySpec":
    """A BodySpec from FMU parameter values (name -> value), as a scene binds them."""
    spec = BodySpec()
    for name, value in values.items():
        set_parameter(spec, name, value)
    return spec


def _numbers(text: str, what: str) -> list[float]:
    try:
        return [float(word) for word in text.split()]
    except ValueError:
        raise ValueError(f"{what} '{text}': expected numbers") from None


def point_coordinates(text: str, dim: int, what: str) -> tuple[float, ...]:
    """``"x y"`` or ``"x y z"`` (m) as a point of a ``dim``-D mesh."""
    numbers = _numbers(text, what)
    if len(numbers) != dim:
        raise ValueError(f"{what} '{text}': a {dim}-D mesh needs {dim} coordinates")
    return tuple(numbers)


def node_set_spec(text: str, dim: int, extent: float):
    """A node set from a string (see the module docstring): a predicate on the node
    coordinates, or a boundary name. Box tolerance: 1e-6 of the mesh ``extent`` (m)."""
    parts = [part.strip() for part in text.split(";") if part.strip()]
    if not parts:
        raise ValueError("empty node set")
    if len(parts) == 1 and parts[0].split()[0] not in ("box", "point"):
        return parts[0]  # a boundary stored in the mesh file
    selectors = []
    for part in parts:
        kind, rest = part.split()[0], " ".join(part.split()[1:])
        if kind == "box":
            numbers = _numbers(rest, "box")
            if len(numbers) != 2 * dim:
                raise ValueError(f"node set '{part}': a {dim}-D box needs {2 * dim} numbers "
                                 f"(low corner, then high corner)")
            selectors.append(in_box(numbers[:dim], numbers[dim:], tolerance=1e-6 * extent))
        elif kind == "point":
            point = np.array(point_coordinates(rest, dim, "point"))[:, None]
            selectors.append(lambda x, point=point: np.arange(x.shape[1]) == np.argmin(
                np.sum((x - point) ** 2, axis=0)))
        else:
            raise ValueError(f"node set '{part}': expected 'box ...', 'point ...' or one "
                             f"boundary name")
    return lambda x: np.any([select(x) for select in selectors], axis=0)


def mesh_path(mesh_file: str, resources: Optional[Path]) -> Path:
    """The mesh file: an absolute path, a ``file:`` URI, or a path relative to the FMU's
    resources folder."""
    if mesh_file.startswith("file:"):
        return Path(unquote(urlparse(mesh_file).path))
    path = Path(mesh_file)
    if not path.is_absolute() and resources is not None:
        path = Path(resources) / path
    return path


def _check(spec: BodySpec) -> None:
    if spec.fidelity not in FIDELITIES:
        raise ValueError(f"parameter fidelity = '{spec.fidelity}' must be one of "
                         f"{', '.join(FIDELITIES)}")
    if spec.modes < 0 or (spec.modes and spec.fidelity != "craig_bampton"):
        raise ValueError(f"parameter modes = {spec.modes}: give modes >= 0 with fidelity "
                         f"= craig_bampton (fidelity is '{spec.fidelity}')")
    if spec.order not in (1, 2):
        raise ValueError(f"parameter order = {spec.order} must be 1 or 2")
    for port, count in spec.nodes.items():
        if not 0 <= count <= MAX_NODES:
            raise ValueError(f"parameter {port}.nodes = {count} must be 0 .. {MAX_NODES}")
        if count and not spec.sets[port]:
            raise ValueError(f"port '{port}' has {port}.nodes = {count} but no node set: "
                             f"set the parameter {port}.set")


def build_body(spec: BodySpec, resources: Optional[Path] = None,
               check_counts: bool = True) -> ElasticBody:
    """The body ``spec`` describes, with the node-set ports whose ``S.nodes`` is positive
    and the rigid ports whose set is given.

    Raises ValueError, one line naming the parameter or file, for anything inconsistent
    (``check_counts``: also a node-set port whose ``S.nodes`` differs from its set's size).
    """
    _check(spec)
    if spec.mesh_file:
        path = mesh_path(spec.mesh_file, resources)
        try:
            mesh = load_mesh(path)
        except ValueError as error:  # name the file as the scene does, not the unzip folder
            raise ValueError(str(error).replace(str(path), f"'{spec.mesh_file}'")) from None
    else:  # no mesh file: the built-in beam, so that the FMU runs alone
        mesh = rectangle(**DEFAULT_BEAM)
    dim = mesh.dim()
    extent = float(np.ptp(mesh.p, axis=1).max()) or 1.0
    ports = [port for port in NODE_PORTS if spec.nodes[port] > 0]
    rigid = [port for port in RIGID_PORTS if spec.sets[port]]
    sets = {port: node_set_spec(spec.sets[port], dim, extent) for port in ports + rigid}
    clamped = []
    if spec.clamped:
        sets["clamped"] = node_set_spec(spec.clamped, dim, extent)
        clamped = ["clamped"]
    rigid_ports = {port: point_coordinates(spec.rigid_points[port], dim, f"{port}.point")
                   if spec.rigid_points[port] else None for port in rigid}
    probes = {probe: point_coordinates(spec.probes[probe], dim, f"{probe}.point")
              for probe in PROBES if spec.probes[probe]}
    loads = []
    if any(spec.load_amplitude) or any(spec.load_constant) or spec.load_probe:
        point = point_coordinates(spec.load_point, dim, "load.point")
        omega = 2.0 * np.pi * spec.load_frequency
        loads = [PointLoad(point, dof, constant=constant, amplitude=amplitude, omega=omega)
                 for dof, constant, amplitude in zip(DOFS[:dim], spec.load_constant,
                                                     spec.load_amplitude)
                 if amplitude or constant]
        if spec.load_probe:
            probes["load"] = point
    material = Material(spec.youngs_modulus, spec.poisson_ratio, spec.density)
    body = ElasticBody(mesh, material, thickness=spec.thickness, mass=spec.mass,
                       rayleigh=(spec.rayleigh_alpha, spec.rayleigh_beta), node_sets=sets,
                       clamped=clamped, ports=ports, rigid_ports=rigid_ports, loads=loads,
                       probes=probes, order=spec.order, rigid=spec.fidelity == "rigid",
                       modes=spec.modes if spec.fidelity == "craig_bampton" else None,
                       name=Path(spec.mesh_file).name or "built-in beam")
    for port in ports if check_counts else ():
        count = len(body.node_sets[port])
        if count != spec.nodes[port]:
            raise ValueError(f"port '{port}': its node set has {count} nodes but the parameter "
                             f"{port}.nodes is {spec.nodes[port]}")
    return body


def port_node_counts(spec: BodySpec, resources: Optional[Path] = None) -> dict[str, int]:
    """Node count of every node-set port with a set: the values ``S.nodes`` must take."""
    probe = BodySpec(**{**spec.__dict__, "nodes": {port: int(bool(spec.sets[port]))
                                                     for port in NODE_PORTS}})
    body = build_body(probe, resources, check_counts=False)
    return {port: len(body.node_sets[port]) for port in NODE_PORTS if spec.sets[port]}


def slot_interface() -> tuple[tuple[str, str], ...]:
    """Every (port, dof) slot of the fixed layout: ``port1[1]`` x y z ... then ``rigid1``
    x y z rx ry rz ..."""
    nodes = tuple((f"{port}[{k}]", dof) for port in NODE_PORTS
                  for k in range(1, MAX_NODES + 1) for dof in DOFS)
    return nodes + tuple((port, dof) for port in RIGID_PORTS for dof in RIGID_DOFS)


class SlotBody(InterfaceCore):
    """An :class:`ElasticBody` seen through the fixed slot layout (see module docstring).

    Forces on slots the body does not have are ignored; their kinematics are zero.
    """

    interface = slot_interface()
    output_names = tuple(f"{probe}.u_{dof}" for probe in ("load",) + PROBES for dof in DOFS)

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

    def kinematic_reader(self, kind: int, rows: np.ndarray):
        """The body's reader of these slots, when the body has every one of them."""
        inner = np.full(len(self.interface), -1)
        inner[self._slots] = np.arange(len(self._slots))
        inner = inner[rows]
        return self.body.kinematic_reader(kind, inner) if np.all(inner >= 0) else None

    def get_state(self) -> dict:
        return {"body": self.body.get_state(), "forces": self._forces.copy()}

    def caches(self):
        return self.body.caches()

    def set_caches(self, caches) -> None:
        self.body.set_caches(caches)

    def set_state(self, state: dict) -> None:
        self.body.set_state(state["body"])
        self._forces = state["forces"].copy()
        self._pushed = True  # the body's state holds its own forces

    def outputs(self) -> dict[str, float]:
        values = self.body.outputs()
        return {name: float(values.get(name, 0.0)) for name in self.output_names}
