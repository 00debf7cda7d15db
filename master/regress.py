"""``dsim regress``: run every scene that has a stored baseline and compare.

A scene folder holds scenes (``NAME.ssp`` archives or ``NAME/`` scene folders); a
baseline folder holds, per scene, ``NAME.csv`` (the stored results) and
``NAME.json`` (how to run it and how close it must stay)::

    {"settings": {"stop": 0.5}, "rtol": 1e-6, "atol": 0.0, "columns": null}

Each case runs with :func:`dsim.simulate` and is compared with
:func:`master.compare.compare_files` (a tolerance band over time; first and worst
violation per signal).  ``update`` runs each case and stores its results as the new
baseline instead; nothing else writes a baseline.
"""
from __future__ import annotations

import json
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from xml.etree import ElementTree

from master.errors import InputError
from master.output_files import write_whole

DEFAULTS = {"settings": {}, "rtol": 1e-6, "atol": 0.0, "columns": None}


@dataclass
class Case:
    """A scene with a baseline: how to run it and how close it must stay."""

    name: str
    scene: Path
    baseline: Path
    settings: dict = field(default_factory=dict)
    rtol: float = 1e-6
    atol: float = 0.0
    columns: list | None = None


@dataclass
class Outcome:
    """One case's verdict: passed, regressed (outside the band), failed (the run
    failed or was interrupted) or error (bad input); with what was measured."""

    case: Case
    status: str
    message: str = ""
    comparison: object = None
    seconds: float = 0.0
    results: Path | None = None


def _scenes(folder: Path) -> dict[str, Path]:
    found = {}
    for path in sorted(folder.iterdir()):
        if path.suffix == ".ssp" or (path.is_dir() and (path / "SystemStructure.ssd").is_file()):
            found[path.stem] = path
    return found


def find_cases(folder, baselines=None, only=(), update: bool = False
               ) -> tuple[list[Case], list[str]]:
    """The cases of ``folder`` that have a baseline (``baselines`` defaults to
    ``folder/baselines``; with ``update`` every scene, a missing baseline to be
    written), and the names of the scenes that have none."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"{folder}: no such folder")
    baselines = Path(baselines) if baselines else folder / "baselines"
    scenes = _scenes(folder)
    unknown = [name for name in only if name not in scenes]
    if unknown:
        raise InputError(f"{folder}: no scene {', '.join(unknown)} (scenes: "
                         f"{', '.join(scenes) or 'none'})")
    cases, without = [], []
    for name, scene in scenes.items():
        if only and name not in only:
            continue
        spec = baselines / f"{name}.json"
        if not (baselines / f"{name}.csv").is_file() and not spec.is_file() and not update:
            without.append(name)
            continue
        cases.append(_case(name, scene, baselines))
    return cases, without


def _case(name: str, scene: Path, baselines: Path) -> Case:
    spec = baselines / f"{name}.json"
    values = dict(DEFAULTS)
    if spec.is_file():
        try:
            values.update(json.loads(spec.read_text()))
        except json.JSONDecodeError as error:
            raise InputError(f"{spec}: not JSON: {error}") from None
        unknown = set(values) - set(DEFAULTS)
        if unknown:
            raise InputError(f"{spec}: unknown keys {', '.join(sorted(unknown))} (known: "
                             f"{', '.join(DEFAULTS)})")
    return Case(name, scene, baselines / f"{name}.csv", dict(values["settings"]),
                float(values["rtol"]), float(values["atol"]), values["columns"])


def run_case(case: Case, results: Path, update: bool = False, rtol=None,
             atol=None) -> Outcome:
    """Run one case into ``results`` and compare it with its baseline (or, with
    ``update``, store it as the baseline)."""
    from master.api import simulate
    from master.compare import compare_files

    start = time.perf_counter()
    out = results / f"{case.name}.csv"
    try:
        result = simulate(case.scene, out=out, handle_signals=False, **case.settings)
    except InputError as error:
        return Outcome(case, "error", "; ".join(error.problems),
                       seconds=time.perf_counter() - start)
    seconds = time.perf_counter() - start
    if result.status != "completed":
        return Outcome(case, "failed", result.message, seconds=seconds, results=out)
    if update:
        write_whole(case.baseline, out.read_bytes())
        spec = case.baseline.with_suffix(".json")
        if not spec.is_file():
            write_whole(spec, (json.dumps({**DEFAULTS, "settings": case.settings},
                                          indent=2) + "\n").encode())
        return Outcome(case, "updated", f"baseline {case.baseline} ({result.steps} steps)",
                       seconds=seconds, results=out)
    if not case.baseline.is_file():
        return Outcome(case, "error", f"{case.baseline}: no baseline (run with --update)",
                       seconds=seconds, results=out)
    try:
        comparison = compare_files(out, case.baseline, case.columns,
                                   case.rtol if rtol is None else rtol,
                                   case.atol if atol is None else atol)
    except InputError as error:
        return Outcome(case, "error", "; ".join(error.problems), seconds=seconds, results=out)
    if comparison.passed:
        return Outcome(case, "passed", "", comparison, seconds, out)
    return Outcome(case, "regressed", _regression(comparison), comparison, seconds, out)


def _regression(comparison) -> str:
    parts = []
    if comparison.short:
        parts.append(f"ends at t = {comparison.result_end:g} s, before the baseline "
                     f"({comparison.reference_end:g} s)")
    for d in comparison.failed:
        parts.append(f"{d.column}: outside the band from t = {d.first[0]:.6g} s, worst at "
                     f"t = {d.worst[0]:.6g} s ({d.worst[1]:.6g} against {d.worst[2]:.6g}, "
                     f"allowed +-{d.allowed:.3g})")
    return "; ".join(parts)


def run_cases(cases, results=None, update=False, rtol=None, atol=None, progress=None):
    """Every case's outcome (``results``: where the runs' CSVs go; a temporary folder
    when None)."""
    outcomes = []
    with tempfile.TemporaryDirectory(prefix="dsim-regress-") as temp:
        folder = Path(results) if results else Path(temp)
        for case in cases:
            outcome = run_case(case, folder, update, rtol, atol)
            outcomes.append(outcome)
            if progress:
                progress(outcome)
    return outcomes


def summary_lines(outcomes) -> list[str]:
    """The table printed at the end: one row per case."""
    width = max([len(o.case.name) for o in outcomes] + [5])
    lines = [f"{'scene':<{width}}  {'verdict':<9}  {'seconds':>7}  worst column"]
    for outcome in outcomes:
        worst = ""
        if outcome.comparison is not None and outcome.comparison.differences:
            d = max(outcome.comparison.differences,
                    key=lambda d: d.max_difference / d.allowed if d.allowed else 0.0)
            worst = f"{d.column} {d.max_difference:.2e} (allowed {d.allowed:.2e})"
        lines.append(f"{outcome.case.name:<{width}}  {outcome.status:<9}  "
                     f"{outcome.seconds:>7.2f}  {worst}")
    return lines


def junit_xml(outcomes, path) -> None:
    """A JUnit XML report (one testcase per scene), as CI systems read them."""
    failures = sum(o.status in ("regressed", "failed") for o in outcomes)
    errors = sum(o.status == "error" for o in outcomes)
    suite = ElementTree.Element("testsuite", name="dsim regress", tests=str(len(outcomes)),
                                failures=str(failures), errors=str(errors),
                                time=f"{sum(o.seconds for o in outcomes):.3f}")
    for outcome in outcomes:
        case = ElementTree.SubElement(suite, "testcase", classname="dsim.regress",
                                      name=outcome.case.name, time=f"{outcome.seconds:.3f}")
        if outcome.status in ("regressed", "failed"):
            failure = ElementTree.SubElement(case, "failure", type=outcome.status,
                                             message=outcome.message[:500])
            failure.text = outcome.message
        elif outcome.status == "error":
            error = ElementTree.SubElement(case, "error", message=outcome.message[:500])
            error.text = outcome.message
    document = ElementTree.Element("testsuites")
    document.append(suite)
    ElementTree.indent(document)
    write_whole(path, ElementTree.tostring(document, encoding="utf-8", xml_declaration=True))
