"""From joints and resolved ports to the gluing layout, joint states and each
component's glued interface (the order of its force vector)."""
from __future__ import annotations

import scipy.sparse as sp

from master.gluing import GluingLayout
from master.joints import JointStates, measure_weights
from master.ssp import Joint


def assemble(components: list[str], joints: list[Joint], sides: dict):
    """Build the gluing problem.

    ``sides[joint.name]`` is ``(a_dofs, b_dofs)``: equally long lists of objects
    with ``component``, ``port`` and ``dof`` attributes (``PortDof``), entry i of
    one side glued to entry i of the other.  Returns ``(layout, joint_states,
    interfaces)`` where ``interfaces[component]`` lists the PortDofs it is
    glued at, in the order of its force vector (a port dof in several joints
    appears once and receives the sum of their forces: eq. 4.10).
    """
    interfaces: dict[str, list] = {c: [] for c in components}
    position: dict[str, dict] = {c: {} for c in components}
    entries = []  # (component, local index, force index, sign)
    labels, joint_of, weights = [], [], []
    flexible, k0, k1, c0, c1 = [], [], [], [], []
    for joint in joints:
        a_dofs, b_dofs = sides[joint.name]
        w = measure_weights(joint.measure, joint.xi, joint.omega)
        nodes = len(a_dofs) // max(len(joint.dofs), 1)
        for i, (a, b) in enumerate(zip(a_dofs, b_dofs)):
            r = len(labels)
            node = f"[{i // len(joint.dofs) + 1}]" if nodes > 1 else ""
            labels.append(f"{joint.name}{node}.f_{a.dof}")
            joint_of.append(joint.name)
            weights.append(w)
            d = joint.dofs.index(a.dof)
            flexible.append(joint.kind == "flexible")
            k0.append(joint.k0[d] if joint.k0 else 0.0)
            k1.append(joint.k1[d] if joint.k1 else 0.0)
            c0.append(joint.c0[d] if joint.c0 else 0.0)
            c1.append(joint.c1[d] if joint.c1 else 0.0)
            for port_dof, sign in ((a, -1.0), (b, 1.0)):
                key = (port_dof.port, port_dof.dof)
                local = position[port_dof.component]
                if key not in local:
                    local[key] = len(interfaces[port_dof.component])
                    interfaces[port_dof.component].append(port_dof)
                entries.append((port_dof.component, local[key], r, sign))
    n = len(labels)
    per_component = {c: ([], [], []) for c in components}
    for owner, local, r, sign in entries:
        rows, cols, data = per_component[owner]
        rows.append(local), cols.append(r), data.append(sign)
    incidence = [sp.csr_matrix((data, (rows, cols)), shape=(len(interfaces[c]), n))
                 for c, (rows, cols, data) in per_component.items()]
    layout = GluingLayout(incidence, weights, labels, joint_of)
    states = JointStates(flexible, k0, k1, c0, c1)
    return layout, states, interfaces


class _Glued:
    """A port dof of an in-process core (what :func:`assemble` needs of a side)."""

    def __init__(self, component, port, dof):
        self.component, self.port, self.dof = component, port, dof


def glue_cores(cores: dict, joints: list[Joint], settings, start_time: float = 0.0):
    """Glue in-process physics cores (no FMI) with the T-T algorithm.

    ``cores`` maps component names to :class:`fmus.interface.InterfaceCore`
    objects; joints name them as in an SSP file (node-set ports excluded).
    Returns the started :class:`~master.gluing.TTGluing`; its ``backend``
    holds the subsystems.
    """
    from master.backends.inprocess import InProcessBackend
    from master.gluing import TTGluing
    from master.subsystem import CoreSubsystem

    sides = {j.name: tuple([_Glued(getattr(j, s)[0], getattr(j, s)[1], d) for d in j.dofs]
                           for s in ("a", "b")) for j in joints}
    layout, states, interfaces = assemble(list(cores), joints, sides)
    subsystems = [CoreSubsystem(name, core, [(p.port, p.dof) for p in interfaces[name]],
                                start_time) for name, core in cores.items()]
    gluing = TTGluing(InProcessBackend(subsystems), layout, states, settings)
    gluing.start(gluing.backend.kinematics())
    return gluing
