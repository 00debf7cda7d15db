"""Algebraic loops: cycles of direct feedthrough through the scene's connections.

A connection feeds an input; inside an FMU an output depends directly on some inputs
(the modelDescription's ModelStructure: ``dependencies``; an output that declares
none may depend on every input, as the standard says).  A cycle of such edges is an
algebraic loop: at a communication point the outputs on it depend on themselves,
and the once-per-step exchange would pass it on unsolved (each value a step late).
The cycles are the strongly connected components of the variable graph
(scipy.sparse.csgraph), found once when the plan is made; the running layer solves
each at every communication point (:mod:`dsim.master.running.loops`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from dsim.master.reading.fmi_description import describe


@dataclass(frozen=True)
class Loop:
    """One algebraic loop: the connected inputs on it (component path, variable), in
    the order of the run's transfer, and a name for messages (``a.y -> b.u -> ...``)."""

    inputs: tuple[tuple[str, str], ...]
    label: str


def _feeds_directly(source, output: str, inputs: list[str]) -> list[str]:
    """The inputs of the FMU at ``source`` that ``output`` depends on directly."""
    dependencies = describe(source).dependencies.get(output)
    if dependencies is None:  # undeclared: every input, as the standard says
        return list(inputs)
    return [name for name in dependencies if name in inputs]


def find_loops(scene, links, chosen: dict) -> tuple[Loop, ...]:
    """The algebraic loops of the connections ``links`` (every-step Real ones) of
    ``scene``; ``chosen``: each component's interface (a Model Exchange FMU's output
    depends on its inputs through its states only where it declares so)."""
    moving = [link for link in links if link.every_step and link.kind == "Real"]
    if not moving:
        return ()
    index: dict = {}

    def node(variable) -> int:
        return index.setdefault(variable, len(index))

    edges = []
    inputs_of: dict[str, list[str]] = {}
    for link in moving:
        edges.append((node(link.start), node(link.end)))
        inputs_of.setdefault(link.end[0], []).append(link.end[1])
    for link in moving:  # inside each FMU whose output feeds a connection
        path, output = link.start
        if path not in inputs_of:
            continue
        source = scene.component(path).source
        for name in _feeds_directly(source, output, inputs_of[path]):
            edges.append((node((path, name)), node(link.start)))
    size = len(index)
    rows, cols = zip(*edges)
    graph = coo_matrix((np.ones(len(edges)), (rows, cols)), shape=(size, size))
    count, labels = connected_components(graph, directed=True, connection="strong")
    names = {i: v for v, i in index.items()}
    fed = {link.end for link in moving}
    loops = []
    for group in range(count):
        members = [names[i] for i in np.flatnonzero(labels == group)]
        if len(members) < 2:
            continue
        inputs = tuple(v for v in members if v in fed)
        order = [link.end for link in moving if link.end in inputs]
        names = [".".join(v) for v in members]
        label = " -> ".join(names) if len(names) <= 8 else (
            " -> ".join(names[:4]) + f" -> ... -> {names[-1]} ({len(names)} variables)")
        loops.append(Loop(tuple(order), label))
    return tuple(loops)
