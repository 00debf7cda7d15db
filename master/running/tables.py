"""Input tables in a run: a table component (an SSP Component whose source is a .csv or
.mat file, or the table of ``--input``) is a :class:`TableSubsystem`, a source with no
FMU whose outputs are its columns at its time, run in process wherever the backend runs
its subsystems (a Ray worker too: its spec carries the table).

What a column gives at time t (s), FMPy's conventions for input tables:

- a **continuous** column (one that feeds continuous Real inputs, and every column of a
  table component) is interpolated linearly between the rows around t;
- a **held** column (one that feeds an Integer, Boolean or Enumeration input, or a
  discrete Real one) gives the value of the last row at or before t;
- a time given on two rows is a jump: before it the first row's value, at and after it
  the second's (the values are right-continuous);
- before the first row and after the last, the first and last values are held.

A time within round-off of a row's time (``math.isclose``, relative 1e-9, as FMPy
compares them) counts as that row's: a communication point ``start + n * step`` that
lands a hair before a jump is at the jump.

Why not ``fmpy.simulation.Input.interpolate``: it is written for one FMU's inputs of one
kind at a time, and at a jump at the table's very first time it gives the value before
the jump (its ``i0 == 0`` branch runs before its event test).  The rules here are FMPy's
otherwise, with its weights ``w0 v0 + w1 v1`` (a row's time gives that row's value
exactly).

A connection moves a column's value at the start of each macro step (the outputs read
at a communication point feed the inputs of the step that starts there); the table's
value at the step's end (its left limit there) gives the slope over the step to the FMUs
that take one (:func:`left_values`; :mod:`dsim.master.running.fmi.table_inputs`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dsim.master.running.subsystem import Subsystem

#: relative tolerance (FMPy's, math.isclose's default) within which a time is a row's
ROUND_OFF = 1e-9


@dataclass(frozen=True, eq=False)
class TableData:
    """What a table subsystem needs wherever it runs (picklable): ``times`` (s, n rows,
    not decreasing), ``values`` (one row of n values per column it outputs, in the
    spec's ``reads`` order) and ``held`` (per column: True where the value is held from
    the last row, False where it is interpolated)."""

    times: np.ndarray
    values: np.ndarray
    held: tuple[bool, ...]


def _snapped(times: np.ndarray, t: float) -> float:
    """``t``, or the time of the row nearest it when it is within round-off of it."""
    k = int(np.searchsorted(times, t))
    for j in (k - 1, k):
        if 0 <= j < len(times) and abs(times[j] - t) <= ROUND_OFF * max(abs(t), abs(times[j])):
            return float(times[j])
    return t


def values_at(data: TableData, t: float, held=None) -> np.ndarray:
    """Every column's value at ``t`` (s), right-continuous (at a jump, the value after
    it); ``held``: a boolean mask of the columns held (default: the data's)."""
    times, values = data.times, data.values
    held = np.asarray(data.held if held is None else held, dtype=bool)
    t = _snapped(times, t)
    last = len(times) - 1
    j = int(np.searchsorted(times, t, side="right")) - 1  # the last row at or before t
    if j < 0:
        return values[:, 0].copy()
    if j >= last:
        return values[:, last].copy()
    return _between(times, values, held, j, t)


def left_values(data: TableData, t: float) -> np.ndarray:
    """Every column's value just before ``t`` (s): its left limit (at a jump, the value
    before it; a held column, the last row strictly before t).  A step that ends at t
    ramps to these values."""
    times, values = data.times, data.values
    held = np.asarray(data.held, dtype=bool)
    t = _snapped(times, t)
    last = len(times) - 1
    j = int(np.searchsorted(times, t, side="left")) - 1  # the last row before t
    if j < 0:
        return values[:, 0].copy()
    if j >= last:
        return values[:, last].copy()
    return _between(times, values, held, j, t)


def _between(times, values, held, j: int, t: float) -> np.ndarray:
    """The values at ``t`` in [times[j], times[j + 1]] (times[j] < times[j + 1]):
    linear for the interpolated columns, row j for the held ones."""
    t0, t1 = times[j], times[j + 1]
    w0 = (t1 - t) / (t1 - t0)
    w1 = 1.0 - w0
    result = w0 * values[:, j] + w1 * values[:, j + 1]
    result[held] = values[held, j]
    return result


class TableSubsystem(Subsystem):
    """A table component as a subsystem: no FMU, no input, no port; its outputs
    (``spec.reads``, columns of the table) are the table's values at its time; a
    step moves its time; its state is its time (saved, restored and carried in a Ray
    worker's checkpoint)."""

    SAVED = ("_saved",)

    def __init__(self, spec):
        super().__init__()
        self.name = spec.name
        self.spec = spec
        self.data: TableData = spec.table
        self.output_names = tuple(spec.reads)
        self.time = spec.start_time
        self._saved = None

    def save_state(self) -> None:
        self._saved = self.time

    def restore_state(self) -> None:
        self.time = self._saved

    def set_forces(self, forces) -> None:
        """A table has no port: nothing to set."""

    def do_step(self, time: float, step_size: float) -> None:
        self.counters["step"][0] += 1  # counted as a step in the statistics
        self.time = time + step_size

    def kinematics(self):
        empty = np.zeros(0)
        return empty, empty, empty

    def read_outputs(self) -> np.ndarray:
        return values_at(self.data, self.time)

    def set_values(self, names, values) -> None:
        """A table has nothing a scenario can set (the plan refuses it)."""
        raise NotImplementedError(f"table '{self.name}' has no variable to set")

    # --- a Ray worker's checkpoint: the time is the whole state ---------------------
    def checkpoint(self) -> dict:
        """The state the last :meth:`save_state` saved (the time now, where none was)."""
        return {"time": self.time if self._saved is None else self._saved}

    def resume(self, state: dict) -> None:
        self.time = self._saved = state["time"]
