"""What a run records: which columns (``outputs``: glob patterns) and how often
(``output_interval``: a whole multiple of the macro step).

A finite-element scene records every free output of its FMUs by default, thousands
of columns a step; these two choices keep the CSV, the in-memory result and the plot
to what a study needs.  They choose among the values the run computes anyway: the
run itself (its steps, its checks of every output for non-finite values) is the same.

Rows are recorded at exact communication points of the master, never interpolated:
the start time, every ``k``-th macro step (``output_interval = k * step``), and the
last converged step (the stop time, or where a failed or interrupted run ended), so
that every run's file ends with its final state.
"""
from __future__ import annotations

import difflib
import math
import re
from fnmatch import fnmatchcase
from functools import lru_cache

import numpy as np


@lru_cache(maxsize=256)
def _literal_brackets(pattern: str) -> str:
    # brackets are part of dsim's column names (x[2]): each one matches itself
    return re.sub(r"([\[\]])", r"[\1]", pattern)


def column_matches(name: str, pattern: str) -> bool:
    """Whether results column ``name`` is the one ``pattern`` names (``right.x[2]``) or
    one of those its glob names (``*`` and ``?`` are wildcards: ``j1.*``, ``right.x[*]``;
    brackets are literal, not a glob class).  The one rule for ``--outputs``, ``dsim
    plot`` and ``--kpi``."""
    return name == pattern or fnmatchcase(name, _literal_brackets(pattern))


def select_columns(patterns, columns, text_columns) -> tuple[np.ndarray | None,
                                                                tuple[int, ...] | None,
                                                                list[str]]:
    """The indices of the numeric ``columns`` and of the ``text_columns`` that match
    one of ``patterns`` (None, None: no patterns, everything), and one problem per
    pattern that matches nothing (naming the closest columns)."""
    patterns = [patterns] if isinstance(patterns, str) else list(patterns or ())
    if not patterns:
        return None, None, []
    problems = []
    every = list(columns) + list(text_columns)
    for pattern in patterns:
        if not isinstance(pattern, str) or not pattern.strip():
            problems.append(f"outputs: pattern {pattern!r} is not a column name or glob")
        elif not any(column_matches(name, pattern) for name in every):
            close = difflib.get_close_matches(pattern, every[:50000], n=3, cutoff=0.4)
            problems.append(f"outputs: pattern '{pattern}' matches no recorded column"
                            + (f" (closest: {', '.join(close)})" if close else
                               f" (columns: {', '.join(every[:6])}"
                               f"{', ...' if len(every) > 6 else ''})"))
    if problems:
        return None, None, problems
    chosen = [i for i, name in enumerate(columns)
              if any(column_matches(name, p) for p in patterns)]
    texts = tuple(i for i, name in enumerate(text_columns)
                  if any(column_matches(name, p) for p in patterns))
    return np.array(chosen, dtype=int), texts, []


def record_every(interval, step: float) -> tuple[int, str | None]:
    """How many macro steps apart rows are recorded for ``output_interval`` (s), and
    the problem with it (None: fine).  The interval must be a whole multiple of the
    step (to 1e-9 relative), so that every recorded row is a point the master lands
    on: a coarser grid that is not one would need interpolation, which dsim refuses
    (it would put values in the file that no FMU computed)."""
    if interval is None:
        return 1, None
    try:
        if isinstance(interval, bool):
            raise ValueError
        value = float(interval)
    except (TypeError, ValueError):
        return 1, f"output_interval '{interval}' is not a number"
    if not (math.isfinite(value) and value > 0):
        return 1, f"output_interval must be a finite number greater than 0, got {interval}"
    k = round(value / step)
    if k < 1 or not math.isclose(k * step, value, rel_tol=1e-9):
        below = max(math.floor(value / step), 1)
        return 1, (f"output_interval {value:g} s is not a whole multiple of the macro step "
                   f"{step:g} s: rows are recorded only where the master lands (try "
                   f"{below * step:g} or {(below + 1) * step:g} s)")
    return k, None


def recorded_rows(planned_steps: int, every: int) -> int:
    """Rows a completed run records: the start, every ``every``-th step, the last."""
    return 1 + planned_steps // every + (1 if planned_steps % every else 0)
