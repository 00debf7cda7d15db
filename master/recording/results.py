"""The results of a run (DESIGN.md, "Results contract"): the :class:`RunResult`
that :func:`dsim.simulate` returns, reading a results CSV back, and plots."""
from __future__ import annotations

import csv
import difflib
import io
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


def _panels(panels, png_path, title: str = "") -> None:
    """Panels over time, one under the other: ``panels`` is a list of (y label,
    [(curve label, time, values), ...])."""
    import matplotlib  # only when a plot is asked for: it takes a third of a second
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # only when a plot is asked for

    figure, axes = plt.subplots(max(len(panels), 1), 1, sharex=True, squeeze=False,
                                figsize=(8, 2.4 * max(len(panels), 1) + 0.6))
    for axis, (label, curves) in zip(axes[:, 0], panels):
        for name, time, values in curves:
            axis.plot(time, values, label=name)
        axis.set_ylabel(label, fontsize=8)
        axis.grid(True, alpha=0.3)
        axis.legend(fontsize=8, loc="best")
    axes[-1, 0].set_xlabel("time (s)")
    if title:
        axes[0, 0].set_title(title)
    save_figure(figure, png_path)


def plot_signals(signals: dict, png_path, title: str = "", max_curves: int = 8) -> None:
    """Two panels over time: recorded outputs, and joint forces (``*.f_*``); ``png_path``
    is a path or a binary file object."""
    time = signals["time"]
    names = [n for n in signals if n != "time" and signals[n].dtype != object]
    forces = [n for n in names if ".f_" in n]
    outputs = [n for n in names if n not in forces]
    _panels([(label, [(n, time, signals[n]) for n in columns[:max_curves]])
             for columns, label in ((outputs, "recorded outputs"),
                                    (forces, "joint forces (N, N.m)")) if columns],
            png_path, title)


def plot_overlay(results: dict, names: list[str], png_path, title: str = "") -> None:
    """One panel per signal of ``names`` (at most eight), each with one curve per
    result (``results``: label -> signals), for comparing runs."""
    _panels([(name, [(label, signals["time"], signals[name])
                      for label, signals in results.items() if name in signals])
             for name in names[:8]], png_path, title)


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


def mat_bytes(signals: dict) -> bytes:
    """A MATLAB .mat (version 5) file of the signals: ``time``, ``data`` (one column
    per numeric signal), ``names`` (their column names) and a struct ``signals`` with
    one field per signal, String ones as cell arrays (names made valid identifiers)."""
    from scipy.io import savemat  # only when a .mat file is asked for

    names = [n for n in signals if n != "time" and signals[n].dtype != object]
    texts = [n for n in signals if signals[n].dtype == object]
    data = (np.column_stack([signals[n] for n in names]) if names
            else np.zeros((len(signals["time"]), 0)))
    content = {"time": np.asarray(signals["time"], float), "data": data,
               "names": np.array(names, dtype=object),
               "signals": dict(zip(matlab_names(names + texts),
                                   [signals[n] for n in names + texts]))}
    buffer = io.BytesIO()
    savemat(buffer, content, do_compression=True, oned_as="column")
    return buffer.getvalue()


def plot_results(csv_path, png_path, title: str = "", max_curves: int = 8) -> None:
    """:func:`plot_signals` of a results CSV."""
    header, data = read_csv(csv_path)
    plot_signals({name: data[:, i] for i, name in enumerate(header)}, png_path, title,
                 max_curves)


def save_figure(figure, png_path) -> None:
    """Lay out, write as PNG (creating the folder) and release a matplotlib figure."""
    import matplotlib.pyplot as plt

    figure.tight_layout()
    if isinstance(png_path, (str, Path)):
        Path(png_path).parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(png_path, dpi=110, format="png")
    plt.close(figure)
