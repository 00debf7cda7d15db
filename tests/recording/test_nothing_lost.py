"""Nothing is lost when a run fails, is interrupted or meets a bad file: outputs
never overwrite inputs, are written under a temporary name and locked, hold only
whole rows, and keep every converged step with the statistics beside them."""
import hashlib
import json
import resource
import signal
import subprocess
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

import dsim
from dsim.master.recording.results import read_csv
from tests.support.paths import DSIM, ROOT
from tests.support.runs import run_cli
from tests.support.scene_files import pack
from tests.support.scenes import block_scene


def digest(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@pytest.mark.parametrize("which", ["scene", "plot"])
def test_an_output_that_is_an_input_of_the_run_is_refused(built, tmp_path, capsys, which):
    scene = tmp_path / "scene.ssp"
    scene.write_bytes((built["ssp"] / "spring_mass_linear.ssp").read_bytes())
    before = digest(scene)
    args = ["--out", scene] if which == "scene" else ["--out", tmp_path / "r.csv",
                                                      "--plot", scene]
    code, lines = run_cli(capsys, scene, *args)
    assert code == 2 and len(lines) == 1
    assert "this output would overwrite an input of the run" in lines[0]
    assert digest(scene) == before
    assert not (tmp_path / "r.csv").exists()


def test_an_fmu_of_a_scene_folder_is_an_input_too(block_fmus, tmp_path, capsys):
    folder = block_scene(tmp_path / "scene", block_fmus["state"])
    fmu = folder / "resources" / "block.fmu"
    before = digest(fmu)
    code, lines = run_cli(capsys, folder, "--out", fmu)
    assert code == 2 and "would overwrite an input" in lines[0] and digest(fmu) == before


class PeekAtFiles(dsim.Observer):
    """Looks at the output folder while the run is going."""

    def __init__(self, target: Path):
        self.target, self.seen, self.files = target, [], {}

    def stepped(self, record):
        if record.index == 5:
            self.seen = sorted(p.name for p in self.target.parent.iterdir())


def test_results_grow_under_a_temporary_name_and_are_renamed_at_the_end(built, tmp_path):
    target = tmp_path / "run.csv"
    target.write_text("an older result\n")
    peek = PeekAtFiles(target)
    result = dsim.simulate(built["ssp"] / "spring_mass_linear.ssp", stop=0.1, out=target,
                           observers=[peek])
    # the older result stays meanwhile; the statistics' temporary file is reserved too
    assert peek.seen == [".run.csv.partial", ".run.stats.json.partial", "run.csv"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.csv", "run.stats.json"]
    header, data = read_csv(target)
    assert result.ok and data.shape == (11, len(header))


def test_a_failed_run_keeps_its_converged_rows_under_the_final_name(built, tmp_path):
    target = tmp_path / "failed.csv"
    result = dsim.simulate(built["ssp"] / "spring_mass_nonlinear.ssp", max_iterations=2,
                           step_cuts=0, out=target)
    assert result.status == "failed"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["failed.csv", "failed.stats.json"]
    assert read_csv(target)[1].shape[0] == result.steps + 1


def _wait_for(path: Path, seconds: float = 60.0) -> None:
    deadline = time.monotonic() + seconds
    while not path.exists():
        assert time.monotonic() < deadline, f"{path} never appeared"
        time.sleep(0.05)


def _long_run(scene, target: Path, **popen):
    """dsim run on a long span, as a user would start it."""
    return subprocess.Popen(DSIM + ["run", str(scene), "--stop", "1e6", "--out", str(target),
                                    "--quiet", "--force"], cwd=ROOT, stderr=subprocess.PIPE,
                            text=True,
                            **popen)


@pytest.mark.parametrize("signal_number", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_ends_the_run_after_a_step_with_everything_written(
        block_fmus, tmp_path, capsys, signal_number):
    """Also: a second run on the same output is refused while the first holds it, and
    a stop time of 1e6 s (1e9 steps, more than the disk takes: --force) starts at once
    (step times come as the run goes)."""
    folder = block_scene(tmp_path / "scene", block_fmus["state"])
    target = tmp_path / "out" / "run.csv"
    process = _long_run(folder, target)
    try:
        _wait_for(target.with_name(".run.csv.partial"))
        time.sleep(0.5)
        code, lines = run_cli(capsys, folder, "--stop", "1", "--out", target)
        assert code == 2 and len(lines) == 1 and "another run is writing this file" in lines[0]
        process.send_signal(signal_number)
        _, err = process.communicate(timeout=60)
    finally:
        process.kill()
    assert process.returncode == 128 + signal_number
    assert f"dsim: interrupted: interrupted by {signal.Signals(signal_number).name}" in err
    header, data = read_csv(target)
    stats = json.loads(target.with_suffix(".stats.json").read_text())
    assert stats["status"] == "interrupted" and stats["steps"] == data.shape[0] - 1 > 10
    # what ended it, as the command said it (the statistics said "message": null)
    name = signal.Signals(signal_number).name
    assert stats["message"] == (f"interrupted by {name} (stopped at t = "
                                f"{stats['time_reached']:g} s, step {stats['steps']} of "
                                f"{stats['planned_steps']})")
    assert np.allclose(np.diff(data[:, 0]), 1e-3)
    assert sorted(p.name for p in target.parent.iterdir()) == ["run.csv", "run.stats.json"]


def test_a_full_disk_leaves_whole_rows_and_one_line(block_fmus, tmp_path):
    """No file may grow beyond 60 kB (a file size limit stands in for a full disk):
    the 10 000 rows of the run do not fit."""
    folder = block_scene(tmp_path / "scene", block_fmus["state"], stop=10.0)
    target = tmp_path / "run.csv"

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (60_000, 60_000))

    process = subprocess.run(DSIM + ["run", str(folder), "--out", str(target), "--quiet"],
                             cwd=ROOT, text=True, capture_output=True, preexec_fn=limit,
                             timeout=120)
    assert process.returncode == 1
    lines = process.stderr.strip().splitlines()
    assert lines[0].startswith(f"dsim: simulation failed: cannot write {target}: File too large")
    header, data = read_csv(target)  # whole rows only: read_csv refuses anything else
    assert 1000 < data.shape[0] < 10001 and target.stat().st_size <= 60_000
    stats = json.loads(target.with_suffix(".stats.json").read_text())
    assert stats["status"] == "failed" and stats["steps"] >= data.shape[0] - 1


def test_an_unwritable_output_is_one_line_before_anything_runs(built, tmp_path, capsys):
    (tmp_path / "file").write_text("a file, not a folder")
    code, lines = run_cli(capsys, built["ssp"] / "spring_mass_linear.ssp", "--out",
                          tmp_path / "file" / "run.csv")
    assert code == 2 and len(lines) == 1
    assert lines[0].endswith(f"run.csv: cannot write: {tmp_path / 'file'} is a file, not a "
                             "folder")


def test_a_non_finite_output_ends_the_run_naming_component_variable_step_and_time(
        block_fmus, tmp_path, capsys):
    folder = block_scene(tmp_path / "scene", block_fmus["state"], failure=1, fail_time=0.0505)
    target = tmp_path / "run.csv"
    code, lines = run_cli(capsys, folder, "--out", target)
    assert code == 1
    assert lines[0] == ("dsim: simulation failed: step 51 (t = 0.051 s): component 'b1' "
                        "output 'y' is not finite (nan)")
    header, data = read_csv(target)
    assert data.shape[0] == 51 and np.all(np.isfinite(data))


@pytest.mark.parametrize("failure, status", [(2, "fmi2Error"), (3, "fmi2Discard")])
def test_an_fmu_error_names_component_step_time_and_carries_its_log(
        block_fmus, tmp_path, capsys, failure, status):
    folder = block_scene(tmp_path / "scene", block_fmus["state"], failure=failure,
                         fail_time=0.0505)
    code, lines = run_cli(capsys, folder, "--out", tmp_path / "run.csv")
    assert code == 1
    assert lines[0].startswith(f"dsim: simulation failed: step 51 (t = 0.051 s): component "
                               f"'b1': fmi2DoStep failed: it returned {status} (block: ")
    assert read_csv(tmp_path / "run.csv")[1].shape[0] == 51
    # the FMU's fmi2Terminate fails too: said after the error, never instead of it
    assert lines[-1].startswith("dsim: warning: releasing the subsystems: component 'b1': "
                                "fmi2Terminate failed")
    assert lines[-1].endswith("(block: cannot terminate cleanly after the failure)")


def test_a_truncated_fmu_archive_is_one_line_before_any_step(block_fmus, tmp_path, capsys):
    data = block_fmus["state"].read_bytes()
    folder = block_scene(tmp_path / "scene", block_fmus["state"])
    (folder / "resources" / "block.fmu").write_bytes(data[: len(data) // 2])
    code, lines = run_cli(capsys, folder, "--out", tmp_path / "run.csv")
    assert code == 2 and len(lines) == 1
    assert "Component 'b1'" in lines[0] and "FMU block.fmu: not a readable FMU archive" in lines[0]
    assert not (tmp_path / "run.csv").exists()


def test_a_truncated_fmu_binary_is_one_line_never_a_crash(block_fmus, tmp_path):
    """Mapping a library cut short kills the process that loads it (SIGBUS): dsim
    loads it in a child process first."""
    source = block_fmus["state"]
    broken = tmp_path / "block.fmu"
    with zipfile.ZipFile(source) as old, zipfile.ZipFile(broken, "w") as new:
        for name in old.namelist():
            content = old.read(name)
            if name.endswith(".so"):
                content = content[: len(content) // 3]
            new.writestr(name, content)
    folder = block_scene(tmp_path / "scene", broken)
    process = subprocess.run(DSIM + ["run", str(folder), "--out", str(tmp_path / "r.csv")],
                             cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert process.returncode == 2
    lines = process.stderr.strip().splitlines()
    assert len(lines) == 1 and "its library binaries/linux64/block.so" in lines[0]
    # its ELF headers point past its end: refused from its bytes, before any loading
    assert "is cut short" in lines[0]


def test_a_packed_scene_with_a_bad_fmu_is_refused_too(block_fmus, tmp_path, capsys):
    folder = block_scene(tmp_path / "scene", block_fmus["state"])
    (folder / "resources" / "block.fmu").write_bytes(b"PK\x03\x04 not really")
    archive = pack(folder, tmp_path / "scene.ssp")
    code, lines = run_cli(capsys, archive, "--out", tmp_path / "r.csv")
    assert code == 2 and len(lines) == 1 and "not a readable FMU archive" in lines[0]
