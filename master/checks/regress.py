"""``dsim regress``: run every scene that has a stored baseline and compare.

A scene folder holds scenes (``NAME.ssp`` archives or ``NAME/`` scene folders); a
baseline folder holds, per scene, ``NAME.csv`` (the stored results) and
``NAME.json`` (how to run it and how close it must stay)::

    {"settings": {"stop": 0.5}, "rtol": 1e-6, "atol": 0.0, "columns": null,
     "noise": {"coupler.omega": 1.28e-12}, "study": {"kernels": ...}}

Each case runs with :func:`dsim.simulate` and is compared with
:func:`dsim.master.checks.compare.compare_files` (a tolerance band over time, with a floor that
round-off cannot cross; first and worst violation per signal).  ``update`` runs
each case and stores its results as the new baseline instead, and (unless told not
to) measures with :mod:`dsim.master.checks.kernel_study` how far each column moves between
OpenBLAS kernels: ``noise``, the band's floor, with the ``study`` that measured it.
Nothing else writes a baseline.
"""
from __future__ import annotations

import json
import tempfile
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from xml.etree import ElementTree

from dsim.master.api import simulate
from dsim.master.checks.compare import band_origin, compare_files
from dsim.master.checks.kernel_study import study
from dsim.master.errors import InputError
from dsim.master.recording.output_files import write_whole

DEFAULTS = {"settings": {}, "rtol": 1e-6, "atol": 0.0, "columns": None}
#: what --update measures and stores besides (absent from older baselines: then the
#: bands' floor is the ulps one only)
MEASURED = ("noise", "study")


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
    noise: dict = field(default_factory=dict)
    #: folders whose files the scene may name besides its own (``--allow-outside``)
    allow_outside: tuple = ()


@dataclass
class KernelChoice:
    """What ``update`` does about the kernel study: run it (``enabled``), under these
    kernels (None: every one the CPU supports)."""

    enabled: bool = True
    kernels: list | None = None


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


def find_cases(folder, baselines=None, only=(), update: bool = False, allow_outside=()
               ) -> tuple[list[Case], list[str]]:
    """The cases of ``folder`` that have a baseline (``baselines`` defaults to
    ``folder/baselines``; with ``update`` every scene, a missing baseline to be
    written), and the names of the scenes that have none.  ``allow_outside``: folders
    whose files the scenes may name besides their own (docs/security.md)."""
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
        cases.append(replace(_case(name, scene, baselines),
                             allow_outside=tuple(allow_outside or ())))
    return cases, without


def _case(name: str, scene: Path, baselines: Path) -> Case:
    spec = baselines / f"{name}.json"
    values = dict(DEFAULTS)
    if spec.is_file():
        try:
            values.update(json.loads(spec.read_text()))
        except json.JSONDecodeError as error:
            raise InputError(f"{spec}: not JSON: {error}") from None
        unknown = set(values) - set(DEFAULTS) - set(MEASURED)
        if unknown:
            raise InputError(f"{spec}: unknown keys {', '.join(sorted(unknown))} (known: "
                             f"{', '.join([*DEFAULTS, *MEASURED])})")
    return Case(name, scene, baselines / f"{name}.csv", dict(values["settings"]),
                float(values["rtol"]), float(values["atol"]), values["columns"],
                noise_map(values.get("noise"), spec))


def noise_map(noise, spec) -> dict[str, float]:
    """A baseline JSON's ``noise`` (column -> spread between kernels) checked: absent
    is none measured; anything but non-negative numbers is bad input."""
    noise = {} if noise is None else noise
    if not isinstance(noise, dict) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and v >= 0
            for v in noise.values()):
        raise InputError(f"{spec}: noise must map column names to non-negative numbers")
    return {str(k): float(v) for k, v in noise.items()}


def read_noise(spec) -> dict[str, float]:
    """The ``noise`` of a baseline JSON file (``dsim compare --noise``)."""
    try:
        record = json.loads(Path(spec).read_text())
    except OSError as error:
        raise InputError(f"{spec}: cannot read: {error.strerror}") from None
    except json.JSONDecodeError as error:
        raise InputError(f"{spec}: not JSON: {error}") from None
    if not isinstance(record, dict):
        raise InputError(f"{spec}: not a baseline JSON (an object with settings, rtol, ...)")
    return noise_map(record.get("noise"), spec)


def run_case(case: Case, results: Path, update: bool = False, rtol=None,
             atol=None, kernels: KernelChoice | None = None) -> Outcome:
    """Run one case into ``results`` and compare it with its baseline (or, with
    ``update``, store it as the baseline, and its kernel study as ``kernels`` says)."""

    start = time.perf_counter()
    out = results / f"{case.name}.csv"
    try:
        result = simulate(case.scene, out=out, handle_signals=False,
                          allow_outside=list(case.allow_outside) or None, **case.settings)
    except InputError as error:
        return Outcome(case, "error", "; ".join(error.problems),
                       seconds=time.perf_counter() - start)
    seconds = time.perf_counter() - start
    if result.status != "completed":
        return Outcome(case, "failed", result.message, seconds=seconds, results=out)
    if update:
        write_whole(case.baseline, out.read_bytes())
        said = _store_study(case, kernels or KernelChoice())
        return Outcome(case, "updated", f"baseline {case.baseline} ({result.steps} steps)"
                       + (f"; {said}" if said else ""),
                       seconds=time.perf_counter() - start, results=out)
    if not case.baseline.is_file():
        return Outcome(case, "error", f"{case.baseline}: no baseline (run with --update)",
                       seconds=seconds, results=out)
    try:
        comparison = compare_files(out, case.baseline, case.columns,
                                   case.rtol if rtol is None else rtol,
                                   case.atol if atol is None else atol, case.noise)
    except InputError as error:
        return Outcome(case, "error", "; ".join(error.problems), seconds=seconds, results=out)
    if comparison.passed:
        return Outcome(case, "passed", "", comparison, seconds, out)
    return Outcome(case, "regressed", _regression(comparison), comparison, seconds, out)


def _store_study(case: Case, kernels: KernelChoice) -> str:
    """Measure the case's kernel noise (unless not wanted) and write its JSON: the
    settings and band kept as they were, ``noise`` and ``study`` replaced; what was
    done, in words.  Without a study the stored noise is kept: it belongs to the
    scene and its settings, and dropping it would tighten the bands below round-off."""
    spec = case.baseline.with_suffix(".json")
    record = json.loads(spec.read_text()) if spec.is_file() else {
        **DEFAULTS, "settings": case.settings}
    measured = study(case.scene, case.settings, case.baseline, kernels.kernels,
                     allow_outside=case.allow_outside) if kernels.enabled else None
    if measured is None or measured.skipped:
        said = measured.skipped if measured else "no kernel study (asked not to)"
        if record.get("noise"):
            said += "; the stored noise is kept"
        if spec.is_file():
            return said  # nothing new to store: the file stays as its author wrote it
    else:
        # three significant digits (the floor is ten times it): a readable JSON, and
        # a review diff that shows changes of the spread, not of its last bits
        record["noise"] = {name: float(f"{value:.3g}") for name, value in
                           measured.noise.items() if value > 0}
        record["study"] = measured.record()
        ran = [k for k in measured.kernels if k != "default"]
        said = (f"kernel study: {', '.join(ran) or 'no kernel'} besides the default "
                f"{measured.kernels['default']}, {len(record['noise'])} columns differ, "
                f"{measured.seconds:.1f} s")
        if measured.failed:
            said += "; FAILED under " + "; ".join(
                f"{k}: {v}" for k, v in measured.failed.items())
    write_whole(spec, (json.dumps(record, indent=2) + "\n").encode())
    return said


def _regression(comparison) -> str:
    parts = []
    if comparison.short:
        parts.append(f"ends at t = {comparison.result_end:g} s, before the baseline "
                     f"({comparison.reference_end:g} s)")
    for d in comparison.failed:
        origin = "" if d.source == "rtol" else f", {band_origin(d)}"
        parts.append(f"{d.column}: outside the band from t = {d.first[0]:.6g} s, worst at "
                     f"t = {d.worst[0]:.6g} s ({d.worst[1]:.6g} against {d.worst[2]:.6g}, "
                     f"allowed +-{d.allowed:.3g}{origin})")
    return "; ".join(parts)


def run_cases(cases, results=None, update=False, rtol=None, atol=None, progress=None,
              kernels: KernelChoice | None = None):
    """Every case's outcome (``results``: where the runs' CSVs go; a temporary folder
    when None; ``kernels``: the kernel study of ``update``)."""
    outcomes = []
    with tempfile.TemporaryDirectory(prefix="dsim-regress-") as temp:
        folder = Path(results) if results else Path(temp)
        for case in cases:
            outcome = run_case(case, folder, update, rtol, atol, kernels)
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
            origin = "" if d.source == "rtol" else f", {d.source} floor"
            worst = f"{d.column} {d.max_difference:.2e} (allowed {d.allowed:.2e}{origin})"
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
