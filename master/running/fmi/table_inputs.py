"""The continuous Real inputs an FMU takes from a table (an SSP table component, or
``--input``), followed within each macro step where the FMU can follow them.

A connection gives every input the table's value at the start of the step (the
outputs read at a communication point feed the step that starts there).  A table knows
its future, so an FMU that can take more gets the line from that value to the table's
value at the step's end (its left limit there: a jump at the end is the next step's):

- a **Model Exchange** FMU, which dsim integrates, sees the line at every time its
  integrator evaluates it: the table itself wherever no row falls inside the step, its
  chord across a row that does;
- an **FMI 2.0 co-simulation FMU that declares canInterpolateInputs** gets the line's
  slope, ``fmi2SetRealInputDerivatives`` (order 1), before each step.

The chord (the end's value minus the start's, over the step) rather than FMPy's slope
of the row segment at the step's start: the input then ends each step where the next
one starts, a continuous line through the table's values at the communication points,
where the segment's slope would overshoot across a row and jump back at the next step.
Any other FMU holds the step's start value, as FMPy feeds an FMU that cannot
interpolate.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dsim.master.reading.fmi_description import CO_SIMULATION, MODEL_EXCHANGE
from dsim.master.running.tables import TableData, left_values, values_at


def follows_table(description, interface: str | None) -> bool:
    """Whether an FMU run through ``interface`` can follow a table within a step:
    Model Exchange (dsim integrates it), or FMI 2.0 co-simulation with
    canInterpolateInputs."""
    if interface == MODEL_EXCHANGE:
        return True
    found = description.interface(CO_SIMULATION)
    return (interface == CO_SIMULATION and description.major == 2 and found is not None
            and found.canInterpolateInputs)


@dataclass(frozen=True, eq=False)
class TableInputs:
    """The table-fed inputs of one FMU (picklable): ``entries`` are (place among the
    spec's ``writes``, the table's times, the column's values, the connection's factor,
    its offset), the input = factor * column + offset."""

    entries: tuple

    @property
    def places(self) -> list[int]:
        """Where the inputs are among the spec's ``writes``."""
        return [entry[0] for entry in self.entries]

    def _data(self) -> list[tuple[TableData, float, float]]:
        data = self.__dict__.get("_made")
        if data is None:
            data = [(TableData(times, np.asarray(column, dtype=float).reshape(1, -1),
                               (False,)), factor, offset)
                    for _, times, column, factor, offset in self.entries]
            object.__setattr__(self, "_made", data)
        return data

    def ends(self, time: float, step_size: float) -> tuple[np.ndarray, np.ndarray]:
        """The inputs' values at the start ``time`` (s) of a step of ``step_size`` (s)
        and at its end (the left limit there), as the connections convert them."""
        start = np.empty(len(self.entries))
        end = np.empty(len(self.entries))
        for k, (data, factor, offset) in enumerate(self._data()):
            start[k] = values_at(data, time)[0] * factor + offset
            end[k] = left_values(data, time + step_size)[0] * factor + offset
        return start, end

    def slopes(self, time: float, step_size: float) -> np.ndarray:
        """The inputs' slopes (per s) over a step from ``time`` by ``step_size`` (s)."""
        start, end = self.ends(time, step_size)
        return (end - start) / step_size
