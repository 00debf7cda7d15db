"""From joints and resolved ports to the gluing layout, joint states and each
component's glued interface (the order of its force vector)."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from dsim.master.planning.layout import GluingLayout
from dsim.master.planning.mls import transfer_matrix
from dsim.master.running.backends.inprocess import InProcessBackend
from dsim.master.running.couplings import IterativeCoupling
from dsim.master.running.joints import JointStates, measure_weights
from dsim.master.running.start import start_forces
from dsim.master.running.subsystem import CoreSubsystem
from dsim.master.scene import Joint


def _nodes(port_dofs):
    """Group a side's port dofs by port (node), keeping their order."""
    nodes: dict[str, list] = {}
    for port_dof in port_dofs:
        nodes.setdefault(port_dof.port, []).append(port_dof)
    return list(nodes.values())


def _pairs(joint: Joint, a_dofs, b_dofs, positions):
    """Per glued dof r: the dependent side's port dof and sign, and the
    independent side's (port dof, weight) terms.  Matching sides pair entry i
    with entry i; non-matching node sets carry the side with more nodes
    (dependent) to the other by moving least squares (section 2.2.3)."""
    if len(a_dofs) == len(b_dofs):
        return [(b, 1.0, [(a, -1.0)]) for a, b in zip(a_dofs, b_dofs)]
    dependent, d_sign, independent, i_sign = (
        (b_dofs, 1.0, a_dofs, -1.0) if len(b_dofs) > len(a_dofs) else
        (a_dofs, -1.0, b_dofs, 1.0))
    d_nodes, i_nodes = _nodes(dependent), _nodes(independent)
    if positions is None:  # only the interfaces are wanted yet
        transfer = np.zeros((len(d_nodes), len(i_nodes)))
    else:
        def coordinates(nodes):
            return np.array([[positions[(p.component, p.port, p.dof)] for p in node]
                             for node in nodes])
        transfer = transfer_matrix(coordinates(d_nodes), coordinates(i_nodes), joint.support)
    pairs = []
    for p, node in enumerate(d_nodes):
        for c, port_dof in enumerate(node):
            pairs.append((port_dof, d_sign, [(i_nodes[k][c], i_sign * transfer[p, k])
                                             for k in range(len(i_nodes))]))
    return pairs


def assemble(components: list[str], joints: list[Joint], sides: dict, positions=None):
    """Build the gluing problem.

    ``sides[joint.name]`` is ``(a_dofs, b_dofs)``: lists of objects with
    ``component``, ``port`` and ``dof`` attributes (``PortDof``).  Equally long
    sides glue entry i to entry i; node sets of different sizes are glued by
    moving least squares, which needs ``positions[(component, port, dof)]``, the
    initial position of every glued dof (m) -- without them the transfer is
    left zero, which is enough to learn the interfaces.  Returns ``(layout,
    joint_states, interfaces)`` where ``interfaces[component]`` lists the
    PortDofs it is glued at (empty for a component in no joint; the layout's
    incidence lists only the glued components, in ``components`` order), in the order of its force vector (a port dof in
    several joints appears once and receives the sum of their forces: eq. 4.10).
    """
    interfaces: dict[str, list] = {c: [] for c in components}
    position: dict[str, dict] = {c: {} for c in components}
    entries = []  # (component, local index, force index, coefficient)
    labels, joint_of, weights, measures = [], [], [], []
    flexible, k0, k1, c0, c1 = [], [], [], [], []

    def enter(port_dof, r, coefficient):
        key = (port_dof.port, port_dof.dof)
        local = position[port_dof.component]
        if key not in local:
            local[key] = len(interfaces[port_dof.component])
            interfaces[port_dof.component].append(port_dof)
        entries.append((port_dof.component, local[key], r, coefficient))

    for joint in joints:
        a_dofs, b_dofs = sides[joint.name]
        w = measure_weights(joint.measure, joint.xi, joint.omega)
        pairs = _pairs(joint, a_dofs, b_dofs, positions)
        nodes = len(pairs) // max(len(joint.dofs), 1)
        for i, (dependent, sign, terms) in enumerate(pairs):
            r = len(labels)
            node = f"[{i // len(joint.dofs) + 1}]" if nodes > 1 else ""
            labels.append(f"{joint.name}{node}.f_{dependent.dof}")
            joint_of.append(joint.name)
            weights.append(w)
            measures.append(joint.measure)
            d = joint.dofs.index(dependent.dof)
            flexible.append(joint.kind == "flexible")
            k0.append(joint.k0[d] if joint.k0 else 0.0)
            k1.append(joint.k1[d] if joint.k1 else 0.0)
            c0.append(joint.c0[d] if joint.c0 else 0.0)
            c1.append(joint.c1[d] if joint.c1 else 0.0)
            enter(dependent, r, sign)
            for port_dof, coefficient in terms:
                enter(port_dof, r, coefficient)
    n = len(labels)
    # only the glued components have a C_i: the others are stepped without the algorithm
    glued = [c for c in components if interfaces[c]]
    sizes = [len(interfaces[c]) for c in glued]
    offset = dict(zip(glued, np.r_[0, np.cumsum(sizes)[:-1]].astype(int).tolist()))
    # all the C_i stacked, built as one matrix (one small matrix per component cost
    # more than the rest of planning 10,000 of them); entries in the order each C_i's
    # own would have, so that every sum comes out the same
    order = sorted(range(len(entries)), key=lambda k: offset[entries[k][0]])
    rows = [offset[entries[k][0]] + entries[k][1] for k in order]
    cols = [entries[k][2] for k in order]
    data = [entries[k][3] for k in order]
    stacked = sp.csr_matrix((data, (rows, cols)), shape=(sum(sizes), n))
    layout = GluingLayout(stacked, weights, labels, joint_of, measures, sizes=sizes)
    states = JointStates(flexible, k0, k1, c0, c1)
    return layout, states, interfaces


class _Glued:
    """A port dof of an in-process core (what :func:`assemble` needs of a side)."""

    def __init__(self, component, port, dof):
        self.component, self.port, self.dof = component, port, dof


def _core_side(core, component, port, dofs):
    """The glued dofs of ``component.port`` on an in-process core: the port
    itself, or the members ``port[1]``, ``port[2]``, ... of a node set."""
    names = {p for p, _ in core.interface}
    members = [port] if port in names else [
        p for p in dict.fromkeys(n for n, _ in core.interface) if p.startswith(port + "[")]
    if not members:
        raise ValueError(f"{component} has no port '{port}'")
    return [_Glued(component, member, d) for member in members for d in dofs]


def glue_cores(cores: dict, joints: list[Joint], settings, start_time: float = 0.0):
    """Glue in-process physics cores (no FMI) with the T-T algorithm.

    ``cores`` maps component names to :class:`dsim.fmus.interface.InterfaceCore`
    objects; joints name them as in an SSP file, node-set ports included
    (node sets of different sizes are glued by moving least squares).  The start
    forces follow ``settings.start`` (dsim.master.running.start).  Returns the started
    :class:`~dsim.master.running.couplings.IterativeCoupling`; its ``backend`` holds the
    subsystems and ``step(time, step_size, step_index)`` advances them.
    """

    sides = {j.name: tuple(_core_side(cores[getattr(j, s)[0]], *getattr(j, s), j.dofs)
                           for s in ("a", "b")) for j in joints}
    names = list(cores)
    layout, states, interfaces = assemble(names, joints, sides)
    subsystems = [CoreSubsystem(name, core, [(p.port, p.dof) for p in interfaces[name]],
                                start_time) for name, core in cores.items()]
    backend = InProcessBackend(subsystems)
    glued_indices = [i for i, name in enumerate(names) if interfaces[name]]
    glued = backend.subset(glued_indices)
    if any(len(a) != len(b) for a, b in sides.values()):
        positions = {(s.name, port, dof): value for s in glued.subsystems
                     for (port, dof), value in zip(s.interface, s.kinematics()[0])}
        layout, states, _ = assemble(names, joints, sides, positions)
    forces, _, _ = start_forces(settings.start, glued, layout, states)
    backend.finish_initialization()
    coupling = IterativeCoupling(backend, glued_indices, layout, states, settings)
    coupling.start(glued.kinematics(), forces)
    return coupling
