"""``dsim plot``: chosen signals of one or more results CSVs, overlaid in one PNG."""
from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

from dsim.master.errors import InputError
from dsim.master.recording.output_files import write_whole
from dsim.master.recording.results import plot_overlay, read_columns
from dsim.master.recording.selection import column_matches

#: panels of one plot (plot_overlay draws the first this many signals)
MAX_PANELS = 8


@dataclass
class Overlay:
    """What :func:`overlay_files` wrote: the PNG, the matching signals, those drawn,
    and how many results files each panel overlays."""

    out: Path
    names: list[str]
    drawn: list[str]
    results: int


def overlay_files(files, patterns=(), out=None, title: str = "") -> Overlay:
    """Plot the signals of ``files`` (results CSVs) that match ``patterns`` (every
    signal when none), one panel per signal (at most eight) with one curve per file,
    into ``out`` (default: the first file's name with .png; written whole, never over
    one of the CSVs).  Raises InputError when there is no CSV or nothing matches."""
    files = [Path(f) for f in files]
    if not files:
        raise InputError("dsim plot: give at least one results CSV")
    results = {}
    for path in files:
        label = path.stem if path.stem not in results else str(path)
        results[label] = {name: values for name, values in read_columns(path).items()
                          if values.dtype != object}  # text columns have no curve
    columns = list(dict.fromkeys(n for signals in results.values() for n in signals
                                 if n != "time"))
    names = [n for n in columns
             if not patterns or any(column_matches(n, p) for p in patterns)]
    unmatched = [p for p in patterns if not any(column_matches(n, p) for n in columns)]
    if unmatched or not names:
        raise InputError(f"dsim plot: no column matches {', '.join(unmatched) or 'anything'} "
                         f"(columns: {', '.join(columns)})")
    out = Path(out or files[0].with_suffix(".png"))
    image = io.BytesIO()
    plot_overlay(results, names, image, title)
    write_whole(out, image.getvalue(), files)
    return Overlay(out, names, names[:MAX_PANELS], len(results))
