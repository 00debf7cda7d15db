"""User mistakes give exit code 2 and one line naming the problem, never a
traceback; a failed simulation exits 1 and keeps its converged steps."""
import subprocess
import sys
import zipfile

import numpy as np

from dsim.master.recording.results import read_csv
from dsim.master.tools.cli import main
from tests.support.runs import run_cli
from tests.support.scenes import archive_with


def test_missing_file(capsys, tmp_path):
    code, lines = run_cli(capsys, tmp_path / "nope.ssp", "--out", tmp_path / "o.csv")
    assert code == 2 and len(lines) == 1 and "nope.ssp: no such file" in lines[0]


def test_not_a_zip(capsys, tmp_path):
    bad = tmp_path / "text.ssp"
    bad.write_text("hello")
    code, lines = run_cli(capsys, bad)
    assert code == 2 and len(lines) == 1 and "not an SSP archive (not a zip file)" in lines[0]


def test_archive_without_system_structure(capsys, tmp_path):
    bad = tmp_path / "empty.ssp"
    with zipfile.ZipFile(bad, "w") as archive:
        archive.writestr("readme.txt", "nothing")
    code, lines = run_cli(capsys, bad)
    assert code == 2 and len(lines) == 1 and "no SystemStructure.ssd" in lines[0]


def test_malformed_xml(capsys, tmp_path, built):
    bad = archive_with(tmp_path, built, replace=[("</ssd:System>", "</ssd:Sys>")])
    code, lines = run_cli(capsys, bad)
    assert code == 2 and len(lines) == 1 and "malformed XML" in lines[0]


def test_referenced_fmu_missing(capsys, tmp_path, built):
    bad = archive_with(tmp_path, built, drop=["resources/SpringMass.fmu"])
    code, lines = run_cli(capsys, bad)
    assert code == 2 and len(lines) == 2  # both components name the missing FMU
    assert all("FMU 'resources/SpringMass.fmu' not found" in line for line in lines)
    assert "Component 'left'" in lines[0] and "Component 'right'" in lines[1]


def test_unknown_component_in_joint(capsys, tmp_path, built):
    bad = archive_with(tmp_path, built, replace=[('a="left.P"', 'a="lefty.P"')])
    code, lines = run_cli(capsys, bad)
    assert code == 2 and len(lines) == 1
    assert "Joint 'j1'" in lines[0] and "unknown component 'lefty'" in lines[0]


def test_port_that_does_not_exist(capsys, tmp_path, built):
    bad = archive_with(tmp_path, built, replace=[('b="right.Q"', 'b="right.Z"')])
    code, lines = run_cli(capsys, bad)
    assert code == 2 and len(lines) == 1
    assert "component 'right' has no port 'Z' (ports: P, Q)" in lines[0]


def test_unknown_parameter_and_bad_master_setting(capsys, tmp_path, built):
    bad = archive_with(tmp_path, built, replace=[('refreshAfter="10"', 'refreshAfter="ten"')])
    code, lines = run_cli(capsys, bad)
    assert code == 2 and len(lines) == 1 and "glue:Master: refreshAfter 'ten' is not an integer" in lines[0]


def test_bad_input_through_the_console_has_no_traceback(tmp_path):
    process = subprocess.run([sys.executable, "-m", "dsim.master.tools.cli", "run",
                              str(tmp_path / "missing.ssp")], capture_output=True, text=True)
    assert process.returncode == 2
    assert "Traceback" not in process.stderr and len(process.stderr.splitlines()) == 1


def test_failed_run_exits_1_and_keeps_converged_steps(capsys, tmp_path, built):
    """Two iterations are not enough for every step of the nonlinear scene: with no
    step cut allowed, the run stops at the first step that needs more, naming it and
    the joint."""
    out = tmp_path / "failed.csv"
    code = main(["run", str(built["ssp"] / "spring_mass_nonlinear.ssp"), "--out", str(out),
                 "--max-iterations", "2", "--step-cuts", "0", "--quiet"])
    err = capsys.readouterr().err
    assert code == 1
    assert "joint 'j1' (j1.f_x) did not converge in 2 iterations" in err
    header, data = read_csv(out)
    failed_step = int(err.split("step ")[1].split(" ")[0])
    assert data.shape[0] == failed_step  # t0 plus every converged step
    assert failed_step >= 2 and np.all(np.isfinite(data))  # step 1 converged, kept
    assert '"status": "failed"' in out.with_suffix(".stats.json").read_text()
