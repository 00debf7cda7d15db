"""``dsim run --input FILE`` (the API's ``inputs=``): an input table's columns resolved
against the scene's components, and the table added to the scene as a table component
(:data:`INPUT_COMPONENT`) with one connection per column into the input it names.  From
there the run is the run of any table component (:mod:`dsim.master.running.tables`):
the plan, every coupling and every backend see a source and connections.

A column is named ``component.variable`` (a nested component by its dotted path:
``frame.rail.P.f_x`` is variable ``P.f_x`` of ``frame.rail``).  Refused, one line each,
before anything runs: an unknown component or variable (with the closest names); a
variable that is not an input (an output, a parameter: ``--set`` gives parameters); a
String input; an input a connection feeds (a table does not override a connection).
A column on a glued port's force (its joint sets it) is refused by the plan, as any
connection into one is (planning/plan.py: the joints' own port dofs, node sets and port
maps included).
"""
from __future__ import annotations

from dataclasses import replace

from dsim.master.errors import InputError
from dsim.master.planning.names import closest, owner_split
from dsim.master.reading.fmi_description import describe
from dsim.master.reading.input_tables import held, read_table
from dsim.master.scene import Component, Connection, Scene

#: the name of the table component ``--input`` adds (no SSP scene names one so)
INPUT_COMPONENT = "--input"
#: the input kinds a table can feed
FED = ("Real", "Integer", "Boolean", "Enumeration")


def with_inputs(scene: Scene, inputs) -> Scene:
    """``scene`` with the input table ``inputs`` (a .csv or .mat file's path, a pandas
    DataFrame, a numpy structured array, or a read
    :class:`~dsim.master.reading.input_tables.Table`) as the table component
    :data:`INPUT_COMPONENT`, each column connected to the input it names;
    InputError listing every problem (the scene's own first)."""
    table = read_table(inputs)
    # the file itself where it is here (a run never writes over it), else the table
    # held in memory (a DataFrame; a table read elsewhere, as a sweep's Ray worker gets it)
    source = table.file if table.file is not None and table.file.is_file() else held(table)
    paths = {c.path: c for c in scene.components}
    fed = {c.end: c.start for c in scene.connections}
    problems, connections = [], []
    where = f"{table.source}"
    for column in table.names:
        path, name = owner_split(column, paths) or (None, column)
        if path is None:
            head = column.split(".")[0]
            problems.append(f"{where}: column '{column}': the scene has no component "
                            f"'{head}'" + closest(head, paths))
            continue
        component = paths[path]
        try:
            description = scene.descriptions.get(component.source) or describe(component.source)
        except Exception:  # an FMU the plan refuses: it says why
            continue
        variable = description.by_name.get(name)
        if variable is None:
            inputs_of = [v.name for v in description.modelVariables if v.causality == "input"]
            problems.append(f"{where}: column '{column}': component '{path}' has no variable "
                            f"'{name}'" + closest(name, inputs_of))
            continue
        if variable.causality != "input":
            problems.append(f"{where}: column '{column}' is {variable.causality} '{name}' of "
                            f"'{path}': an input table feeds inputs"
                            + (" (--set gives a parameter its value)"
                               if variable.causality == "parameter" else ""))
            continue
        if variable.type not in FED:
            problems.append(f"{where}: column '{column}' is a {variable.type} input: an input "
                            "table feeds numbers (Real, Integer, Boolean, Enumeration)")
            continue
        if (path, name) in fed:
            problems.append(f"{where}: column '{column}': '{path}.{name}' is fed by the "
                            f"connection from '{'.'.join(fed[path, name])}': an input table "
                            "feeds inputs no connection feeds")
            continue
        connections.append(Connection((INPUT_COMPONENT, column), (path, name),
                                      location=f"{where}: column '{column}'"))
    if problems:
        refused = InputError(list(scene.problems) + problems)
        refused.warnings = list(scene.warnings)
        raise refused
    component = Component(INPUT_COMPONENT, source, location=f"{where} (--input)")
    return replace(scene, components=scene.components + (component,),
                   connections=scene.connections + tuple(connections))
