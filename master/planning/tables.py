"""Table components in the plan (an SSP Component whose source is a .csv or .mat file,
and the table of ``--input``): the data each table subsystem carries, which of its
columns are held rather than interpolated, and the ramps of the FMUs that follow a
table's values within a step (:mod:`dsim.master.running.tables`)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from dsim.master.reading.fmi_description import describe
from dsim.master.reading.input_tables import read_table
from dsim.master.running.fmi.table_inputs import TableInputs, follows_table
from dsim.master.running.tables import TableData

#: the input kinds a table column feeds with held values (FMPy: every input but a
#: continuous Real one)
HELD_KINDS = ("Integer", "Boolean", "Enumeration")


def _held(variable) -> bool:
    """Whether an input takes a table's value held from the last row (FMPy's rule: any
    but a continuous Real input)."""
    return variable.type in HELD_KINDS or variable.variability in ("discrete", "tunable")


def table_data(component, reads, links, usable: dict, problems: list) -> TableData:
    """The data of table component ``component`` for its outputs ``reads`` (the
    columns recorded or connected), each column held where the inputs it feeds take
    held values (one line in ``problems`` for a column that feeds both kinds, or that
    feeds an Integer or Boolean input values it cannot take)."""
    table = read_table(component.source)
    held = []
    for name in reads:
        column = table.column(name)
        kinds = set()
        for link in links:
            if link.start != (component.path, name):
                continue
            variable = usable[link.end[0]][link.end[1]]
            kinds.add(_held(variable))
            where = (f"{component.location}: column '{name}' feeds "
                     f"'{'.'.join(link.end)}'")
            if variable.type in ("Integer", "Enumeration") and not np.all(
                    column == np.round(column)):
                row = int(np.flatnonzero(column != np.round(column))[0])
                problems.append(f"{where}, an {variable.type}: row {row + 1} holds "
                                f"{column[row]:g}, not a whole number")
            elif variable.type == "Boolean" and not np.all((column == 0) | (column == 1)):
                row = int(np.flatnonzero((column != 0) & (column != 1))[0])
                problems.append(f"{where}, a Boolean: row {row + 1} holds {column[row]:g} "
                                "(give 0 or 1)")
        if len(kinds) > 1:
            problems.append(f"{component.location}: column '{name}' of {table.source} feeds "
                            "both continuous Real inputs (interpolated) and discrete ones "
                            "(held): give each kind its own column")
        held.append(kinds == {True})
    values = np.array([table.column(name) for name in reads]).reshape(len(reads),
                                                                      len(table.times))
    return TableData(table.times, values, tuple(held))


def with_table_inputs(scene, specs, links, chosen: dict, coupling: str) -> tuple:
    """The specs with, for every FMU that takes continuous Real inputs from a table and
    can follow them within a step (Model Exchange, which dsim integrates; an FMI 2.0
    co-simulation FMU that declares canInterpolateInputs), the table's ramp over each
    step (:class:`~dsim.master.running.fmi.table_inputs.TableInputs`).  Not under the
    strong coupling, whose iterations ramp every connection already, nor for an FMU
    whose inputs are extrapolated over substeps (``--substeps``)."""
    if coupling == "strong":
        return specs
    index = {spec.name: i for i, spec in enumerate(specs)}
    found: dict[int, list] = {}
    for link in links:
        if link.kind != "Real" or not link.every_step:
            continue
        source = specs[index[link.start[0]]]
        if source.table is None:
            continue
        target = index[link.end[0]]
        spec = specs[target]
        if spec.table is not None or spec.substeps != 1:
            continue
        description = describe(spec.path)
        variable = description.by_name[link.end[1]]
        if _held(variable) or variable.causality != "input":
            continue
        if not follows_table(description, chosen.get(spec.name)):
            continue
        column = source.reads.index(link.start[1])
        found.setdefault(target, []).append((
            spec.writes.index(link.end[1]), source.table.times,
            source.table.values[column], link.factor, link.offset))
    if not found:
        return specs
    specs = list(specs)
    for target, entries in found.items():
        specs[target] = replace(specs[target], table_inputs=TableInputs(tuple(entries)))
    return tuple(specs)

