"""What SSP's system hierarchy means for the components: which parameter values reach
each component (bindings at every level, with the standard's precedence), and which
output feeds each input (connections through system connectors, across levels).

Names: a component or system is known by its dotted path from the root system
(``frame.rail``); the root system's path is ``""``.
"""
from __future__ import annotations

from dataclasses import dataclass

from dsim.master.scene import Connection, Connector, Transformation


@dataclass
class Binding:
    """The values of one ParameterBinding: of a component (names are its variables) or
    of a system (names are hierarchical, relative to it); ``depth`` 0 is the root."""

    owner: str
    component: bool
    depth: int
    values: dict  # name -> (type, value)
    where: str


@dataclass
class RawConnection:
    """An ssd:Connection as written: ends (element or None for the system itself,
    connector) inside the system at ``system``."""

    system: str
    start: tuple[str | None, str]
    end: tuple[str | None, str]
    transformation: Transformation | None
    where: str
    convert_units: bool = True


def _join(path: str, name: str) -> str:
    return f"{path}.{name}" if path else name


def resolve_bindings(bindings: list[Binding], components: set[str],
                     system_connectors: dict[str, dict[str, Connector]], problems: list,
                     warnings: list, refused=frozenset()):
    """(component path -> {variable: (type, value)}, component path -> {variable: where},
    system connector node (system path, connector) -> (type, value)).

    Bindings of an enclosing system take precedence over inner ones; at one level a
    later binding over an earlier one (SSP 1.0, ParameterBinding).  A name that reaches
    no component and no system connector is a warning (an error with ``strict``): SSP
    ignores it, and tools write sets with values for other tools (CAD geometry beside
    the model's parameters), but a value that silently does not apply may be a wrong
    result.  Names of components in ``refused`` (their FMU refused already) are left
    out without a warning of their own."""
    values: dict[str, dict] = {path: {} for path in components}
    origins: dict[str, dict] = {path: {} for path in components}
    connector_values: dict[tuple[str, str], tuple] = {}
    # deepest first, so that shallower levels (and later bindings) overwrite
    for binding in sorted(bindings, key=lambda b: -b.depth):
        for name, typed in binding.values.items():
            if binding.component:
                target = (binding.owner, name)
            else:
                full = _join(binding.owner, name)
                target = _target(full, components, system_connectors)
                if target is None and any(full.startswith(path + ".") for path in refused):
                    continue
                if target is None:
                    warnings.append(f"{binding.where}: parameter '{name}' names no component "
                                    "variable and no system connector: not applied")
                    continue
            if target[0] in components:
                values[target[0]][target[1]] = typed
                origins[target[0]][target[1]] = binding.where
            else:
                connector_values[target] = typed
    return values, origins, connector_values


def _target(full: str, components: set[str], system_connectors) -> tuple[str, str] | None:
    """The (component, variable) or (system, connector) a hierarchical name reaches: the
    longest element path that prefixes it."""
    parts = full.split(".")
    for cut in range(len(parts) - 1, 0, -1):
        owner, rest = ".".join(parts[:cut]), ".".join(parts[cut:])
        if owner in components:
            return owner, rest
        if owner in system_connectors and rest in system_connectors[owner]:
            return owner, rest
    if full in system_connectors.get("", {}):
        return "", full
    return None


#: connector kinds that give a value, seen from the element that owns the connector
GIVES = {"output", "calculatedParameter", "parameter"}


def _node(raw: RawConnection, end) -> tuple[str, str, bool]:
    """(owner path, connector, whether the owner is the connection's own system)."""
    element, connector = end
    if element is None:
        return raw.system, connector, True
    return _join(raw.system, element), connector, False


def _role(node, components: set[str], component_connectors, system_connectors) -> str | None:
    """'source' or 'target' of a connection end by its connector's kind (None: unknown)."""
    owner, connector, inside = node
    if owner in components:
        kind = component_connectors.get(owner, {}).get(connector)
        if kind is None:
            return None
        return "source" if kind.kind in GIVES else "target"
    kind = system_connectors.get(owner, {}).get(connector)
    if kind is None:
        return None
    # a system's input feeds what is inside it and is fed from outside
    gives = kind.kind in ("input", "parameter") if inside else kind.kind in GIVES - {"parameter"}
    return "source" if gives else "target"


def resolve_connections(raws: list[RawConnection], components: set[str],
                        component_connectors: dict[str, dict[str, Connector]],
                        system_connectors: dict[str, dict[str, Connector]],
                        connector_values: dict, problems: list, refused=frozenset()):
    """Connections between component variables (through any chain of system connectors),
    and start values that system connector parameters give to component variables
    (component path -> {variable: (type, value)}).  A connection to a component in
    ``refused`` (its FMU refused already) is left out without a problem of its own."""
    feeds = {}  # (owner, connector) -> (source (owner, connector), transformation, where, units)
    for raw in raws:
        start, end = _node(raw, raw.start), _node(raw, raw.end)
        if start[0] in refused or end[0] in refused:
            continue
        for node, side in ((start, "start"), (end, "end")):
            owner, connector, _ = node
            if owner not in components and connector not in system_connectors.get(owner, {}):
                element = raw.start[0] if side == "start" else raw.end[0]
                problems.append(f"{raw.where}: {side} '{_join(element or '', connector)}' is "
                                "no connector of a component or system")
                break
        else:
            roles = (_role(start, components, component_connectors, system_connectors),
                     _role(end, components, component_connectors, system_connectors))
            if roles == ("target", "source"):  # SSP: start and end do not say the direction
                start, end = end, start
            key = (end[0], end[1])
            if key in feeds:
                problems.append(f"{raw.where}: '{_join(*key)}' is fed twice")
                continue
            feeds[key] = ((start[0], start[1]), raw.transformation, raw.where,
                          raw.convert_units)
    connections, starts = [], {path: {} for path in components}
    for target, (source, change, where, convert) in feeds.items():
        if target[0] not in components:
            continue  # a system connector: reached through the chains below
        chain = [change] if change else []
        seen = {target}
        while source[0] not in components:
            if source in connector_values:  # a system parameter feeds the variable
                kind, value = connector_values[source]
                try:
                    for step in chain:
                        value = step.apply(value)
                except KeyError as error:
                    problems.append(f"{where}: no mapping entry for {error}")
                starts[target[0]][target[1]] = (kind, value)
                break
            if source not in feeds or source in seen:
                # an input of the root system that nothing feeds is driven by nobody: the
                # component keeps its own start value
                if source[0] != "":
                    problems.append(f"{where}: system connector '{_join(*source)}' that feeds "
                                    f"'{_join(*target)}' is not connected to a component")
                break
            seen.add(source)
            source, change, _, hop_converts = feeds[source]
            convert = convert and hop_converts
            if change:
                chain.insert(0, change)
        else:
            units = (_unit(source, component_connectors), _unit(target, component_connectors))
            connections.append(Connection(source, target, tuple(chain), units, where, convert))
    return connections, starts


def _unit(node, component_connectors) -> str | None:
    """The unit a component connector declares (None: the FMU variable's applies)."""
    declared = component_connectors.get(node[0], {}).get(node[1])
    return declared.unit if declared else None
