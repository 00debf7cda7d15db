"""Scenes of thousands of components: checked with the right findings, with the work
per FMU file done once and the rest growing linearly; instances of one FMU file
sharing one binding of its library (docs/scaling.md has the times)."""
from __future__ import annotations

import cProfile
import hashlib
import pstats
import shutil
from pathlib import Path

import numpy as np
from fmpy.fmi2 import FMU2Slave

import dsim
from dsim.build_fmus.scenes import CHAIN, chain
from dsim.master.api import prepare
from dsim.master.checks.validate import validate
from dsim.master.reading import digests, fmi_description, ports
from dsim.master.reading.fmu_archive import unzipped
from dsim.master.running.backends.inprocess import InProcessBackend
from dsim.master.running.fmi import library
from tests.support.paths import ROOT


def chain_folder(folder: Path, fmu: Path, count: int, broken: bool = False) -> Path:
    """A chain of ``count`` SpringMass components (one FMU file) as a scene folder;
    ``broken``: with one joint on a port no FMU has and one component binding a value
    to no variable."""
    scene = chain(count)
    if broken:
        middle = count // 2
        scene.joint("jbad", f"m{middle}.R", f"m{middle + 1}.P")
        scene.component("extra", "SpringMass", {"n": 1, "no_such": 2.0}, inline=True)
    scene.write(folder, 0.0, CHAIN["stop"], step=CHAIN["step"], tolerance=1e-13,
                maxIterations=20, predictor="linear", refreshAfter=10)
    (folder / "resources").mkdir(exist_ok=True)
    shutil.copy(fmu, folder / "resources" / "SpringMass.fmu")
    return folder


def test_ten_thousand_components_validate_with_the_right_findings(built, tmp_path,
                                                                   monkeypatch):
    """Every finding said once, and the FMU file's work (hash, description, ports)
    done once for 10,001 components."""
    hashed, described = [], []
    real_sha, real_read = hashlib.sha256, fmi_description.read_model_description
    monkeypatch.setattr(digests.hashlib, "sha256",
                        lambda data: hashed.append(len(data)) or real_sha(data))
    monkeypatch.setattr(fmi_description, "read_model_description",
                        lambda *a, **k: described.append(a) or real_read(*a, **k))
    monkeypatch.setattr(fmi_description, "_READ", {})  # not parsed by a test before
    misses = ports._file_ports.cache_info().misses
    folder = chain_folder(tmp_path / "chain", built["fmus"] / "SpringMass.fmu", 10_000,
                          broken=True)
    found = validate(folder)
    assert len(found.errors) == 1, found.errors[:5]
    assert "Joint 'jbad'" in found.errors[0]
    assert "component 'm5000' has no port 'R' (ports: P, Q)" in found.errors[0]
    assert [w for w in found.warnings if "no_such" in w] == [w for w in found.warnings
                                                          if "not applied" in w]
    assert len([w for w in found.warnings if "no_such" in w]) == 1
    assert "parameter 'no_such' is not a variable of component 'extra'" in \
        " ".join(found.warnings)
    # one FMU file: hashed once, its description parsed once, its ports matched once
    assert len(hashed) == 1 and len(described) == 1
    assert ports._file_ports.cache_info().misses - misses == 1


def _calls(folder: Path) -> int:
    """Python function calls that validating ``folder`` makes (deterministic: the
    same scene makes the same calls on any machine, however loaded)."""
    profiler = cProfile.Profile()
    profiler.enable()
    found = validate(folder)
    profiler.disable()
    assert found.ok, found.errors[:3]
    return pstats.Stats(profiler).total_calls


def test_validation_grows_linearly_with_the_components(built, tmp_path):
    """Ten times the components, at most about ten times the work: a scan per
    look-up (the components by name, a system's annotations read once per component
    inside it) made it a hundred times."""
    fmu = built["fmus"] / "SpringMass.fmu"
    small = chain_folder(tmp_path / "small", fmu, 300)
    large = chain_folder(tmp_path / "large", fmu, 3000)
    _calls(small)  # what is done once per process (imports, schemas) done before
    ratio = _calls(large) / _calls(small)
    assert 8 < ratio < 11, ratio


def test_instances_of_one_fmu_file_share_one_binding_of_its_library(built, tmp_path):
    """Ten instances, one binding of the library's functions; freed with the last
    instance, and made again by the next run, whose results are the same."""
    folder = chain_folder(tmp_path / "chain", built["fmus"] / "SpringMass.fmu", 10)
    plan = prepare(folder)
    path = plan.specs[0].path
    shared = str(Path(unzipped(path)) / "binaries" / fmi_description.library_folder(
        fmi_description.describe(path)) / "SpringMass.so")
    backend = InProcessBackend.from_specs(plan.specs)
    try:
        assert library.binds(FMU2Slave, shared) == 10
        functions = {id(s.fmu._functions) for s in backend.subsystems}
        assert len(functions) == 1
        # the time loop's functions and value-reference arrays: one object per file
        steps = {id(s.call("fmi2DoStep").function) for s in backend.subsystems}
        forces = {id(s._forces.vrs) for s in backend.subsystems}
        distinct = {tuple(s._forces.vrs) for s in backend.subsystems}  # ends, middles
        values = {id(s._forces.values) for s in backend.subsystems}
        assert (len(steps), len(forces), len(values)) == (1, len(distinct), 10)
        assert len(distinct) < 10
    finally:
        assert backend.close() == []
    assert library.binds(FMU2Slave, shared) == 0
    first = dsim.simulate(folder, stop=0.05, handle_signals=False)
    assert library.binds(FMU2Slave, shared) == 0  # the run freed its instances
    again = dsim.simulate(folder, stop=0.05, handle_signals=False)
    columns = [f"m{i}.x[1]" for i in range(1, 11)]
    assert all(np.array_equal(first.signals[c], again.signals[c]) for c in columns)
    assert np.abs(first.signals["m1.x[1]"]).max() > 1e-6  # it moved


def test_a_run_keeps_its_set_up_out_of_the_collectors_passes_until_it_ends(built,
                                                                           tmp_path):
    """The scene, plan and instances of an in-process run are frozen (gc.freeze) from
    the end of its set-up to its end: the collector's full passes do not walk them at
    every few steps; two runs at once thaw them when the last ends, and a run's end
    gives every object back (freed cycles included)."""
    import gc

    from dsim.master.recording.observers import Observer

    folder = chain_folder(tmp_path / "chain", built["fmus"] / "SpringMass.fmu", 30)
    seen = []

    class Frozen(Observer):
        def stepped(self, record):
            seen.append(gc.get_freeze_count())

    before = gc.get_freeze_count()
    plan = prepare(folder)
    outer = InProcessBackend.from_specs(plan.specs)
    try:
        held = gc.get_freeze_count() - before
        assert held > 30 * 50  # every instance's objects, at least
        result = dsim.simulate(folder, stop=0.01, handle_signals=False,
                               observers=[Frozen()])
        # the inner run's are frozen with it, and its end left the outer's frozen
        assert len(seen) == 11 and min(seen) - before - held > 30 * 50
        assert gc.get_freeze_count() - before > 0.9 * held
    finally:
        assert outer.close() == []
    assert gc.get_freeze_count() == before
    assert np.abs(result.signals["m1.x[1]"]).max() > 1e-6


def test_the_benchmarks_page_quotes_the_scaling_tables_as_they_stand(tmp_path):
    """docs/benchmarks.md quotes docs/scaling.md's figures (benchmarks/scaling.py rewrites
    the quote with its page), and the quote reads them from the right cells."""
    from benchmarks import scaling

    docs = ROOT / "docs"
    page = (docs / "scaling.md").read_text()
    line = scaling.quote(page)
    assert line in (docs / "benchmarks.md").read_text().splitlines()
    row = next(text for text in page.splitlines() if text.startswith("| 10000 | ")
               and text.count("|") == 14)
    cells = [cell.strip() for cell in row.strip("|").split("|")]
    assert f"sets up in {cells[2]} s, peaks at {cells[12]} MB and takes {cells[9]} times" \
        in line
    # a page measured again: the quote is rewritten in place, not added again
    target = tmp_path / "benchmarks.md"
    target.write_text((docs / "benchmarks.md").read_text())
    smaller = row.rsplit(f"| {cells[12]} ", 1)[0] + "| 1 |"  # peak memory 1 MB
    scaling.requote(target, page.replace(row, smaller))
    quoted = [text for text in target.read_text().splitlines()
              if text.startswith(scaling.QUOTE_START)]
    assert len(quoted) == 1 and "peaks at 1 MB" in quoted[0], quoted
