"""Causal SSP connections, resolved once into index arrays.

Every subsystem reads one batch of variables after each step (its recorded
outputs and the sources of its outgoing connections): the run's flat output
vector is their concatenation.  A connection is then an index into that vector
and a linear transformation, and each macro step moves every connection with one
gather, one multiply-add and one batched write per receiving subsystem.
"""
from __future__ import annotations

import numpy as np


class Transfer:
    """Input values for the causal connections: ``outputs[gather] * factor + offset``,
    split per receiving subsystem (``targets``: (subsystem index, start, stop))."""

    def __init__(self, gather, factor, offset, targets):
        self.gather = np.asarray(gather, dtype=int)
        self.factor = np.asarray(factor, dtype=float)
        self.offset = np.asarray(offset, dtype=float)
        self.targets = tuple(targets)
        #: number of connections
        self.size = len(self.gather)
        #: whether every connection copies its value unchanged
        self.identity = bool(np.all(self.factor == 1.0) and np.all(self.offset == 0.0))

    def inputs(self, outputs: np.ndarray) -> list[tuple[int, np.ndarray]]:
        """(subsystem index, its input values) from the flat output vector."""
        values = outputs[self.gather]
        if not self.identity:
            values = values * self.factor + self.offset
        return [(index, values[start:stop]) for index, start, stop in self.targets]

    def restricted(self, indices) -> "Transfer":
        """The connections into the subsystems at ``indices``, numbered by their
        position in ``indices`` (for a backend subset)."""
        position = {index: local for local, index in enumerate(indices)}
        gather, factor, offset, targets = [], [], [], []
        for index, start, stop in self.targets:
            if index in position:
                targets.append((position[index], len(gather), len(gather) + stop - start))
                gather.extend(self.gather[start:stop])
                factor.extend(self.factor[start:stop])
                offset.extend(self.offset[start:stop])
        return Transfer(np.array(gather, dtype=int), np.array(factor, dtype=float),
                        np.array(offset, dtype=float), tuple(targets))


def build_transfer(components: list[str], reads: dict[str, list[str]],
                   connections: list) -> tuple[Transfer, dict[str, list[str]]]:
    """The transfer of ``connections`` ((start component, variable, end component,
    variable, factor, offset) each) over the flat outputs of ``reads`` (component ->
    variables read after each step, in order), and the inputs each component has
    written (component -> variables, the order of its input vector)."""
    offsets, position = {}, 0
    for component in components:
        offsets[component] = position
        position += len(reads[component])
    by_target: dict[str, list] = {c: [] for c in components}
    for start, start_name, end, end_name, factor, offset in connections:
        source = offsets[start] + reads[start].index(start_name)
        by_target[end].append((end_name, source, factor, offset))
    gather, factors, offsets_, targets, writes = [], [], [], [], {}
    for index, component in enumerate(components):
        entries = by_target[component]
        writes[component] = [name for name, _, _, _ in entries]
        if entries:
            targets.append((index, len(gather), len(gather) + len(entries)))
        for _, source, factor, offset in entries:
            gather.append(source)
            factors.append(factor)
            offsets_.append(offset)
    transfer = Transfer(np.array(gather, dtype=int), np.array(factors, dtype=float),
                        np.array(offsets_, dtype=float), tuple(targets))
    return transfer, writes
