"""The CI tools: `dsim validate` (every check of a run, one line per finding) and
`dsim regress` (every shipped scene against its stored baseline, JUnit report)."""
import json
import shutil
from pathlib import Path
from xml.etree import ElementTree

from dsim.master.tools.cli import main
from tests.support.interop import block, connection, connectors, system, write_scene
from tests.support.paths import ROOT


def test_validate_says_every_finding_in_one_line_each(block_fmus, tmp_path, capsys):
    bad = system(
        block("b1", inside=connectors(("nope", "output", "Real", None),
                                      ("u", "output", "Real", None),
                                      ("count", "output", "Real", None)))
        + block("b2", "resources/missing.fmu"),
        connection("b1", "y", "b1", "extra"))
    folder = write_scene(tmp_path / "bad", bad, {"block.fmu": block_fmus["state"]})
    assert main(["validate", str(folder)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    expected = ["Component 'b2'", "FMU 'resources/missing.fmu' not found"]
    assert any(all(part in line for part in expected) for line in lines)
    errors = [line for line in lines if line.startswith("dsim: error: ")]
    for text in ("connector 'u' is declared output, but the FMU's variable is input",
                 "connects a Real 'b1.y' to a Integer 'b1.extra'"):
        assert sum(text in line for line in errors) == 1, text
    # what changes nothing a run computes is a warning (docs/ssp_support.md)
    warnings = [line for line in lines if line.startswith("dsim: warning: ")]
    for text in ("1 connector(s) name no variable of block.fmu and are connected to "
                 "nothing: dropped (nope)",
                 "connector 'count' is declared Real, but the FMU's variable is Integer"):
        assert sum(text in line for line in warnings) == 1, text
    assert len(errors) + len(warnings) == len(lines)
    assert all("SystemStructure.ssd line" in line for line in lines)  # where, each time


def test_validate_runs_no_code_of_the_fmus(tmp_path):
    """A library runs its constructors when it is loaded: validating a scene reads its
    FMUs' libraries as bytes only (a C FMU that writes a marker file from a constructor
    leaves none), while a run does load it."""
    import subprocess
    import sys

    from tests.support.third_party.build import c_fmu

    marker = tmp_path / "constructor-ran"
    fmu = c_fmu(tmp_path / "fmu", "marker", source="marker.c",
                defines=[f'MARKER_FILE="{marker}"'])
    folder = write_scene(tmp_path / "scene", system(block("b1", "resources/marker.fmu")),
                         {"marker.fmu": fmu})
    command = [sys.executable, "-m", "dsim.master.tools.cli"]
    checked = subprocess.run(command + ["validate", str(folder)], cwd=ROOT,
                             capture_output=True, text=True, timeout=120)
    assert checked.returncode == 0, checked.stderr
    assert not marker.exists(), "dsim validate loaded the FMU's library"
    ran = subprocess.run(command + ["run", str(folder), "--out", str(tmp_path / "r.csv"),
                                    "--quiet"], cwd=ROOT, capture_output=True, text=True,
                         timeout=120)
    assert ran.returncode == 0, ran.stderr
    assert marker.read_text().startswith("loaded")  # the marker FMU does write it


def test_validate_passes_every_shipped_scene(built, capsys):
    for archive in sorted(built["ssp"].glob("*.ssp")):
        assert main(["validate", str(archive)]) == 0, archive
    assert capsys.readouterr().out.count(": valid: ") == len(list(built["ssp"].glob("*.ssp")))


def test_every_shipped_scene_matches_its_baseline(built, tmp_path, capsys):
    """The repository's baselines (regression/baselines): a regression check of dsim
    itself, and what docs/ci.md tells users to run."""
    report = tmp_path / "report.xml"
    code = main(["regress", str(built["ssp"]), "--baselines",
                 str(ROOT / "regression" / "baselines"), "--junit", str(report)])
    out = capsys.readouterr().out
    assert code == 0, out
    suite = ElementTree.parse(report).getroot().find("testsuite")
    names = {case.get("name") for case in suite.iter("testcase")}
    assert names == {path.stem for path in built["ssp"].glob("*.ssp")}
    assert suite.get("failures") == "0" and suite.get("errors") == "0"


def regress_folder(built, tmp_path) -> Path:
    """A scene folder with spring_mass_linear and a baseline made by --update."""
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    shutil.copy(built["ssp"] / "spring_mass_linear.ssp", scenes)
    shutil.copy(built["ssp"] / "chain_10.ssp", scenes)  # no baseline: not run
    baselines = scenes / "baselines"
    baselines.mkdir()
    (baselines / "spring_mass_linear.json").write_text(json.dumps(
        {"settings": {"stop": 0.5}, "rtol": 1e-6}))
    assert main(["regress", str(scenes), "--update", "--scene", "spring_mass_linear"]) == 0
    return scenes


def test_regress_finds_a_regression_and_reports_it(built, tmp_path, capsys):
    scenes = regress_folder(built, tmp_path)
    baseline = scenes / "baselines" / "spring_mass_linear.csv"
    header, *rows = baseline.read_text().splitlines()
    assert len(rows) == 51
    assert main(["regress", str(scenes)]) == 0
    out = capsys.readouterr().out
    assert "spring_mass_linear" in out and "passed" in out
    assert "without a baseline (not run): chain_10" in out
    # the stored baseline drifts from t = 0.3 s: the run no longer matches it
    column = header.split(",").index("right.x[2]")
    edited = []
    for k, row in enumerate(rows):
        values = row.split(",")
        if k >= 30:
            values[column] = repr(float(values[column]) + 1e-3 * (k - 29))
        edited.append(",".join(values))
    baseline.write_text("\n".join([header] + edited) + "\n")
    report = tmp_path / "report.xml"
    assert main(["regress", str(scenes), "--junit", str(report),
                 "--results", str(tmp_path / "runs")]) == 1
    err = capsys.readouterr().err
    assert "spring_mass_linear: regressed: right.x[2]: outside the band from t = 0.3 s, " \
           "worst at t = 0.5 s" in err
    failure = ElementTree.parse(report).getroot().find("testsuite/testcase/failure")
    assert failure is not None and "right.x[2]" in failure.get("message")
    assert (tmp_path / "runs" / "spring_mass_linear.csv").is_file()  # kept for a look


def test_regress_update_writes_the_missing_baselines(built, tmp_path, capsys):
    scenes = regress_folder(built, tmp_path)
    assert not (scenes / "baselines" / "chain_10.json").exists()
    # chain_10 had none: now it has (without the kernel study, spring_mass_linear's
    # JSON stays as the first --update wrote it, noise and all)
    study = (scenes / "baselines" / "spring_mass_linear.json").read_text()
    assert main(["regress", str(scenes), "--update", "--no-kernel-study"]) == 0
    assert (scenes / "baselines" / "spring_mass_linear.json").read_text() == study
    assert "noise" not in json.loads((scenes / "baselines" / "chain_10.json").read_text())
    assert len((scenes / "baselines" / "chain_10.csv").read_text().splitlines()) == 2 + 1000  # header, t = 0, steps
    assert main(["regress", str(scenes)]) == 0
    assert "without a baseline" not in capsys.readouterr().out


def test_regress_refuses_a_folder_without_baselines(built, tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    assert main(["regress", str(tmp_path / "empty")]) == 2
    assert "no scene has a baseline" in capsys.readouterr().err


def test_compare_reports_a_run_that_ends_early(built, tmp_path, capsys):
    full, short = tmp_path / "full.csv", tmp_path / "short.csv"
    assert main(["run", str(built["ssp"] / "spring_mass_linear.ssp"), "--stop", "0.5",
                 "--out", str(full), "--quiet"]) == 0
    assert main(["run", str(built["ssp"] / "spring_mass_linear.ssp"), "--stop", "0.3",
                 "--out", str(short), "--quiet"]) == 0
    assert main(["compare", str(short), str(full)]) == 1
    assert "ends at t = 0.3 s, before the reference (0.5 s)" in capsys.readouterr().err
