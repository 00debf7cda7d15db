"""Which FMU variables form which port (DESIGN.md, "Ports").

By convention a port P with dof c has the input ``P.f_c`` and the outputs
``P.u_c``, ``P.v_c``, ``P.a_c``; a ``glue:Port`` annotation maps a third-party
FMU's own names onto a port instead.  A port ``S`` that does not exist but
``S[1]``, ``S[2]``, ... do is a node set: a joint on it glues node i to node i.
An FMU whose variable list is fixed but whose node count is not (a finite-element
body's depends on its mesh) declares an Integer parameter ``S.nodes``: only
``S[1]`` .. ``S[n]`` are then ports, n being the scene's value of ``S.nodes``
(or its start value); the FMU checks n against its mesh when it initialises.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from dsim.master.reading.fmi_description import describe, variables_by_name
from dsim.master.scene import Joint, PortMap, Scene

PORT_VARIABLE = re.compile(r"^(?P<port>.+)\.(?P<kind>[fuva])_(?P<dof>x|y|z|rx|ry|rz)$")
KIND_NAMES = {"f": "force", "u": "position", "v": "velocity", "a": "acceleration"}
NEEDED = {"displacement": ("u",), "velocity": ("v",), "acceleration": ("a",),
          "penalized": ("u", "v", "a")}


@dataclass(frozen=True)
class PortDof:
    """One glueable degree of freedom of one component: its value references."""

    component: str
    port: str
    dof: str
    force: int
    position: int | None
    velocity: int | None
    acceleration: int | None


def conventional_ports(path: Path) -> dict[str, dict[str, dict[str, int]]]:
    """port -> dof -> kind (f, u, v, a) -> value reference, from variable names (the
    names matched once per FMU file; each call gets its own port and dof dicts)."""
    return {port: dict(dofs) for port, dofs in _file_ports(describe(path)).items()}


@lru_cache(maxsize=64)
def _file_ports(description) -> dict:
    """:func:`conventional_ports` of one description (kept with it: a scene of 10,000
    instances of one FMU matches its variable names once)."""
    ports: dict = {}
    for variable in description.modelVariables:
        match = PORT_VARIABLE.match(variable.name)
        if match:
            ports.setdefault(match["port"], {}).setdefault(match["dof"], {})[
                match["kind"]] = variable.valueReference
    return ports


@lru_cache(maxsize=64)
def _node_counts(description) -> tuple:
    """(node set S, its Integer parameter ``S.nodes``) of one description."""
    return tuple((name[:-len(".nodes")], variable)
                 for name, variable in description.by_name.items()
                 if name.endswith(".nodes") and variable.type == "Integer"
                 and variable.causality == "parameter")


def _mapped_ports(path: Path, maps: list[PortMap], problems: list) -> dict:
    variables = variables_by_name(path)
    ports: dict = {}
    for port_map in maps:
        for i, dof in enumerate(port_map.dofs):
            entry = ports.setdefault(port_map.name, {}).setdefault(dof, {})
            for kind, names in (("f", port_map.force), ("u", port_map.position),
                                ("v", port_map.velocity), ("a", port_map.acceleration)):
                if names is None or i >= len(names):
                    continue
                variable = variables.get(names[i])
                if variable is None:
                    problems.append(f"{port_map.location}: FMU {path.name} has no "
                                    f"variable '{names[i]}'")
                else:
                    entry[kind] = variable.valueReference
    return ports


def expand_node_set(ports: dict, port: str) -> list[str]:
    """``[port]`` if it exists, else its members ``port[1]``, ``port[2]``, ..."""
    if port in ports:
        return [port]
    members = []
    while f"{port}[{len(members) + 1}]" in ports:
        members.append(f"{port}[{len(members) + 1}]")
    return members


def joint_port_dofs(joint: Joint, side: str, ports: dict, problems: list) -> list[PortDof]:
    """The PortDofs of one side ('a' or 'b') of a joint, in (node, dof) order."""
    component, port = getattr(joint, side)
    members = expand_node_set(ports, port)
    if not members:
        problems.append(f"{joint.location}: component '{component}' has no port '{port}' "
                        f"(ports: {', '.join(sorted(ports)) or 'none'})")
        return []
    result = []
    for member in members:
        for dof in joint.dofs:
            kinds = ports[member].get(dof, {})
            # an unknown measure is the reader's problem, said already: needs no more here
            missing = [k for k in ("f",) + NEEDED.get(joint.measure, ()) if k not in kinds]
            if missing:
                problems.append(
                    f"{joint.location}: port '{component}.{member}' has no "
                    f"{' or '.join(KIND_NAMES[k] for k in missing)} variable for dof {dof}")
                continue
            result.append(PortDof(component, member, dof, kinds["f"], kinds.get("u"),
                                  kinds.get("v"), kinds.get("a")))
    return result


def _limit_node_sets(ports: dict, component) -> None:
    """Drop the members ``S[k]``, k > n, of every node set with a parameter ``S.nodes`` = n."""
    for port, variable in _node_counts(describe(component.source)):
        name = variable.name
        count = int(component.parameters.get(name, (None, variable.start or 0))[1])
        member = re.compile(re.escape(port) + r"\[(\d+)\]")
        for key in list(ports):
            match = member.fullmatch(key)
            if match and int(match[1]) > count:
                del ports[key]


def component_ports(scene: Scene, problems: list, usable=None) -> dict[str, dict]:
    """component path -> its ports (conventional names, then annotation maps), for
    the components in ``usable`` (default: every component whose FMU file exists)."""
    result = {}
    maps_of: dict[str, list] = {}
    for port_map in scene.port_maps:
        maps_of.setdefault(port_map.component, []).append(port_map)
    for component in scene.components:
        if (component.path not in usable) if usable is not None \
                else not component.source.is_file():
            continue
        ports = conventional_ports(component.source)
        _limit_node_sets(ports, component)
        maps = maps_of.get(component.path, [])
        for name, dofs in (_mapped_ports(component.source, maps, problems).items()
                           if maps else ()):
            ports.setdefault(name, {}).update(dofs)
        result[component.path] = ports
    return result
