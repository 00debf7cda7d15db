"""``dsim plot``: chosen signals of one or more results CSVs, overlaid in one PNG, one
panel per unit (the units, display units and ``--set`` values come from each CSV's
statistics JSON)."""
from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

from dsim.master.errors import InputError
from dsim.master.recording.output_files import write_whole
from dsim.master.recording.results import (display_units_of, in_display_units, plot_overlay,
                                            read_columns, read_statistics, set_title,
                                            units_of)
from dsim.master.recording.selection import column_matches


@dataclass
class Overlay:
    """What :func:`overlay_files` wrote: the PNG, the matching signals, those drawn,
    how many results files each panel overlays, and each panel's axis label."""

    out: Path
    names: list[str]
    drawn: list[str]
    results: int
    labels: list[str]


def overlay_files(files, patterns=(), out=None, title: str = "") -> Overlay:
    """Plot the signals of ``files`` (results CSVs) that match ``patterns`` (every
    signal when none), one panel per unit with one curve per signal and file, each its
    own colour, in the display units the statistics name (at most eight signals a
    panel; the figure says how many it leaves out), into ``out``
    (default: the first file's name with .png; written whole, never over one of the
    CSVs); the title names the scene and each file's ``--set`` values unless ``title``
    is given.  Raises InputError when there is no CSV or nothing matches."""
    files = [Path(f) for f in files]
    if not files:
        raise InputError("dsim plot: give at least one results CSV")
    results, units = {}, {}
    statistics = [read_statistics(path) for path in files]
    for path, stats in zip(files, statistics):
        label = path.stem if path.stem not in results else str(path)
        signals, declared = in_display_units(
            {name: values for name, values in read_columns(path).items()
             if values.dtype != object},  # text columns have no curve
            units_of(stats), display_units_of(stats))
        results[label] = signals
        for name, unit in declared.items():  # the first file that declares one names it
            if unit and not units.get(name):
                units[name] = unit
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
    panels = plot_overlay(results, names, image,
                          title or _title(statistics, list(results)), units)
    write_whole(out, image.getvalue(), files)
    return Overlay(out, names, [n for panel in panels for n in panel.names], len(results),
                   [panel.label for panel in panels])


def _title(statistics, labels) -> str:
    """The scenes of the files (``statistics``: each one's) and, per file, the values
    its run was given (--set)."""
    scenes = list(dict.fromkeys(s.get("scene") or "" for s in statistics if s.get("scene")))
    lines = [", ".join(scenes) or ", ".join(labels)]
    for label, data in zip(labels, statistics):
        if data.get("parameters"):
            lines.append(set_title(label, data["parameters"]).replace("\n", " "))
    return "\n".join(lines[:4]) + (" ..." if len(lines) > 4 else "")
