"""A linear elastic finite-element body as a glueable core (no FMI here).

Equations: M a + C v + K u = f_loads(t) + B^T F on the generalized coordinates q of
:mod:`.constraints` (clamps, rigid sets), optionally reduced (Craig-Bampton, or the body
as one rigid body), integrated by Newmark average acceleration (:mod:`.newmark`),
equilibrium at the end of each step. Units: SI (m, s, kg, N, Pa, rad).

Nodes are the element's interpolation points: the mesh vertices for linear elements
(``order=1``), vertices plus mid-side (and quad centre) points for quadratic ones
(``order=2``); node sets, ports, clamps and loads select among them.

Ports. A *node-set port* ``S`` glues every node of node set ``S``: its interface pairs
are ``("S[1]", "x"), ("S[1]", "y"), ... ("S[N]", "y")`` (3-D adds z), nodes in the order
of :func:`.geometry.sort_along`. A *rigid port* ties node set ``S`` to one reference
point: pairs ``("S", "x"), ("S", "y"), ("S", "rz")`` (3-D: x y z rx ry rz). Interface
kinematics are global positions (reference coordinate + displacement; rotation angle),
velocities and accelerations.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Optional, Sequence

import numpy as np
import scipy.sparse as sp
from skfem import Basis

from ..interface import InterfaceCore
from .assembly import STEEL, Material, mass_matrix, stiffness_matrix, vector_basis, von_mises
from .constraints import ROTATIONS, TRANSLATIONS, build_transformation
from .geometry import NodeSetSpec, check_mesh, nearest_node, resolve_node_set
from .maps import InterfaceMap
from .newmark import NewmarkAverageAcceleration
from .retry import RepeatedStep
from .reduction import craig_bampton_basis, generalized_eigen, rigid_body_basis


def _check_options(mesh, name: str, mass: str, order: int, rigid: bool, modes) -> None:
    """ValueError naming the body for a mesh or an option combination it cannot take."""
    check_mesh(mesh, name)
    if mass not in ("consistent", "lumped"):
        raise ValueError(f"{name}: mass must be 'consistent' or 'lumped', got {mass!r}")
    if mass == "lumped" and order != 1:  # row sums of quadratic elements go negative
        raise ValueError(f"{name}: lumped mass needs linear elements (order 1)")
    if rigid and modes is not None:
        raise ValueError(f"{name}: a rigid body has no Craig-Bampton modes")


@dataclass(frozen=True)
class PointLoad:
    """Force (N) along ``dof`` (x, y or z) at the node nearest ``point`` (m):
    ``constant + amplitude * sin(omega * t + phase)``, omega in rad/s."""

    point: tuple[float, ...]
    dof: str
    constant: float = 0.0
    amplitude: float = 0.0
    omega: float = 0.0
    phase: float = 0.0

    def value(self, time: float) -> float:
        return self.constant + self.amplitude * np.sin(self.omega * time + self.phase)


class ElasticBody(InterfaceCore):
    """Linear elastic FE body: plane stress (tri/quad, with thickness) or solid (tet/hex).

    Parameters: ``mesh`` (skfem mesh, see :mod:`.geometry`), ``material``, ``thickness``
    (m, 2-D only), ``mass`` ("consistent" or "lumped"), ``rayleigh`` = (alpha in 1/s,
    beta in s) for C = alpha M + beta K, ``node_sets`` (name -> spec), ``clamped`` (node
    set names with u = 0), ``ports`` (node-set port names), ``rigid_ports`` (node set name
    -> reference point, None for the set's centroid), ``loads``, ``probes`` (name ->
    point; outputs ``name.u_x`` ...), ``modes`` (None for the full model, or the number of
    Craig-Bampton fixed-interface modes), ``rigid`` (the body as one rigid body: its
    rigid-body motions only, the lowest fidelity), ``order`` (1 linear, 2 quadratic
    elements), ``stress_outputs`` (add ``name.von_mises`` to outputs), ``ties`` (hanging
    node -> (master nodes, weights): u = sum w u_master), ``name`` (used in errors).
    """

    def __init__(self, mesh, material: Material = STEEL, *, thickness: float = 1.0,
                 mass: str = "consistent", rayleigh: tuple[float, float] = (0.0, 0.0),
                 node_sets: Optional[Mapping[str, NodeSetSpec]] = None,
                 clamped: Sequence[str] = (), ports: Sequence[str] = (),
                 rigid_ports: Optional[Mapping[str, Optional[Sequence[float]]]] = None,
                 loads: Sequence[PointLoad] = (),
                 probes: Optional[Mapping[str, Sequence[float]]] = None,
                 modes: Optional[int] = None, rigid: bool = False, order: int = 1,
                 stress_outputs: bool = False,
                 ties: Optional[Mapping[int, tuple[Sequence[int], Sequence[float]]]] = None,
                 name: str = "body"):
        _check_options(mesh, name, mass, order, rigid, modes)
        self.name, self.mesh, self.material, self.thickness = name, mesh, material, thickness
        self.dim = mesh.dim()
        self.basis: Basis = vector_basis(mesh, order)
        self._nodes(order)
        rigid_ports = dict(rigid_ports or {})
        self._resolve_node_sets(node_sets, [*clamped, *ports, *rigid_ports], ports,
                                rigid_ports)

        # Constraints: u_full = T q.
        nodal = self.node_dofs
        clamped_nodes = np.unique(np.concatenate(
            [self.node_sets[key] for key in clamped] or [np.zeros(0, dtype=int)]))
        rigid_sets = {key: (self.node_sets[key],
                       np.mean(self.points[:, self.node_sets[key]], axis=1) if point is None
                       else np.asarray(point, dtype=float))
                 for key, point in rigid_ports.items()}
        ties = {int(node): (np.asarray(m, dtype=int), np.asarray(w, dtype=float))
                for node, (m, w) in (ties or {}).items()}
        transformation = build_transformation(nodal, self.points, clamped_nodes, rigid_sets, ties)
        T = transformation.matrix

        k_full = stiffness_matrix(self.basis, material, thickness)
        m_full = mass_matrix(self.basis, material, thickness, lumped=(mass == "lumped"))
        stiffness = (T.T @ k_full @ T).tocsr()
        mass_q = (T.T @ m_full @ T).tocsr()

        interface_map = self._build_interface(ports, rigid_sets, transformation)
        self.loads = tuple(loads)
        loads_q = self._build_loads(T)  # f(t) = loads_q @ values(t)
        self.probes = {key: np.asarray(point, dtype=float) for key, point in (probes or {}).items()}
        probe_map = self._build_probes(T)  # probe displacements = probe_map @ q
        self.stress_outputs = stress_outputs

        self.modes, self.rigid = modes, bool(rigid)
        stiffness, mass_q, interface_map, loads_q, probe_map = self._reduce(
            T, nodal, stiffness, mass_q, interface_map, loads_q, probe_map)
        alpha, beta = rayleigh
        damping = alpha * mass_q + beta * stiffness if (alpha or beta) else None
        self.stiffness, self.mass, self.damping = stiffness, mass_q, damping
        self._interface_map = InterfaceMap(interface_map)
        self._loads, self._probe_map = loads_q, probe_map
        self.integrator = NewmarkAverageAcceleration(stiffness, mass_q, damping)
        self._repeat = RepeatedStep(self.integrator, self._interface_map)

        n = stiffness.shape[0]
        self.time = 0.0
        self._q, self._v, self._a = np.zeros(n), np.zeros(n), np.zeros(n)
        self._forces = np.zeros(len(self.interface))

    # -- construction helpers --------------------------------------------------------------
    def _resolve_node_sets(self, node_sets, used, ports, rigid_ports) -> None:
        """``self.node_sets``: each named node set's nodes; every set ``used`` (clamped,
        port, rigid port) must be one, and no set both a node-set and a rigid port."""
        name = self.name
        try:
            self.node_sets = {key: resolve_node_set(self.mesh, key, spec, self.points,
                                                    self._facet_nodes)
                              for key, spec in (node_sets or {}).items()}
        except ValueError as error:  # say which body (its mesh file, in the FMU)
            raise ValueError(f"{name}: {error}") from None
        for key in used:
            if key not in self.node_sets:
                raise ValueError(f"{name}: node set {key!r} is not defined "
                                 f"(defined: {sorted(self.node_sets)})")
        if set(ports) & set(rigid_ports):
            raise ValueError(f"{name}: {sorted(set(ports) & set(rigid_ports))} "
                             f"both node-set and rigid ports")

    def _reduce(self, T, nodal, stiffness, mass_q, interface_map, loads_q, probe_map):
        """Reduction q = Psi r: Craig-Bampton (interface coordinates kept physical) or
        the rigid-body motions alone; the matrices in the reduced coordinates (as given
        when there is no reduction).  Sets ``self._full_map`` (u_full = map @ q)."""
        self._full_map = T
        psi = None
        if self.modes is not None:
            # loaded dofs stay physical too: the static response to a point load is then
            # exact, instead of converging slowly with the number of modes
            boundary = np.unique(np.concatenate([interface_map.indices,
                                                 sp.csc_matrix(loads_q).indices]))
            psi = craig_bampton_basis(stiffness, mass_q, boundary, self.modes)
        elif self.rigid:
            psi = rigid_body_basis(T, self.points, nodal, self.name)
        if psi is None:
            return stiffness, mass_q, interface_map, loads_q, probe_map
        stiffness = sp.csr_matrix(psi.T @ (stiffness @ psi))
        if self.rigid:  # rigid motions store no strain energy: drop the round-off
            stiffness = sp.csr_matrix(stiffness.shape)
        self._full_map = sp.csr_matrix(T @ psi)
        return (stiffness, sp.csr_matrix(psi.T @ (mass_q @ psi)),
                sp.csr_matrix(interface_map @ psi), sp.csr_matrix(psi.T @ loads_q.toarray()),
                sp.csr_matrix(probe_map @ psi))

    def _nodes(self, order: int) -> None:
        """Interpolation points ``self.points`` (dim, nnodes) and their dofs
        ``self.node_dofs`` (dim, nnodes): the vertices for linear elements."""
        if order == 1:
            self.points, self.node_dofs = self.mesh.p, self.basis.nodal_dofs
        else:  # every component's dofs sit at the same points, in the same order
            split = self.basis.split_indices()
            self.node_dofs = np.vstack(split)
            self.points = self.basis.doflocs[:, split[0]]
        self._node_of_dof = np.full(self.basis.N, -1)
        self._node_of_dof[self.node_dofs[0]] = np.arange(self.node_dofs.shape[1])

    def _facet_nodes(self, facets: np.ndarray) -> np.ndarray:
        """Nodes on the given mesh facets (vertices and, quadratic, mid-side points)."""
        nodes = self._node_of_dof[self.basis.get_dofs(facets=facets).all()]
        return np.unique(nodes[nodes >= 0])

    def _build_interface(self, ports, rigid, transformation) -> sp.csr_matrix:
        """Interface pairs, reference positions and B (interface displacement = B q)."""
        T, nodal, points = transformation.matrix, self.node_dofs, self.points
        pairs, rows, reference = [], [], []
        self._port_slices: dict[str, slice] = {}
        for key in ports:  # node-set ports: rows of T
            start = len(pairs)
            for k, node in enumerate(self.node_sets[key], start=1):
                for c, dof in enumerate(TRANSLATIONS[self.dim]):
                    pairs.append((f"{key}[{k}]", dof))
                    rows.append(T[nodal[c, node]])
                    reference.append(points[c, node])
            self._port_slices[key] = slice(start, len(pairs))
        for key, (_, point) in rigid.items():  # rigid ports: their own reference columns
            start = len(pairs)
            for j, dof in enumerate(TRANSLATIONS[self.dim] + ROTATIONS[self.dim]):
                pairs.append((key, dof))
                column = transformation.rigid_columns[key][j]
                rows.append(sp.csr_matrix(([1.0], ([0], [column])), shape=(1, T.shape[1])))
                reference.append(point[j] if j < self.dim else 0.0)
            self._port_slices[key] = slice(start, len(pairs))
        self.interface = tuple(pairs)
        self._rigid_points = {key: point for key, (_, point) in rigid.items()}
        self._reference = np.array(reference, dtype=float)
        return sp.vstack(rows).tocsr() if rows else sp.csr_matrix((0, T.shape[1]))

    def _build_loads(self, T: sp.csr_matrix) -> sp.csr_matrix:
        """Unit load columns in q (one per point load, at its nearest node)."""
        columns = []
        for load in self.loads:
            if load.dof not in TRANSLATIONS[self.dim]:
                raise ValueError(f"{self.name}: load dof {load.dof!r} must be one of "
                                 f"{TRANSLATIONS[self.dim]}")
            node = nearest_node(self.points, load.point)
            columns.append(T[self.node_dofs[TRANSLATIONS[self.dim].index(load.dof), node]].T)
        return sp.hstack(columns).tocsr() if columns else sp.csr_matrix((T.shape[1], 0))

    def _build_probes(self, T: sp.csr_matrix) -> sp.csr_matrix:
        """Rows interpolating each probe's displacement components from q."""
        nodal = self.node_dofs  # the scalar basis numbers its dofs as these nodes
        scalar = Basis(self.mesh, self.basis.elem.elem)  # nodal interpolation weights
        self._probe_elements, rows, self._output_names = {}, [], []
        for key, point in self.probes.items():
            try:
                self._probe_elements[key] = int(self.mesh.element_finder()(*point[:, None])[0])
            except (ValueError, IndexError):
                raise ValueError(f"{self.name}: probe {key!r} at {point.tolist()} "
                                 f"is outside the mesh") from None
            weights = sp.csr_matrix(scalar.probes(point[:, None]))
            for c, dof in enumerate(TRANSLATIONS[self.dim]):
                row = sp.csr_matrix((weights.data, (np.zeros(weights.nnz, dtype=int),
                                                    nodal[c, weights.indices])),
                                    shape=(1, self.basis.N))
                rows.append(row @ T)
                self._output_names.append(f"{key}.u_{dof}")
        return sp.vstack(rows).tocsr() if rows else sp.csr_matrix((0, T.shape[1]))

    # -- InterfaceCore -------------------------------------------------------------------
    def initialize(self, start_time: float) -> None:
        """Time := start_time; M a0 = f(t0) + B^T F - K u0 - C v0 on the free coordinates."""
        self.time = float(start_time)
        self._a = self.integrator.acceleration(self._q, self._v, self._force(self.time))

    def set_interface_forces(self, forces: np.ndarray) -> None:
        forces = np.asarray(forces, dtype=float)
        if forces.shape != self._forces.shape:
            raise ValueError(f"{self.name}: {forces.size} interface forces given, "
                             f"{self._forces.size} expected")
        self._forces = forces.copy()

    def step(self, time: float, step_size: float) -> None:
        """Newmark step t -> t + h with loads evaluated at t + h and the forces held (a
        repeat of the last step from the same state with other forces, as a master's
        Newton iteration makes it, by the body's linear response: fmus/elastic/retry.py)."""
        end = time + step_size
        q, v, a = self._q, self._v, self._a
        self._q, self._v, self._a = self._repeat.step(
            time, step_size, (q, v, a), self._forces,
            lambda: self.integrator.step(q, v, a, self._force(end), step_size))
        self.time = end

    def interface_kinematics(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return tuple(self.interface_kinematic(kind) for kind in range(3))

    def interface_kinematic(self, kind: int) -> np.ndarray:
        values = self._interface_map.apply((self._q, self._v, self._a)[kind])
        return self._reference + values if kind == 0 else values

    def kinematic_reader(self, kind: int, rows: np.ndarray):
        """Entries ``rows`` of :meth:`interface_kinematic`, read straight from the state
        where B only picks coordinates (each entry the same sum as there), else None."""
        interface_map = self._interface_map
        if interface_map.picked is None:
            return None
        state = ("_q", "_v", "_a")[kind]
        if interface_map._every_row:
            picked = interface_map.picked[rows]
            if kind == 0:
                reference = self._reference[rows]
                return lambda: reference + self._q[picked]
            return lambda: getattr(self, state)[picked]
        # some rows pick nothing (a glued node that is clamped): zero there, as in apply()
        source = np.full(interface_map.rows, -1)
        source[interface_map.picking] = interface_map.picked
        source = source[rows]
        places, picked = np.flatnonzero(source >= 0), source[source >= 0]
        reference = self._reference[rows] if kind == 0 else None

        def read():
            values = np.zeros(len(rows))
            values[places] = getattr(self, state)[picked]
            return values if reference is None else reference + values
        return read

    def caches(self):
        return self._repeat.snapshot()

    def set_caches(self, caches) -> None:
        self._repeat.resume(caches)

    def get_state(self) -> dict:
        return {"time": self.time, "q": self._q.copy(), "v": self._v.copy(),
                "a": self._a.copy(), "forces": self._forces.copy()}

    def set_state(self, state: dict) -> None:
        self.time = float(state["time"])
        self._q, self._v = state["q"].copy(), state["v"].copy()
        self._a, self._forces = state["a"].copy(), state["forces"].copy()

    def outputs(self) -> dict[str, float]:
        """Probe displacements ``<probe>.u_<dof>`` (m); ``<probe>.von_mises`` (Pa) if asked."""
        values = dict(zip(self._output_names, (self._probe_map @ self._q).tolist()))
        if self.stress_outputs:
            for key in self.probes:
                values[f"{key}.von_mises"] = self.von_mises(key)
        return values

    # -- beyond the contract -------------------------------------------------------------
    def _force(self, time: float) -> np.ndarray:
        """Generalized force: point loads at ``time`` plus the interface forces (N)."""
        values = np.array([load.value(time) for load in self.loads])
        force = self._interface_map.apply_transpose(self._forces)
        return force + self._loads @ values if self.loads else force

    def displacement(self) -> np.ndarray:
        """Full displacement vector (m), dofs of ``self.basis`` (``self.node_dofs[c, node]``)."""
        return np.asarray(self._full_map @ self._q).ravel()

    @property
    def interface_matrix(self) -> sp.csr_matrix:
        """B, interface displacement = B q (rows in ``interface`` order; m per unit q)."""
        return self._interface_map.matrix

    def port_coordinates(self, port: str) -> np.ndarray:
        """Reference coordinates (m) of a port's nodes, shape (N, dim), in interface order
        (a rigid port gives its reference point, shape (1, dim))."""
        if port in self._rigid_points:
            return self._rigid_points[port][None, :].copy()
        if port not in self._port_slices:
            raise ValueError(f"{self.name}: no port {port!r} (ports: {sorted(self._port_slices)})")
        return self.points[:, self.node_sets[port]].T.copy()

    def port_slice(self, port: str) -> slice:
        """The entries of the interface vectors that belong to ``port``."""
        if port not in self._port_slices:
            raise ValueError(f"{self.name}: no port {port!r} (ports: {sorted(self._port_slices)})")
        return self._port_slices[port]

    def von_mises(self, probe: str) -> float:
        """Von Mises stress (Pa), averaged over the element containing the probe."""
        return von_mises(self.basis, self.material, self.displacement(),
                         self._probe_elements[probe])

    def static_displacement(self, time: float = 0.0) -> np.ndarray:
        """Full displacement (m) of K u = f(time) + B^T F (does not change the state)."""
        return np.asarray(self._full_map @ self.integrator.static(self._force(time))).ravel()

    def set_static_equilibrium(self, time: float = 0.0) -> None:
        """State := static solution K q = f(time) + B^T F with zero velocity and acceleration
        (a preloaded start; time is set to ``time``)."""
        self._q = self.integrator.static(self._force(time))
        self._v, self._a = np.zeros_like(self._q), np.zeros_like(self._q)
        self.time = float(time)

    def natural_frequencies(self, count: int) -> np.ndarray:
        """Lowest ``count`` natural frequencies (Hz) on the clamps, interface free, undamped."""
        values, _ = generalized_eigen(self.stiffness, self.mass, count)
        return np.sqrt(np.maximum(values, 0.0)) / (2.0 * np.pi)
