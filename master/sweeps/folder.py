"""A sweep's folder: the design it holds, the points already finished there, and the
files written at the end.

``design.json`` records what the sweep is (its spec: design, factors, samples, seed,
explicit points, fixed settings, KPIs, reference, columns) and its points as they were
drawn.  A rerun into the same folder with the same spec reads the points back from it
(so a sampled design gives the very same points, whatever scipy or SALib would draw
today) and the finished rows back from ``sweep.csv`` (and from the temporary file a
killed sweep left), and runs only the points missing.  A rerun with another spec is
refused: its rows would not belong to one design.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from dsim.master.errors import InputError
from dsim.master.recording.output_files import finish_dead_partial, write_whole
from dsim.master.settings import SETTINGS, convert
from dsim.master.sweeps import sensitivity
from dsim.master.sweeps.design import Design, describe, same_json
from dsim.master.sweeps.plots import (plot_kpis, plot_points, plot_scatter, sweep_title,
                                      sweep_units)
from dsim.master.sweeps.table import Point, markdown, read_table

DESIGN_FILE = "design.json"
TABLE_FILE = "sweep.csv"


#: settings that say where the points run, not what they compute: a sweep killed on
#: Ray may be finished in-process, and the other way round
WHERE = ("backend", "address", "call_timeout", "restarts")


def _typed(name: str, value):
    """A setting's value as its type (``"0.01"`` from a command line is 0.01 from
    Python), a parameter's as given."""
    if name in SETTINGS:
        converted, problem = convert(SETTINGS[name], value, name)
        return value if problem else converted
    return value


def spec(scene, sweep, kpis) -> dict:
    """What makes two sweeps the same sweep (JSON-ready)."""
    design = sweep.plan().record()
    for factor in design["factors"]:
        factor["values"] = [_typed(factor["name"], v) for v in factor["values"]]
    return {"scene": Path(scene).name, "design": design,
            "points": [{k: _typed(k, v) for k, v in p.items()} for p in sweep.points],
            "settings": {k: _typed(k, v) for k, v in sweep.fixed.items() if k not in WHERE},
            "kpis": [k.label for k in kpis],
            "reference": None if sweep.reference is None else str(sweep.reference),
            "columns": sweep.columns}


def open_folder(out: Path, wanted: dict, configurations: list[dict],
                inputs) -> tuple[list[dict], dict[int, Point]]:
    """The sweep's points (those recorded in ``out/design.json`` when it holds this
    sweep, else ``configurations``, then recorded) and the points already finished
    there (0-based index -> Point); InputError when the folder holds another sweep."""
    path = out / DESIGN_FILE
    if not path.exists():
        write_whole(path, json.dumps({"spec": wanted, "configurations": configurations},
                                     indent=1).encode(), inputs)
        return configurations, {}
    try:
        recorded = json.loads(path.read_text())
        old, configurations = recorded["spec"], recorded["configurations"]
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise InputError(f"{path}: cannot read the recorded design ({error}); remove the "
                         "folder to start over, or choose another --out") from None
    if not same_json(old, wanted):
        changed = [key for key in wanted if not same_json(old.get(key), wanted[key])]
        raise InputError(f"{out}: holds another sweep ({', '.join(changed)} differ: it "
                         f"has {describe(old.get('design', {}))}, this is "
                         f"{describe(wanted['design'])}); choose another --out, or remove "
                         "the folder to start over")
    return configurations, finished(out, configurations)


def finished(out: Path, configurations: list[dict]) -> dict[int, Point]:
    """The points of ``out/sweep.csv`` that a rerun keeps (any ending but interrupted;
    the rows a killed sweep left under its temporary name first moved to the table),
    each with its recorded configuration and results file."""
    finish_dead_partial(out / TABLE_FILE)
    _, _, points = read_table(out / TABLE_FILE)
    kept = {}
    for point in points:
        k = point.index - 1
        if point.finished and 0 <= k < len(configurations):
            point.settings = dict(configurations[k])
            results = out / f"point_{point.index:03d}.csv"
            point.results = results if results.is_file() else None
            kept[k] = point
    return kept


def write_outputs(out: Path, points: list[Point], sweep, names: list[str], labels: list[str],
                  reference_label: str, title: str, inputs, total: int,
                  plan=None) -> list[str]:
    """``sweep.md``, ``sweep.png`` (where errors were measured), and for KPIs
    ``kpis.png``, ``scatter.png``, ``sensitivity.csv`` and ``sensitivity.md``; the
    names of the files written.  ``total``: how many points the sweep has (a design
    not run whole has no Sobol' or Morris indices); ``plan``: the scene's plan, whose
    FMUs say the varied parameters' units."""
    title = sweep_title(title, sweep.fixed)

    written = ["sweep.md"]
    write_whole(out / "sweep.md", markdown(points, names, reference_label, labels).encode(),
                inputs)
    if any(math.isfinite(p.error) for p in points):
        write_whole(out / "sweep.png", plot_points(points, title), inputs)
        written.append("sweep.png")
    design: Design = sweep.plan()
    if not labels or not design.factors or not points:
        return written
    units = sweep_units(plan, [f.name for f in design.factors], labels, points)
    write_whole(out / "kpis.png", plot_kpis(points, design.factors, labels, title, units),
                inputs)
    write_whole(out / "scatter.png", plot_scatter(points, design.factors, labels, title,
                                                  units), inputs)
    written += ["kpis.png", "scatter.png"]
    if sweep.points:
        return written  # explicit points are outside the design: no indices of it
    ordered = [None] * total
    for point in points:
        ordered[point.index - 1] = point
    configurations = [p.settings if p else None for p in ordered]
    values = {label: [p.kpis.get(label, math.nan) if p else math.nan for p in ordered]
              for label in labels}
    present = [k for k, c in enumerate(configurations) if c is not None]
    if len(present) < total and design.kind in ("saltelli", "morris"):
        indices = [sensitivity.Index(label, "", design.kind, "", math.nan,
                                     note=f"{total - len(present)} of {total} points not "
                                     "run: rerun the sweep to finish them")
                   for label in labels]
    else:
        indices = sensitivity.analyse(
            design, [configurations[k] for k in present],
            {label: np.asarray(v)[present] for label, v in values.items()})
    write_whole(out / "sensitivity.csv", sensitivity.csv_text(indices).encode(), inputs)
    write_whole(out / "sensitivity.md", sensitivity.markdown(indices).encode(), inputs)
    return written + ["sensitivity.csv", "sensitivity.md"]


def read_sensitivity(out: Path) -> list[dict]:
    """The rows of ``out/sensitivity.csv`` (empty when there is none)."""
    import csv
    import io

    try:
        return list(csv.DictReader(io.StringIO((out / "sensitivity.csv").read_text())))
    except (OSError, UnicodeDecodeError, csv.Error):
        return []
