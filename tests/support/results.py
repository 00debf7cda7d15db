"""Result files written and read by tests."""
from pathlib import Path


def write_csv(path, times, columns):
    """A results CSV: ``times`` and ``columns`` (name -> values)."""
    lines = ["time," + ",".join(columns)]
    for i, t in enumerate(times):
        lines.append(",".join([repr(float(t))] + [repr(float(v[i])) for v in columns.values()]))
    path.write_text("\n".join(lines) + "\n")


def rows_on_disk(path: Path) -> int:
    """The rows a results CSV holds now (-1: no file yet)."""
    try:
        return path.read_bytes().count(b"\n") - 1  # the header
    except FileNotFoundError:
        return -1
