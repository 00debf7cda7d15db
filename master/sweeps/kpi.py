"""Quantities of interest of a run: ``--kpi REDUCTION(COLUMNS)``, parsed, never evaluated.

The grammar is one reduction applied to one column pattern::

    kpi       := reduction "(" pattern ")"
    reduction := max | min | maxabs | mean | rms | final | argmax | argmin
    pattern   := a results column ("right.x[2]") or a glob of columns ("*.f_x")

``max``, ``min``, ``mean``: of the values, in the column's unit; ``maxabs``: the largest
absolute value; ``rms``: the root mean square over the recorded rows (each row weighs
the same: on dsim's uniform macro-step grid that is the time average); ``final``: the
value at the last recorded time; ``argmax``, ``argmin``: the time (s) of the largest or
smallest value (its first occurrence).  A glob matching several columns pools their
values: ``maxabs(*.f_x)`` is the largest x force of any joint, ``argmax`` the time of the
largest value of any of them; ``final`` needs exactly one column.  A pattern is a glob
only where it has ``*`` or ``?``: brackets are read literally, so ``x[2]`` names the
column ``x[2]``.
"""
from __future__ import annotations

import difflib
import math
import re
from dataclasses import dataclass

import numpy as np

from dsim.master.errors import InputError
from dsim.master.recording.selection import column_matches

REDUCTIONS = ("max", "min", "maxabs", "mean", "rms", "final", "argmax", "argmin")
_FORM = re.compile(r"\s*([a-z]+)\s*\(\s*(.+?)\s*\)\s*")


@dataclass(frozen=True)
class Kpi:
    """One quantity of interest: ``reduction`` of the columns matching ``pattern``."""

    reduction: str
    pattern: str

    @property
    def label(self) -> str:
        """Its column name in the sweep's table: ``max(right.x[2])``."""
        return f"{self.reduction}({self.pattern})"

    def columns(self, names) -> list[str]:
        """The columns of ``names`` the pattern names."""
        # a glob pools result columns, not the time axis; "time" by name is itself
        return [n for n in names if column_matches(n, self.pattern)
                and (n != "time" or n == self.pattern)]

    def value(self, signals: dict) -> float:
        """The KPI of a run's signals (``{"time": array, column: array}``); ValueError
        saying why it has none (no matching column, no rows, a text column)."""
        names = self.columns(signals)
        if not names:
            raise ValueError(f"{self.label}: no column matches '{self.pattern}'")
        if self.reduction == "final" and len(names) > 1:
            raise ValueError(f"{self.label}: final needs one column; '{self.pattern}' "
                             f"matches {len(names)} ({', '.join(names[:4])} ...)")
        try:
            values = np.stack([np.asarray(signals[n], dtype=float) for n in names])
        except (TypeError, ValueError):
            raise ValueError(f"{self.label}: a matched column holds text") from None
        if values.shape[1] == 0:
            raise ValueError(f"{self.label}: the run recorded no rows")
        return reduce(self.reduction, values, np.asarray(signals["time"], dtype=float))


def reduce(reduction: str, values: np.ndarray, times: np.ndarray) -> float:
    """``reduction`` of ``values`` (columns, rows) recorded at ``times`` (rows, s)."""
    if reduction == "max":
        return float(np.max(values))
    if reduction == "min":
        return float(np.min(values))
    if reduction == "maxabs":
        return float(np.max(np.abs(values)))
    if reduction == "mean":
        return float(np.mean(values))
    if reduction == "rms":
        return float(math.sqrt(np.mean(np.square(values))))
    if reduction == "final":
        return float(values[0, -1])
    # argmax, argmin: the time of the first extreme over every matched column
    flat = np.argmax(values) if reduction == "argmax" else np.argmin(values)
    return float(times[np.unravel_index(flat, values.shape)[1]])


def parse(text: str) -> Kpi:
    """The KPI of ``--kpi TEXT``; InputError with the grammar when it is not one."""
    match = _FORM.fullmatch(text)
    if not match or match.group(1) not in REDUCTIONS:
        raise InputError(f"--kpi {text}: write REDUCTION(COLUMN), REDUCTION one of "
                         f"{', '.join(REDUCTIONS)}, COLUMN a results column or a glob "
                         "(max(right.x[2]), maxabs(*.f_x))")
    return Kpi(match.group(1), match.group(2))


def parse_all(texts) -> list[Kpi]:
    """Every ``--kpi`` (InputError listing each bad one; a KPI given twice kept once)."""
    kpis, problems = [], []
    for text in texts:
        try:
            kpis.append(parse(text))
        except InputError as error:
            problems += error.problems
    if problems:
        raise InputError(problems)
    return list(dict.fromkeys(kpis))


def unresolved(kpis, names) -> list[str]:
    """One problem per KPI of ``kpis`` whose pattern matches none of the columns
    ``names`` a run of the scene records (naming the closest), or whose ``final``
    matches more than one: what ``dsim sweep`` refuses before its first point, as
    ``dsim run --outputs`` does."""
    names = list(names)
    problems = []
    for kpi in kpis:
        found = kpi.columns(names)
        if not found:
            close = difflib.get_close_matches(kpi.pattern, names[:50000], n=3, cutoff=0.4)
            problems.append(f"--kpi {kpi.label}: no recorded column matches '{kpi.pattern}'"
                            + (f" (closest: {', '.join(close)})" if close else
                               f" (columns: {', '.join(names[:6])}"
                               f"{', ...' if len(names) > 6 else ''})"))
        elif kpi.reduction == "final" and len(found) > 1:
            problems.append(f"--kpi {kpi.label}: final needs one column; '{kpi.pattern}' "
                            f"matches {len(found)} ({', '.join(found[:4])}"
                            f"{' ...' if len(found) > 4 else ''})")
    return problems


def is_label(name: str) -> bool:
    """Whether a sweep table's column name is a KPI's label."""
    match = _FORM.fullmatch(name)
    return bool(match) and match.group(1) in REDUCTIONS
