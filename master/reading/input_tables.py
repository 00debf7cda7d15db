"""Input tables as a user gives them (``dsim run --input FILE``, ``inputs=`` of the API,
and an SSP Component whose source is a ``.csv`` or ``.mat`` file: a table component, as
OMSimulator reads them): a time column and one column per signal, checked for their
form only.  Nothing here knows the scene: :mod:`dsim.master.planning.inputs` resolves
the columns of ``--input`` against the components' variables, and the plan treats a
table component as a source whose outputs are its columns
(:func:`table_description`).

Forms read (FMPy's conventions for input tables):

- **CSV**: a header row whose first name is the time column (``time``), then one name
  per column (``component.variable`` for ``--input``; any name for a table
  component); one row per time, every cell a finite number (Booleans as 0 and 1).
  Read with Python's ``csv`` module rather than ``fmpy.util.read_csv``, which splits
  lines on commas itself (no quoted names), reads a cell with spaces as a vector, and
  says nothing of where a bad cell is: here a bad cell is one line naming its row and
  column.
- **MATLAB .mat** (version 4 to 7, read by ``scipy.io.loadmat``, which builds numpy
  arrays only: it unpickles nothing and runs nothing): a vector ``time`` and either
  dsim's own ``--mat`` layout (a matrix ``data``, one column per signal, and a cell
  array ``names``) or one vector per signal, a struct standing for the dotted name
  (MATLAB's ``offset.u = ...`` is the column ``offset.u``).  A version 7.3 file is an
  HDF5 file: read with h5py where it is installed, else refused in one line.
- **a pandas DataFrame** (its index is the time where it is named ``time`` or no
  ``time`` column is given) or **a numpy structured array** whose first field is the
  time (FMPy's own input form).

Times must not decrease; a time given on two rows is a jump (before it, the first
row's value; at and after it, the second's); values are held before the first and
after the last row (:mod:`dsim.master.running.tables` interpolates).  The file is
untrusted: its size and its number of cells are bounded before it is parsed.
"""
from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from dsim.master.errors import InputError
from dsim.master.reading.small_files import bounded_bytes, bounded_size, utf8_text
from dsim.master.reading.digests import file_digest

#: the largest table file read (bytes) and the most cells (rows x columns) kept: a
#: measured profile at 1 kHz for an hour on a dozen channels fits, a runaway file not
MAX_BYTES = 256 * 1024 * 1024
MAX_CELLS = 50_000_000
#: the suffixes read as tables, and the SSP component types that name a table
#: (OMSimulator writes text/csv, its older versions application/table for a .csv or a
#: .mat file; application/x-mat for a .mat file; a component without a type and with
#: such a source is a table too)
SUFFIXES = (".csv", ".mat")
TABLE_TYPES = ("text/csv", "application/table", "application/x-mat")
#: the first bytes of a MATLAB 7.3 file (its 128-byte header) and of an HDF5 file
MAT73 = b"MATLAB 7.3"
HDF5 = b"\x89HDF\r\n\x1a\n"


@dataclass(frozen=True, eq=False)
class Table:
    """A table of signals over time: ``times`` (s, n rows, not decreasing),
    ``names`` (one per column, without the time column) and ``values`` (columns x
    rows, float: FMPy's orientation of an input table), read from ``source`` (a file's
    path, or what the table was made from)."""

    times: np.ndarray
    names: tuple[str, ...]
    values: np.ndarray
    source: str
    #: the file it was read from, or None (a DataFrame, a structured array)
    file: Path | None = None

    @property
    def span(self) -> tuple[float, float]:
        """The first and last time (s)."""
        return float(self.times[0]), float(self.times[-1])

    def column(self, name: str) -> np.ndarray:
        """The values of column ``name`` (one per row)."""
        return self.values[self.names.index(name)]

    def jumps(self) -> list[float]:
        """The times given on two rows (s): where the values may jump."""
        repeated = np.flatnonzero(np.diff(self.times) == 0)
        return sorted({float(self.times[i]) for i in repeated})

    def lines(self) -> list[str]:
        """What ``dsim info --input`` says: the rows, the time span, the jumps and one
        line per column (its range)."""
        first, last = self.span
        jumps = self.jumps()
        lines = [f"input table {self.source}: {len(self.times)} rows, "
                 f"{len(self.names)} column{'s' * (len(self.names) != 1)}, "
                 f"t = {first:g} .. {last:g} s (values held outside)"
                 + (f", jumps at t = {', '.join(f'{t:g}' for t in jumps[:5])}"
                    f"{', ...' if len(jumps) > 5 else ''} s" if jumps else "")]
        for name, column in zip(self.names, self.values):
            lines.append(f"  {name}: {np.min(column):g} .. {np.max(column):g}")
        return lines


#: tables made in memory (a DataFrame, a structured array given as ``inputs=``), by the
#: name that stands for them where a file's path would (:func:`held`)
_HELD: dict[Path, Table] = {}


def is_table_file(path) -> bool:
    """Whether ``path`` names a table by its suffix (.csv, .mat)."""
    return Path(path).suffix.lower() in SUFFIXES


def is_table(path) -> bool:
    """Whether ``path`` is a table file that exists or a table held in memory."""
    path = Path(path)
    return is_table_file(path) and (path in _HELD or path.is_file())


def held(table: Table) -> Path:
    """A name that stands for ``table`` (made in memory) where a file's path would: the
    plan reads it back by :func:`read_table`.  Each table is held once (by identity)."""
    for path, found in _HELD.items():
        if found is table:
            return path
    path = Path(f"<{table.source} {len(_HELD) + 1}>.csv")
    _HELD[path] = table
    return path


def read_table(given, label: str | None = None) -> Table:
    """The :class:`Table` of ``given``: a .csv or .mat file's path, a pandas
    DataFrame or a numpy structured array; InputError (one line) when it is not a
    table dsim can take.  A file is read once per content."""
    if isinstance(given, Table):
        return given
    if isinstance(given, (str, Path)):
        path = Path(given)
        if path in _HELD:
            return _HELD[path]
        if not is_table_file(path):
            raise InputError(f"{path}: an input table is a .csv or .mat file")
        try:
            digest = file_digest(path)
        except OSError as error:
            raise InputError(f"{path}: cannot read: {error.strerror}") from None
        return _read_file(path, digest)
    if isinstance(given, np.ndarray) and given.dtype.names:
        return _from_structured(given, label or "the structured array")
    frame = _as_frame(given)
    if frame is not None:
        return _from_frame(frame, label or "the DataFrame")
    raise InputError(f"inputs: {type(given).__name__} is not an input table (give a .csv "
                     "or .mat file, a pandas DataFrame or a numpy structured array)")


def table_problem(path) -> str | None:
    """What is wrong with the table file at ``path`` (one line), or None."""
    try:
        read_table(path)
    except InputError as error:
        return "; ".join(error.problems)
    return None


@lru_cache(maxsize=32)
def _read_file(path: Path, digest: str) -> Table:
    """The table of the file at ``path`` (``digest``: its content's, the cache key)."""
    if path.suffix.lower() != ".mat":
        return _csv(path, bounded_bytes(path, MAX_BYTES, "an input table"))
    bounded_size(path, MAX_BYTES, "an input table")
    try:
        return _mat(path)
    except OSError as error:
        raise InputError(f"{path}: cannot read: {error.strerror}") from None


# --- the checks every form shares ------------------------------------------------
def _checked(times, names, values, source: str, file: Path | None, where_row) -> Table:
    """A :class:`Table` of float ``times`` (n) and ``values`` (columns x n), after the
    checks every form shares: a time column, at least one row and one column, unique
    names, finite numbers, times that do not decrease (``where_row(i)``: how a message
    names row i)."""
    times = np.asarray(times, dtype=float).reshape(-1)
    if len(times) == 0:
        raise InputError(f"{source}: the table has no rows")
    values = np.asarray(values, dtype=float).reshape(len(names), len(times))
    if not names:
        raise InputError(f"{source}: the table has a time column only: give one column per "
                         "input after it")
    seen = set()
    for name in names:
        if not name:
            raise InputError(f"{source}: a column has no name")
        if name in seen:
            raise InputError(f"{source}: column '{name}' is given twice")
        seen.add(name)
    bad = np.flatnonzero(~np.isfinite(times))
    if len(bad):
        raise InputError(f"{source} {where_row(bad[0])}: time {times[bad[0]]!r} is not a "
                         "finite number")
    for name, column in zip(names, values):
        bad = np.flatnonzero(~np.isfinite(column))
        if len(bad):
            raise InputError(f"{source} {where_row(bad[0])}, column '{name}': "
                             f"{column[bad[0]]!r} is not a finite number")
    back = np.flatnonzero(np.diff(times) < 0)
    if len(back):
        i = back[0] + 1
        raise InputError(f"{source} {where_row(i)}: time {times[i]:g} s is before the row "
                         f"above's {times[i - 1]:g} s (times must not decrease)")
    if len(times) * max(1, len(names)) > MAX_CELLS:
        raise InputError(f"{source}: {len(times)} rows x {len(names)} columns: more than "
                         f"an input table's {MAX_CELLS} cells")
    values = np.ascontiguousarray(values)
    values.setflags(write=False)
    times.setflags(write=False)
    return Table(times, tuple(names), values, source, file)


# --- CSV ----------------------------------------------------------------------------
def _csv(path: Path, data: bytes) -> Table:
    """The table of a CSV file's bytes."""
    rows = csv.reader(io.StringIO(utf8_text(path, data)))
    header, lines, values = None, [], []
    try:
        for row in rows:
            if not row or all(not cell.strip() for cell in row):
                continue  # blank lines (a trailing one, most often)
            if header is None:
                header = [cell.strip() for cell in row]
                width = len(header)
                continue
            if len(row) != width:
                raise InputError(f"{path} line {rows.line_num}: {len(row)} cells, the header "
                                 f"has {width}")
            parsed = []
            for name, cell in zip(header, row):
                try:
                    parsed.append(float(cell))
                except ValueError:
                    raise InputError(f"{path} line {rows.line_num}, column '{name}': "
                                     f"{cell.strip()!r} is not a number") from None
            values.append(parsed)
            lines.append(rows.line_num)
            if len(values) * width > MAX_CELLS:
                raise InputError(f"{path}: more than an input table's {MAX_CELLS} cells")
    except csv.Error as error:
        raise InputError(f"{path} line {rows.line_num}: malformed CSV: {error}") from None
    if header is None:
        raise InputError(f"{path}: the file is empty: give a header row (time, then one "
                         "name per column) and one row per time")
    if header[0].lower() != "time":
        raise InputError(f"{path}: the first column is '{header[0]}': an input table's "
                         "first column is its time, named 'time'")
    array = np.array(values, dtype=float).reshape(len(values), len(header))
    return _checked(array[:, 0], header[1:], array[:, 1:].T, str(path), path,
                    lambda i: f"line {lines[i]}")


# --- MATLAB .mat --------------------------------------------------------------------
def _mat(path: Path) -> Table:
    """The table of a .mat file: version 4 to 7 through scipy.io, 7.3 (HDF5) through
    h5py where it is installed."""
    with path.open("rb") as file:
        head = file.read(520)
    if head.startswith(MAT73) or head[512:520] == HDF5 or head.startswith(HDF5):
        return _mat73(path)
    from scipy.io import loadmat, whosmat  # only where a .mat table is read

    try:
        # the variables' shapes first, from their headers: a compressed variable that
        # would unpack into more cells than a table holds is refused before it is
        shapes = whosmat(str(path))
    except Exception as error:  # scipy raises ValueError, TypeError, ... on a bad file
        raise InputError(f"{path}: not a MATLAB .mat file dsim can read: {error}") from None
    cells = sum(math.prod(shape) for _, shape, kind in shapes if kind != "struct")
    if cells > MAX_CELLS:
        raise InputError(f"{path}: {cells} cells: more than an input table's {MAX_CELLS}")
    try:
        content = loadmat(str(path), simplify_cells=True)
    except Exception as error:
        raise InputError(f"{path}: not a MATLAB .mat file dsim can read: {error}") from None
    return _mat_content(path, {k: v for k, v in content.items() if not k.startswith("__")})


def _mat73(path: Path) -> Table:
    """A MATLAB 7.3 (HDF5) file: its top-level datasets, through h5py where installed.
    MATLAB stores a matrix transposed in HDF5: a vector's orientation does not matter
    here, and a ``data`` matrix is taken with ``names``' count of rows or columns."""
    try:
        import h5py  # optional: dsim does not depend on it
    except ImportError:
        raise InputError(f"{path}: a MATLAB 7.3 (HDF5) .mat file: save it with -v7 (or read "
                         "it where h5py is installed)") from None
    content = {}
    try:
        with h5py.File(path, "r") as file:
            def take(name, item):
                if isinstance(item, h5py.Dataset) and item.dtype.kind in "fiub":
                    if item.size > MAX_CELLS:
                        raise InputError(f"{path}: '{name}' has {item.size} cells: more "
                                         f"than an input table's {MAX_CELLS}")
                    content[name.replace("/", ".")] = np.asarray(item[()], dtype=float)
            file.visititems(take)
    except OSError as error:
        raise InputError(f"{path}: not a MATLAB 7.3 .mat file dsim can read: {error}") from None
    if "data" in content and "names" not in content:
        content.pop("data")  # the names of a 7.3 file's cell array are not read here
    return _mat_content(path, content)


def _flattened(content: dict, prefix: str = "") -> dict:
    """name -> array of the numeric variables of a loaded .mat file, a struct's fields
    under its dotted name."""
    found = {}
    for key, value in content.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            found.update(_flattened(value, name + "."))
        elif isinstance(value, np.ndarray) and value.dtype.kind in "fiub":
            found[name] = value
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            found[name] = np.array([value], dtype=float)
    return found


def _mat_content(path: Path, content: dict) -> Table:
    """The table of a loaded .mat file's variables (module docstring: two layouts)."""
    if "time" not in content:
        raise InputError(f"{path}: no vector 'time' in the .mat file (an input table holds "
                         "'time' and 'data' with 'names', or one vector per signal)")
    times = np.asarray(content["time"], dtype=float)
    if times.ndim > 1 and min(times.shape) != 1:
        raise InputError(f"{path}: 'time' is a {'x'.join(map(str, times.shape))} matrix, "
                         "not a vector")
    times = times.reshape(-1)
    rows = len(times)
    if "data" in content and "names" in content:  # dsim's own --mat layout
        names = content["names"]
        names = [names] if isinstance(names, str) else [str(n).strip() for n in
                                                        np.asarray(names, dtype=object).ravel()]
        data = np.asarray(content["data"], dtype=float)
        data = data.reshape(rows, -1) if data.ndim < 2 else data
        if data.shape[0] != rows and data.shape[1] == rows:
            data = data.T
        if data.shape != (rows, len(names)):
            raise InputError(f"{path}: 'data' is {data.shape[0]} x {data.shape[1]}: give "
                             f"{rows} rows (one per time) and {len(names)} columns (one per "
                             "name)")
        return _checked(times, names, data.T, str(path), path, lambda i: f"row {i + 1}")
    columns = {name: value for name, value in _flattened(content).items()
               if name not in ("time", "data", "names", "units", "time_unit")
               and not name.startswith("signals.")}
    names, values = [], []
    for name, value in columns.items():
        value = np.asarray(value, dtype=float)
        if value.size != rows or (value.ndim > 1 and min(value.shape) != 1):
            raise InputError(f"{path}: '{name}' has {value.size} values, 'time' {rows}: give "
                             "one value per time")
        names.append(name)
        values.append(value.reshape(-1))
    return _checked(times, names, np.array(values).reshape(len(names), rows), str(path),
                    path, lambda i: f"row {i + 1}")


# --- in memory ----------------------------------------------------------------------
def _as_frame(given):
    """``given`` if it is a pandas DataFrame (pandas imported only when it is
    installed: dsim does not depend on it), else None."""
    module = type(given).__module__
    if not module.startswith("pandas"):
        return None
    try:
        import pandas
    except ImportError:
        return None
    return given if isinstance(given, pandas.DataFrame) else None


def _numbers(column, source: str, name: str) -> np.ndarray:
    """A column as float, or one line naming the first cell that is not a number."""
    try:
        return np.asarray(column, dtype=float)
    except (TypeError, ValueError):
        for row, cell in enumerate(column):
            try:
                float(cell)
            except (TypeError, ValueError):
                raise InputError(f"{source} row {row + 1}, column '{name}': {cell!r} is not "
                                 "a number") from None
        raise InputError(f"{source}: column '{name}' is not numbers") from None


def _from_frame(frame, source: str) -> Table:
    """The table of a DataFrame: its ``time`` column (the first), else its index."""
    names = [str(c) for c in frame.columns]
    if names and names[0] == "time":
        times = _numbers(frame.iloc[:, 0].to_numpy(), source, "time")
        columns = list(range(1, len(names)))
    elif "time" in names:
        raise InputError(f"{source}: 'time' is column {names.index('time') + 1}: an input "
                         "table's first column is its time")
    else:
        times = _numbers(frame.index.to_numpy(), source, "time (the index)")
        columns = list(range(len(names)))
    values = [_numbers(frame.iloc[:, i].to_numpy(), source, names[i]) for i in columns]
    return _checked(times, [names[i] for i in columns], np.array(values).reshape(
        len(columns), len(times)), source, None, lambda i: f"row {i + 1}")


def _from_structured(array: np.ndarray, source: str) -> Table:
    """The table of a numpy structured array whose first field is the time (FMPy's
    form of an input)."""
    fields = array.dtype.names
    if fields[0] != "time":
        raise InputError(f"{source}: the first field is '{fields[0]}': an input table's "
                         "first field is its time, named 'time'")
    array = array.reshape(-1)
    for name in fields:
        if array.dtype[name].shape:
            raise InputError(f"{source}: field '{name}' holds arrays: give one field per "
                             "scalar input")
    values = [_numbers(array[name], source, name) for name in fields[1:]]
    return _checked(_numbers(array["time"], source, "time"), list(fields[1:]),
                    np.array(values).reshape(len(fields) - 1, len(array)), source, None,
                    lambda i: f"row {i + 1}")
