"""Causal SSP connections: checked against the FMUs, then resolved once into index
arrays.

Every subsystem reads one batch of variables after each step (its recorded
outputs and the sources of its outgoing connections): the run's flat output
vector is their concatenation.  A connection is then an index into that vector,
a linear map (unit conversion, then the SSP LinearTransformation) and, for
Integer and Boolean connections with an SSP mapping transformation, a table; each
macro step moves every connection with one gather and one multiply-add, and one
batched write per receiving subsystem.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dsim.master.errors import SimulationError
from dsim.master.reading.input_tables import is_table
from dsim.master.reading.units import conversion, fmu_units, variable_unit

#: FMI types a connection or a recorded column carries, and the kind each moves as
KINDS = {"Real": "Real", "Integer": "Integer", "Enumeration": "Integer", "Boolean": "Boolean",
         "String": "String"}


@dataclass(frozen=True)
class Link:
    """One checked connection: start and end (component path, variable), the value
    kind, the linear map value_end = factor * value_start + offset, and a mapping table
    (source -> target, after the linear map) where one applies."""

    start: tuple[str, str]
    end: tuple[str, str]
    kind: str
    factor: float = 1.0
    offset: float = 0.0
    table: tuple[tuple[float, float], ...] = ()
    #: False for a fixed parameter: set once, at initialization
    every_step: bool = True


def _every_step(variable) -> bool:
    """Whether a connection sets the variable at every step: an input, or a parameter
    FMI 2.0 lets a master change after initialization (tunable); a fixed parameter is
    set once, at initialization."""
    return variable.causality == "input" or variable.variability == "tunable"


def _linear(connection, start_var, end_var, units: dict, where: str, problems: list):
    """factor and offset of a Real connection: unit conversion, then the transformations."""
    factor, offset = 1.0, 0.0
    names = [connection.units[0] or variable_unit(start_var),
             connection.units[1] or variable_unit(end_var)]
    if connection.convert_units and all(names) and names[0] != names[1]:
        known = [units.get(name) for name in names]
        if None in known:
            missing = names[known.index(None)]
            problems.append(f"{where}: unit '{missing}' is defined neither in the SSD nor "
                            "in the FMU, so it cannot be converted")
        else:
            try:
                factor, offset = conversion(*known)
            except ValueError as error:
                problems.append(f"{where}: cannot connect {error}")
    for step in connection.transformations:
        if step.kind != "linear":
            problems.append(f"{where}: a {step.kind} mapping transformation on a Real "
                            "connection (it is for Boolean, Integer and enumeration values)")
            continue
        factor, offset = step.factor * factor, step.factor * offset + step.offset
    return factor, offset


def _table(connection, kind: str, where: str, problems: list):
    """The mapping table of an Integer or Boolean connection (() when it has none)."""
    table = ()
    for step in connection.transformations:
        wanted = "boolean" if kind == "Boolean" else "integer"
        if step.kind != wanted:
            problems.append(f"{where}: a {step.kind} transformation on a {kind} connection")
            continue
        if table:
            problems.append(f"{where}: more than one mapping transformation on one path")
            continue
        table = tuple((float(source), float(target)) for source, target in step.table)
    return table


def check_connections(scene, usable: dict, problems: list, warnings=None) -> list[Link]:
    """The scene's connections checked against the FMUs (the variables exist, the end
    can be set at every step, both ends carry the same kind of value, units convert).
    An Integer output into a Real input is carried exactly (as a Real), with a warning
    in ``warnings``; a Real into an Integer is refused (rounding would change it)."""
    links, units_of = [], {}
    for connection in scene.connections:
        where = connection.location
        ends, missing = [], []
        for (path, name), role in ((connection.start, "start"), (connection.end, "end")):
            variables = usable.get(path)
            if variables is None:
                break  # the component's FMU is unusable: said already
            variable = variables.get(name)
            if variable is None:
                missing.append(f"'{path}' has no variable '{name}'")
            elif role == "end" and variable.causality not in ("input", "parameter"):
                problems.append(f"{where}: '{path}.{name}' is a {variable.causality}; a "
                                "connection can feed only an input or a parameter")
            elif variable.type not in KINDS:
                problems.append(f"{where}: '{path}.{name}' is a {variable.type}, which dsim "
                                "cannot connect")
            else:
                ends.append(variable)
        if missing:  # one line for the connection
            problems.append(f"{where}: {', '.join(missing)}")
        if len(ends) != 2:
            continue
        kinds = [KINDS[v.type] for v in ends]
        if kinds[0] == "Real" and kinds[1] in ("Integer", "Boolean") and \
                is_table(scene.component(connection.start[0]).source):
            # a table's column feeds discrete inputs with its values held (whole
            # numbers, 0 and 1: dsim.master.planning.tables checks them)
            kinds[0] = kinds[1]
        if kinds == ["Integer", "Real"] and warnings is not None:
            warnings.append(f"{where}: connects an {ends[0].type} '{'.'.join(connection.start)}'"
                            f" to a Real '{'.'.join(connection.end)}': carried as a Real "
                            "(exact)")
            kinds[0] = "Real"
        if kinds[0] != kinds[1]:
            problems.append(f"{where}: connects a {ends[0].type} "
                            f"'{'.'.join(connection.start)}' to a {ends[1].type} "
                            f"'{'.'.join(connection.end)}'")
            continue
        if kinds[0] == "String":
            if connection.transformations:
                problems.append(f"{where}: a transformation on a String connection")
            links.append(Link(connection.start, connection.end, "String",
                              every_step=_every_step(ends[1])))
        elif kinds[0] == "Real":
            for path in (connection.start[0], connection.end[0]):
                if path not in units_of:
                    component = scene.component(path)
                    units_of[path] = {**fmu_units(component.source), **scene.units}
            units = {**units_of[connection.start[0]], **units_of[connection.end[0]]}
            factor, offset = _linear(connection, ends[0], ends[1], units, where, problems)
            links.append(Link(connection.start, connection.end, "Real", factor, offset,
                              every_step=_every_step(ends[1])))
        else:
            links.append(Link(connection.start, connection.end, kinds[0],
                              table=_table(connection, kinds[0], where, problems),
                              every_step=_every_step(ends[1])))
    return links


class Transfer:
    """Input values for the causal connections: ``outputs[gather] * factor + offset``,
    then the mapping tables, split per receiving subsystem (``targets``: (subsystem
    index, start, stop)); ``tables``: (position, {source: target}, connection) triples."""

    def __init__(self, gather, factor, offset, targets, tables=()):
        self.gather = np.asarray(gather, dtype=int)
        self.factor = np.asarray(factor, dtype=float)
        self.offset = np.asarray(offset, dtype=float)
        self.targets = tuple(targets)
        self.tables = tuple(tables)
        #: number of connections
        self.size = len(self.gather)
        #: whether every connection copies its value unchanged
        self.identity = bool(np.all(self.factor == 1.0) and np.all(self.offset == 0.0))

    def inputs(self, outputs: np.ndarray) -> list[tuple[int, np.ndarray]]:
        """(subsystem index, its input values) from the flat output vector (KeyError:
        a mapping table has no entry for a value)."""
        return self.split(self.values(outputs))

    def split(self, values: np.ndarray) -> list[tuple[int, np.ndarray]]:
        """The flat input values as (subsystem index, its input values)."""
        return [(index, values[start:stop]) for index, start, stop in self.targets]

    def values(self, outputs: np.ndarray) -> np.ndarray:
        """Every connected input's value, flat (receiving subsystem by subsystem)."""
        values = outputs[self.gather]
        if not self.identity:
            values = values * self.factor + self.offset
        for position, table, label in self.tables:
            value = values[position]
            if value not in table:
                raise SimulationError(f"connection {label}: its mapping has no entry for "
                                      f"the value {value:g}")
            values[position] = table[value]
        return values

    def restricted(self, indices) -> "Transfer":
        """The connections into the subsystems at ``indices``, numbered by their
        position in ``indices`` (for a backend subset)."""
        position = {index: local for local, index in enumerate(indices)}
        tables = {place: (table, label) for place, table, label in self.tables}
        gather, factor, offset, targets, kept = [], [], [], [], []
        for index, start, stop in self.targets:
            if index in position:
                targets.append((position[index], len(gather), len(gather) + stop - start))
                kept += [(len(gather) + k, *tables[start + k]) for k in range(stop - start)
                         if start + k in tables]
                gather.extend(self.gather[start:stop])
                factor.extend(self.factor[start:stop])
                offset.extend(self.offset[start:stop])
        return Transfer(gather, factor, offset, targets, kept)


class TextTransfer:
    """String values for String connections: ``texts[gather]``, split per receiving
    subsystem (``targets``: (subsystem index, start, stop))."""

    def __init__(self, gather, targets):
        self.gather = list(gather)
        self.targets = tuple(targets)
        self.size = len(self.gather)

    def inputs(self, texts: list[str]) -> list[tuple[int, list[str]]]:
        values = [texts[k] for k in self.gather]
        return [(index, values[start:stop]) for index, start, stop in self.targets]


def build_text_transfer(components: list[str], reads: dict[str, list[str]],
                        links: list[Link]) -> tuple[TextTransfer, dict[str, list[str]]]:
    """The String counterpart of :func:`build_transfer`."""
    transfer, writes = build_transfer(components, reads, links)
    return TextTransfer(transfer.gather.tolist(), transfer.targets), writes


def build_transfer(components: list[str], reads: dict[str, list[str]],
                   links: list[Link]) -> tuple[Transfer, dict[str, list[str]]]:
    """The transfer of ``links`` over the flat outputs of ``reads`` (component ->
    variables read after each step, in order), and the inputs each component has
    written (component -> variables, the order of its input vector)."""
    offsets, position = {}, 0
    for component in components:
        offsets[component] = position
        position += len(reads[component])
    by_target: dict[str, list[Link]] = {c: [] for c in components}
    for link in links:
        by_target[link.end[0]].append(link)
    gather, factors, offsets_, targets, tables, writes = [], [], [], [], [], {}
    for index, component in enumerate(components):
        entries = by_target[component]
        writes[component] = [link.end[1] for link in entries]
        if entries:
            targets.append((index, len(gather), len(gather) + len(entries)))
        for link in entries:
            if link.table:
                tables.append((len(gather), dict(link.table),
                               f"'{'.'.join(link.start)}' -> '{'.'.join(link.end)}'"))
            gather.append(offsets[link.start[0]] + reads[link.start[0]].index(link.start[1]))
            factors.append(link.factor)
            offsets_.append(link.offset)
    return Transfer(gather, factors, offsets_, targets, tables), writes
