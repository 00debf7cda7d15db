"""The results of a run (DESIGN.md, "Results contract"): the :class:`RunResult`
that :func:`dsim.simulate` returns, reading a results CSV back, and plots."""
from __future__ import annotations

import csv
import difflib
import io
import json
import re
import signal as signals_module
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dsim.master.errors import InputError

STATUSES = ("completed", "failed", "interrupted")


@dataclass
class RunResult:
    """How a run ended and what it produced (returned also when it failed).

    ``status`` is completed, failed or interrupted; ``message`` says why it failed
    or stopped; ``time`` is the last converged time (s) and ``steps`` the number of
    converged macro steps; ``statistics`` is the statistics JSON's content;
    ``files`` maps what was written ("csv", "statistics", "plot") to its path.
    ``signals`` maps every column (``time``, ``component.variable``,
    ``joint.f_dof``) to its values over time.
    """

    status: str
    message: str
    time: float
    steps: int
    statistics: dict = field(default_factory=dict)
    files: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    error: Exception | None = None
    #: the signal (SIGINT, SIGTERM) that interrupted the run, if one did
    signal: int | None = None
    _signals: object = None

    @property
    def ok(self) -> bool:
        """Whether the run reached its stop time."""
        return self.status == "completed"

    @property
    def exit_code(self) -> int:
        """The command line's exit code: 0, 1 (failed), 128 + signal (interrupted)."""
        if self.status == "completed":
            return 0
        if self.status == "interrupted":
            return 128 + (self.signal or signals_module.SIGINT)
        return 1

    @property
    def signals(self) -> dict[str, np.ndarray]:
        """Column -> values over time (read from the CSV when the run wrote one)."""
        if callable(self._signals):
            self._signals = self._signals()
        if self._signals is None and "csv" in self.files:
            self._signals = read_columns(self.files["csv"])
        return self._signals or {}

    def keep_signals(self, signals=None) -> None:
        """Hold the signals: ``signals`` (a mapping, or a callable that makes it when
        first asked for) where the result has none yet; None: read the results CSV
        now, so that the result keeps them when its files go."""
        if signals is None:
            self._signals = self.signals
        elif self._signals is None:
            self._signals = signals

    def __getitem__(self, column: str) -> np.ndarray:
        """The values of ``column`` over time; :class:`MissingColumn` (a KeyError)
        naming the closest columns when the run recorded none of that name."""
        signals = self.signals
        try:
            return signals[column]
        except (KeyError, TypeError):
            raise MissingColumn(column, list(signals)) from None

    def to_pandas(self):
        """The signals as a pandas DataFrame indexed by ``time`` (s), one column per
        recorded column (numbers as floats, String outputs as objects).  pandas is
        optional: ImportError saying how to install it when it is absent."""
        try:  # optional: dsim itself needs no pandas
            import pandas
        except ImportError:
            raise ImportError("RunResult.to_pandas needs pandas, which dsim does not "
                              "install: pip install pandas (or use result.signals, a dict "
                              "of numpy arrays)") from None
        signals = self.signals
        if not signals:
            return pandas.DataFrame(index=pandas.Index([], name="time", dtype=float))
        frame = pandas.DataFrame({n: v for n, v in signals.items() if n != "time"},
                                 index=pandas.Index(signals["time"], name="time"))
        return frame


class MissingColumn(KeyError):
    """A results column a run did not record: the message names the closest ones."""

    def __init__(self, column, columns):
        super().__init__(column)
        self.column = column
        close = difflib.get_close_matches(str(column), [c for c in columns][:50000], n=3,
                                          cutoff=0.4)
        self.closest = close
        self.message = (f"no column '{column}' in the results"
                        + (f" (closest: {', '.join(close)})" if close else
                           f" (columns: {', '.join(list(columns)[:6])}"
                           f"{', ...' if len(columns) > 6 else ''})" if columns else
                           " (the run recorded no columns)"))

    def __str__(self) -> str:
        return self.message


def _table(path) -> tuple[list[str], list[list[str]]]:
    """Header and rows of a results CSV, checked: InputError for a file that is not
    one (no ``time`` column, a row of the wrong length, a last row cut short)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    with open(path, newline="") as file:
        text = file.read()
    if text and not text.endswith("\n"):
        raise InputError(f"{path}: the last row is incomplete (no line end): the file was "
                         "cut short while it was written")
    rows = list(csv.reader(io.StringIO(text)))
    if not rows or not rows[0] or rows[0][0] != "time":
        raise InputError(f"{path}: not a dsim results CSV (no 'time' column)")
    for number, row in enumerate(rows[1:], start=2):
        if len(row) != len(rows[0]):
            raise InputError(f"{path} line {number}: {len(row)} values for "
                             f"{len(rows[0])} columns")
    return rows[0], rows[1:]


def read_columns(path) -> dict[str, np.ndarray]:
    """Every column of a results CSV over time: numbers as float arrays, the columns
    of String outputs as arrays of str."""
    header, rows = _table(path)
    columns = {}
    for i, name in enumerate(header):
        values = [row[i] for row in rows]
        try:
            columns[name] = np.array([float(v) for v in values], dtype=float)
        except ValueError:
            if name == "time":
                raise InputError(f"{path}: a time that is not a number") from None
            columns[name] = np.array(values, dtype=object)
    return columns


def read_csv(path) -> tuple[list[str], np.ndarray]:
    """Column names and the data of a results CSV of numbers (rows x columns);
    InputError for a file that is not one (see :func:`read_columns` for a CSV with
    String columns)."""
    columns = read_columns(path)
    texts = [name for name, values in columns.items() if values.dtype == object]
    if texts:
        raise InputError(f"{path}: columns {', '.join(texts)} hold text, not numbers")
    header = list(columns)
    return header, np.column_stack([columns[n] for n in header]).reshape(-1, len(header))


#: what a unit measures, for a panel's axis label (other units show as themselves)
QUANTITIES = {"m": "position", "m/s": "velocity", "m/s2": "acceleration", "rad": "angle",
              "rad/s": "angular velocity", "rad/s2": "angular acceleration", "N": "force",
              "N.m": "moment", "s": "time", "kg": "mass", "Pa": "stress", "J": "energy",
              "W": "power", "K": "temperature", "V": "voltage", "A": "current",
              # the display units of dsim's FMUs and those dsim knows (reading/units.py)
              "deg": "angle", "deg/s": "angular velocity", "deg/s2": "angular acceleration",
              "rpm": "angular velocity", "MPa": "stress", "degC": "temperature"}
#: most panels of one figure, and most curves of one panel (more is unreadable)
MAX_PANELS = 6
MAX_CURVES = 8


@dataclass
class Panel:
    """One axis of a plot: the signals of one unit.  ``names``: those drawn,
    ``left_out``: how many more of this unit the panel does not draw."""

    unit: str
    names: list
    left_out: int = 0
    #: the label of a panel of columns whose units nobody recorded
    unknown: str = "no unit declared"

    @property
    def label(self) -> str:
        """The y axis label: the quantity and its unit ('position (m)')."""
        if not self.unit:
            return self.unknown
        quantity = QUANTITIES.get(self.unit)
        return f"{quantity} ({self.unit})" if quantity else f"({self.unit})"


def unit_panels(names, units: dict | None, max_curves: int = MAX_CURVES,
                max_panels: int = MAX_PANELS) -> tuple[list[Panel], list[str]]:
    """Group the columns ``names`` by unit (``units``: column -> unit; '' or missing:
    none declared), one :class:`Panel` per unit in the order the units first appear,
    each drawing at most ``max_curves`` columns; past ``max_panels`` the columns of the
    remaining units are returned as left out (second item)."""
    groups: dict[tuple, list] = {}
    for name in names:
        if units:
            key = (units.get(name) or "", "no unit declared")
        else:  # a CSV without its statistics: joint forces apart, by their names
            key = ("", "joint forces (units not recorded)" if ".f_" in name
                   else "outputs (units not recorded)")
        groups.setdefault(key, []).append(name)
    panels = [Panel(unit, columns[:max_curves], max(0, len(columns) - max_curves), unknown)
              for (unit, unknown), columns in groups.items()]
    left = [n for key in list(groups)[max_panels:] for n in groups[key]]
    return panels[:max_panels], left


def set_title(scene: str, parameters: dict | None = None, width: int = 100) -> str:
    """A figure title: the scene and the values given for the run (``--set``), cut to
    about ``width`` characters a line, three lines at most."""
    values = []
    for name, value in (parameters or {}).items():
        value = value[0] if isinstance(value, (list, tuple)) and len(value) == 1 else value
        values.append(f"{name}={value:g}" if isinstance(value, float) else f"{name}={value}")
    if not values:
        return scene
    lines, line = [], f"{scene}: --set"
    for value in values:
        if len(line) + len(value) + 1 > width:
            lines.append(line)
            line = " "
        line += " " + value
    lines.append(line)
    return "\n".join(lines[:3]) + (" ..." if len(lines) > 3 else "")


def in_display_units(signals: dict, units: dict | None,
                     display: dict | None) -> tuple[dict, dict | None]:
    """``signals`` and their ``units`` (column -> unit) with every column that has a
    display unit (``display``: column -> {"unit", "factor", "offset"}, the statistics'
    "display_units") shown in it: value * factor + offset, an angle in rad as deg."""
    if not display:
        return signals, units
    shown, units = dict(signals), dict(units or {})
    for name, to in display.items():
        values = shown.get(name)
        if values is None or values.dtype == object:
            continue
        shown[name] = values * float(to["factor"]) + float(to.get("offset", 0.0))
        units[name] = str(to["unit"])
    return shown, units


def _panels(panels, png_path, title: str = "", note: str = "") -> None:
    """Panels over time, one under the other, legends right of the data: ``panels`` is
    a list of (y label, [(curve label, time, values[, matplotlib style]), ...], what
    the panel leaves out ('' for nothing)); ``note``: a line under the figure."""
    import matplotlib  # only when a plot is asked for: it takes a third of a second
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # only when a plot is asked for

    count = max(len(panels), 1)
    figure, axes = plt.subplots(count, 1, sharex=True, squeeze=False, layout="constrained",
                                figsize=(9.5, 2.3 * count + 0.9 + 0.2 * title.count("\n")))
    for axis, (label, curves, left_out) in zip(axes[:, 0], panels):
        for name, time, values, *style in curves:
            axis.plot(time, values, label=name, linewidth=1.2, **(style[0] if style else {}))
        axis.set_ylabel(label, fontsize=9)
        axis.grid(True, alpha=0.3)
        axis.tick_params(labelsize=8)
        # outside the data, on the right: a legend never covers a curve
        axis.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0),
                    borderaxespad=0.0, frameon=False)
        if left_out:
            axis.set_title(left_out, fontsize=7, loc="right", color="0.35")
    axes[-1, 0].set_xlabel("time (s)")
    if title:
        figure.suptitle(title, fontsize=10)
    if note:
        figure.supxlabel(note, fontsize=7, color="0.35")
    save_figure(figure, png_path)


def _left_out_text(panel: Panel) -> str:
    if not panel.left_out:
        return ""
    return (f"{len(panel.names)} of {len(panel.names) + panel.left_out} curves drawn "
            "(choose with --outputs)")


def plot_signals(signals: dict, png_path, title: str = "", max_curves: int = MAX_CURVES,
                 units: dict | None = None) -> list[Panel]:
    """One panel per unit (positions, velocities, forces, angles ...), each with at
    most ``max_curves`` curves and a note of how many it leaves out; ``units``: column
    -> unit (the statistics JSON's "units"); ``png_path`` is a path or a binary file
    object.  Returns the panels drawn."""
    time = signals["time"]
    names = [n for n in signals if n != "time" and signals[n].dtype != object]
    panels, left = unit_panels(names, units, max_curves)
    note = ""
    if left:
        note = (f"{len(left)} more columns in other units not drawn "
                f"({', '.join(dict.fromkeys((units or {}).get(n) or '-' for n in left))}): "
                "choose with --outputs")
    _panels([(panel.label, [(n, time, signals[n]) for n in panel.names],
              _left_out_text(panel)) for panel in panels], png_path, title, note)
    return panels


#: line styles that tell the results of an overlay apart (colours tell the curves)
STYLES = ("-", "--", ":", "-.")


def overlay_curves(results: dict, names: list[str]) -> list[tuple]:
    """The curves of one panel of an overlay: each signal of ``names`` from each result
    (``results``: label -> signals) that has it, as (legend label, time, values,
    matplotlib style): every curve of the panel its own colour (the runs of one signal
    too), and one line style per result."""
    several = len(results) > 1
    curves = []
    for name in names:
        for j, (label, signals) in enumerate(results.items()):
            if name in signals:
                curves.append((f"{name} ({label})" if several else name, signals["time"],
                               signals[name], {"color": f"C{len(curves) % 10}",
                                               "linestyle": STYLES[j % len(STYLES)]}))
    return curves


def plot_overlay(results: dict, names: list[str], png_path, title: str = "",
                 units: dict | None = None, max_curves: int = MAX_CURVES) -> list[Panel]:
    """The signals ``names`` of several runs (``results``: label -> signals) in one
    panel per unit, as :func:`plot_signals` groups them: every curve of a panel its own
    colour, one line style per result (:func:`overlay_curves`), at most ``max_curves``
    signals a panel.  Returns the panels drawn."""
    panels, left = unit_panels(names, units, max_curves)
    drawn = []
    for panel in panels:
        text = _left_out_text(panel).replace("--outputs", "their names")
        drawn.append((panel.label, overlay_curves(results, panel.names), text))
    note = (f"{len(left)} more signals in other units not drawn: choose them by name"
            if left else "")
    _panels(drawn, png_path, title, note)
    return panels


def matlab_names(columns) -> list[str]:
    """Valid, distinct MATLAB identifiers for column names (``right.x[2]`` ->
    ``right_x_2``)."""
    result, seen = [], set()
    for column in columns:
        name = re.sub(r"[^0-9A-Za-z_]", "_", column).strip("_") or "signal"
        if not name[0].isalpha():
            name = "s_" + name
        name = name[:60]
        candidate, k = name, 2
        while candidate in seen:
            candidate, k = f"{name}_{k}", k + 1
        seen.add(candidate)
        result.append(candidate)
    return result


def mat_bytes(signals: dict, units: dict | None = None) -> bytes:
    """A MATLAB .mat (version 5) file of the signals: ``time``, ``data`` (one column
    per numeric signal), ``names`` (their column names), ``units`` (the unit of each
    column of ``data``, '' where none is declared; ``units``: column -> unit),
    ``time_unit`` and a struct ``signals`` with one field per signal, String ones as
    cell arrays (names made valid identifiers)."""
    from scipy.io import savemat  # only when a .mat file is asked for

    names = [n for n in signals if n != "time" and signals[n].dtype != object]
    texts = [n for n in signals if signals[n].dtype == object]
    data = (np.column_stack([signals[n] for n in names]) if names
            else np.zeros((len(signals["time"]), 0)))
    content = {"time": np.asarray(signals["time"], float), "data": data,
               "names": np.array(names, dtype=object),
               "units": np.array([(units or {}).get(n, "") for n in names], dtype=object),
               "time_unit": "s",
               "signals": dict(zip(matlab_names(names + texts),
                                   [signals[n] for n in names + texts]))}
    buffer = io.BytesIO()
    savemat(buffer, content, do_compression=True, oned_as="column")
    return buffer.getvalue()


def statistics_path(csv_path) -> Path:
    """Where dsim writes the statistics JSON of a results CSV: ``NAME.stats.json`` beside
    ``NAME.csv``."""
    return Path(csv_path).with_suffix(".stats.json")


def read_statistics(csv_path) -> dict:
    """The statistics JSON dsim writes beside a results CSV (:func:`statistics_path`),
    or {} when there is none or it is not one."""
    path = statistics_path(csv_path)
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def units_of(statistics: dict) -> dict[str, str]:
    """Column -> unit, from a run's statistics (its "units"; {} when there is none: a
    CSV of an older dsim or of another tool)."""
    units = statistics.get("units")
    return {str(k): str(v) for k, v in units.items()} if isinstance(units, dict) else {}


def read_units(csv_path) -> dict[str, str]:
    """Column -> unit of a results CSV, from the statistics JSON beside it."""
    return units_of(read_statistics(csv_path))


def display_units_of(statistics: dict) -> dict[str, dict]:
    """Column -> display unit ({"unit", "factor", "offset"}), from a run's statistics
    ({} when they have none)."""
    display = statistics.get("display_units")
    if not isinstance(display, dict):
        return {}
    return {str(k): v for k, v in display.items()
            if isinstance(v, dict) and {"unit", "factor"} <= set(v)}


def read_display_units(csv_path) -> dict[str, dict]:
    """Column -> display unit of a results CSV, from the statistics JSON beside it."""
    return display_units_of(read_statistics(csv_path))


def plot_results(csv_path, png_path, title: str = "", max_curves: int = MAX_CURVES) -> None:
    """:func:`plot_signals` of a results CSV, in the display units and with the units
    and the ``--set`` values of the statistics JSON beside it."""
    header, data = read_csv(csv_path)
    statistics = read_statistics(csv_path)
    signals, units = in_display_units({name: data[:, i] for i, name in enumerate(header)},
                                      units_of(statistics), display_units_of(statistics))
    plot_signals(signals, png_path,
                 title or set_title(statistics.get("scene", Path(csv_path).stem),
                                    statistics.get("parameters")),
                 max_curves, units)


def save_figure(figure, png_path) -> None:
    """Lay out, write as PNG (creating the folder) and release a matplotlib figure."""
    import matplotlib.pyplot as plt

    if figure.get_layout_engine() is None:
        figure.tight_layout()
    if isinstance(png_path, (str, Path)):
        Path(png_path).parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(png_path, dpi=110, format="png")
    plt.close(figure)
