"""A sweep's table, ``sweep.csv``, written and read back.

One whole row per finished point, as it finishes: ``point`` (its number, 1-based, the
same as its ``point_NNN.csv``), the varied settings and parameters, each KPI's value,
then :data:`MEASURES`.  Cells are written by Python's csv module (RFC 4180 quoting), so
a message with commas or quotes reads back as it was written, by this module, by a
spreadsheet or by pandas.
"""
from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field
from pathlib import Path

from dsim.master.recording.output_files import OutputFile
from dsim.master.sweeps.kpi import is_label

#: the columns of sweep.csv after the point's values and KPIs
MEASURES = ("status", "stable", "error", "wall_seconds", "iterations_per_step",
            "do_steps_per_fmu_step", "lambda_refreshes", "steps", "message")


@dataclass
class Point:
    """One configuration of a sweep and what it measured."""

    settings: dict
    status: str = ""
    stable: bool = False
    error: float = math.nan
    wall_seconds: float = math.nan
    iterations_per_step: float = math.nan
    do_steps_per_fmu_step: float = math.nan
    lambda_refreshes: int = 0
    steps: int = 0
    message: str = ""
    results: Path | None = None
    pareto: bool = False
    #: the point's number in its sweep (1-based: point_NNN.csv), 0 when it has none
    index: int = 0
    #: KPI label -> value (nan where the run gave none)
    kpis: dict = field(default_factory=dict)

    @property
    def label(self) -> str:
        """``name=value ...``, numbers drawn by a design to 6 digits (the table and
        design.json keep every digit)."""
        return " ".join(f"{k}={_short(v)}" for k, v in self.settings.items())

    @property
    def state(self) -> str:
        """Its one word of :data:`STATES` (:func:`state`)."""
        return state(self)

    @property
    def finished(self) -> bool:
        """Whether a rerun of the sweep keeps this point (an interrupted one, and one
        lost with a node of the cluster, runs again)."""
        return self.status not in ("", "interrupted", "lost")


#: one word per point's state, what each means: a point is in exactly one of them
STATES = {
    "completed": "ran to its stop time (and stayed within the reference where there is one)",
    "unstable": "ran to its stop time, but off the reference by more than its peak",
    "failed": "the run failed (its row says why)",
    "refused": "its settings or parameters were refused before it ran (bad input)",
    "interrupted": "stopped by SIGINT or SIGTERM; a rerun of the sweep runs it again",
    "lost": "lost with a node or the head of the Ray cluster; a rerun of the sweep runs it "
            "again",
}


def state(point: Point) -> str:
    """The one word of :data:`STATES` for ``point``."""
    if point.status == "completed":
        return "completed" if point.stable else "unstable"
    if point.status == "bad input":
        return "refused"
    return point.status if point.status in STATES else "failed"


def count_states(points) -> str:
    """``9 completed, 2 failed, 1 interrupted``: how many points are in each state."""
    counts = {word: 0 for word in STATES}
    for point in points:
        counts[state(point)] += 1
    return ", ".join(f"{n} {word}" for word, n in counts.items() if n) or "none"


def _cell(value) -> str:
    return repr(value) if isinstance(value, float) else str(value)


def row(point: Point, names: list[str], kpis: list[str]) -> list[str]:
    """The point's cells, in the table's order."""
    return ([str(point.index)] + [_cell(point.settings.get(n, "")) for n in names]
            + [_cell(point.kpis.get(k, math.nan)) for k in kpis]
            + [point.status, str(point.stable).lower(), repr(point.error),
               repr(point.wall_seconds), repr(point.iterations_per_step),
               repr(point.do_steps_per_fmu_step), str(point.lambda_refreshes),
               str(point.steps), point.message])


def _line(cells: list[str]) -> bytes:
    text = io.StringIO()
    csv.writer(text, lineterminator="\n").writerow(cells)
    return text.getvalue().encode()


class SweepTable:
    """``sweep.csv`` being written: the header, then one whole row per point."""

    def __init__(self, path: Path, names: list[str], inputs, kpis=()):
        self.names, self.kpis = list(names), list(kpis)
        self.output = OutputFile(path, inputs)
        self.output.open()
        self.output.append(_line(["point"] + self.names + self.kpis + list(MEASURES)))

    def add(self, point: Point) -> None:
        self.output.append(_line(row(point, self.names, self.kpis)), separator=b"\n")

    def close(self) -> None:
        self.output.commit()


def _float(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return math.nan


def parse_value(text: str):
    """A varied value read back: an int, a float, or the word."""
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def read_table(path: Path) -> tuple[list[str], list[str], list[Point]]:
    """(varied names, KPI labels, points) of a ``sweep.csv`` (or its temporary file
    while it is written); rows cut short are left out.  Empty when it cannot be read."""
    try:
        rows = list(csv.reader(io.StringIO(Path(path).read_text())))
    except (OSError, UnicodeDecodeError, csv.Error):
        return [], [], []
    if not rows or len(rows[0]) < len(MEASURES) or tuple(rows[0][-len(MEASURES):]) != MEASURES:
        return [], [], []
    header = rows[0]
    numbered = header[0] == "point"
    middle = header[1 if numbered else 0:len(header) - len(MEASURES)]
    kpis = [n for n in middle if is_label(n)]
    names = [n for n in middle if not is_label(n)]
    points = []
    for number, cells in enumerate(rows[1:], start=1):
        if len(cells) != len(header):
            continue  # a row still being written
        values = dict(zip(header, cells))
        try:
            points.append(Point(
                {n: parse_value(values[n]) for n in names if values[n] != ""},
                values["status"], values["stable"] == "true", _float(values["error"]),
                _float(values["wall_seconds"]), _float(values["iterations_per_step"]),
                _float(values["do_steps_per_fmu_step"]), int(values["lambda_refreshes"]),
                int(values["steps"]), values["message"],
                index=int(values["point"]) if numbered else number,
                kpis={k: _float(values[k]) for k in kpis}))
        except ValueError:
            continue  # not a row dsim wrote
    return names, kpis, points


def markdown(points: list[Point], names: list[str], reference: str, kpis=()) -> str:
    """The sweep's table, Pareto points marked (where errors were measured)."""
    errors = any(math.isfinite(p.error) for p in points)
    head = (f"Reference: {reference}. Error: the largest difference of any compared column "
            "over the run, relative to that column's peak in the reference." if errors else
            "No error measured (model parameters vary: give --reference to measure one).")
    columns = (["point"] + list(names) + list(kpis) + ["status"]
               + (["error"] if errors else []) + ["wall (s)", "iterations per step",
                                                  "doSteps per FMU per step"]
               + (["Pareto"] if errors else []))
    lines = [head, "", "| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    for p in points:
        cells = ([str(p.index)] + [_short(p.settings.get(n, "")) for n in names]
                 + [f"{p.kpis.get(k, math.nan):.4g}" for k in kpis]
                 + [state(p)]
                 + ([f"{p.error:.2e}"] if errors else [])
                 + [f"{p.wall_seconds:.3f}", f"{p.iterations_per_step:.2f}",
                    f"{p.do_steps_per_fmu_step:.2f}"]
                 + (["yes" if p.pareto else ""] if errors else []))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _short(value) -> str:
    return f"{value:.6g}" if isinstance(value, float) else str(value)
