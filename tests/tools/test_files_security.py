"""docs/security.md sections 3, 5, 6 and 7 (command line), tested with the attacks as
they were found: real links, a real zip bomb, a real scene of many components, real
archives naming files outside themselves, a killed process's leftovers."""
import hashlib
import os
import re
import signal
import socket
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest

import dsim
from dsim.master.errors import InputError
from dsim.master.reading.unpacking import sweep_dead_folders
from dsim.master.recording.observers import CsvRecorder, RunInfo
from dsim.master.recording.output_files import OutputFile
from tests.support.distributed import AUTHENTICATION
from tests.support.paths import ROOT
from tests.support.scene_files import component, pack, scene_folder, ssd

CLI = [sys.executable, "-m", "dsim.master.tools.cli"]


def digest(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def dsim_cli(*args, tmpdir: Path | None = None, env=None, timeout=120):
    """``python -m dsim.master.tools.cli ARGS``: (exit code, stderr lines)."""
    environment = dict(os.environ, **(env or {}))
    if tmpdir is not None:
        tmpdir.mkdir(exist_ok=True)
        environment["TMPDIR"] = str(tmpdir)
    process = subprocess.run(CLI + [str(a) for a in args], cwd=ROOT, capture_output=True,
                             text=True, timeout=timeout, env=environment)
    assert "Traceback" not in process.stderr, process.stderr
    return process.returncode, process.stderr.strip().splitlines()


@pytest.fixture
def scene(built, tmp_path) -> Path:
    copy = tmp_path / "scene.ssp"
    copy.write_bytes((built["ssp"] / "spring_mass_linear.ssp").read_bytes())
    return copy


def block_scene(folder: Path, fmu: Path, source="resources/block.fmu", **parameters) -> Path:
    text = ssd("block", [component("b1", source, parameters, outputs=["y"])], stop=0.01,
               master='step="0.001"')
    return scene_folder(folder, text, {"block.fmu": fmu})


# --- 3. files dsim writes ---------------------------------------------------------------
@pytest.mark.parametrize("temporary", [".out.csv.partial", ".out.stats.json.partial"])
def test_a_link_at_a_temporary_name_is_never_written_through(scene, tmp_path, temporary):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    target = scene if temporary.endswith("csv.partial") else victim
    before = digest(target)
    (tmp_path / temporary).symlink_to(target)
    code, lines = dsim_cli("run", scene, "--out", tmp_path / "out.csv", "--stop", "0.05",
                           "--quiet")
    assert code == 2 and len(lines) == 1
    assert f"{temporary} exists and is not a file dsim wrote" in lines[0]
    assert digest(target) == before and not (tmp_path / "out.csv").exists()


def test_a_link_at_the_final_name_is_replaced_not_written_through(scene, tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    (tmp_path / "out.csv").symlink_to(victim)
    (tmp_path / "out.stats.json").symlink_to(victim)
    code, lines = dsim_cli("run", scene, "--out", tmp_path / "out.csv", "--stop", "0.05",
                           "--quiet")
    assert code == 0, lines
    assert victim.read_text() == "precious\n"
    for name in ("out.csv", "out.stats.json"):
        assert not (tmp_path / name).is_symlink() and (tmp_path / name).stat().st_size > 10
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "out.csv", "out.stats.json", "scene.ssp", "victim.txt"]


def test_two_runs_on_one_output_never_mix(tmp_path):
    """The interleaving that emptied a finished file: the second run opened the first
    one's temporary file, waited for its lock, and truncated what had been renamed."""
    target = tmp_path / "run.csv"
    first, second = OutputFile(target), OutputFile(target)
    first.open()
    first.append(b"time\n0.0\n")
    with pytest.raises(InputError, match="another run is writing this file now"):
        second.open()
    first.commit()
    second.open()  # after the first: a new file of its own, the finished one untouched
    second.append(b"time\n")
    assert target.read_bytes() == b"time\n0.0\n"
    second.commit()
    assert target.read_bytes() == b"time\n"  # whole, never mixed
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.csv"]


KILLED_WRITER = """
import os, sys
from dsim.master.recording.output_files import OutputFile
output = OutputFile(sys.argv[1])
output.open()
output.append(b"time\\n0.0\\n")
os.kill(os.getpid(), 9)
"""


def test_a_killed_runs_rows_are_kept_under_its_name_by_the_next_run(tmp_path):
    """kill -9 leaves a run's rows in its locked temporary file; the next run that
    writes into the folder ends that file as the killed run would have: renamed to its
    output (nothing converged is lost), and its own file then replaces that output."""
    target = tmp_path / "run.csv"
    for name in ("run.csv", "other.csv"):
        killed = subprocess.run([sys.executable, "-c", KILLED_WRITER, str(tmp_path / name)],
                                cwd=ROOT)
        assert killed.returncode == -9
    assert sorted(p.name for p in tmp_path.iterdir()) == [".other.csv.partial",
                                                          ".run.csv.partial"]
    old = time.time() - 3600  # the other output's: dead and an hour old
    os.utime(tmp_path / ".other.csv.partial", (old, old))
    output = OutputFile(target)
    output.open()  # the same output's lock is free: its run is dead
    assert target.read_bytes() == b"time\n0.0\n"  # the killed run's rows, under its name
    assert (tmp_path / "other.csv").read_bytes() == b"time\n0.0\n"
    output.append(b"time\n")
    output.commit()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other.csv", "run.csv"]
    assert target.read_bytes() == b"time\n"


# --- 5. size --------------------------------------------------------------------------------
def test_a_scene_of_many_components_is_checked_in_linear_time(tmp_path):
    """50 000 components (3.6 MB of SSD): the duplicate-name check was quadratic
    (2.5e9 comparisons, most of an hour); every component's problem is said."""
    count = 50_000
    folder = tmp_path / "many"
    folder.mkdir()
    (folder / "SystemStructure.ssd").write_text(
        ssd("many", [component(f"c{i}", "resources/none.fmu") for i in range(count)]
            + [component("c7", "resources/none.fmu")]))
    started = time.monotonic()
    code, lines = dsim_cli("validate", folder)
    assert time.monotonic() - started < 60
    # one line per component (the two c7 read the same: said once)
    assert code == 2 and len(lines) == count + 1
    assert sum("Component 'c7': component name used twice" in line for line in lines) == 1


@pytest.fixture(scope="module")
def zeros_member():
    """100 MB of zeros: 100 kB compressed, a ratio of 1000 (one member of a zip bomb)."""
    return bytes(100 * 2**20)


def bomb(source: Path, target: Path, data: bytes, member: str = "resources/zeros.bin") -> Path:
    with zipfile.ZipFile(source) as old, zipfile.ZipFile(target, "w",
                                                         zipfile.ZIP_DEFLATED) as new:
        for name in old.namelist():
            new.writestr(name, old.read(name))
        new.writestr(member, data)
    return target


@pytest.mark.parametrize("limit, refusal", [
    (None, "member 'resources/zeros.bin' unpacks to 100 MiB, 1029 times its compressed "
           "size (at most 200: a zip bomb)"),
    ("1048576", "unpacks to 101 MiB (at most 1 MiB)"),
])
def test_a_zip_bomb_is_refused_before_anything_is_unpacked(scene, tmp_path, zeros_member,
                                                           limit, refusal):
    archive = bomb(scene, tmp_path / "bomb.ssp", zeros_member)
    assert archive.stat().st_size < 2**20
    temp = tmp_path / "temp"
    code, lines = dsim_cli("run", archive, "--out", tmp_path / "out.csv", tmpdir=temp,
                           env={"DSIM_MAX_UNPACKED": limit} if limit else {})
    assert code == 2 and len(lines) == 1
    assert lines[0].startswith(f"dsim: error: {archive}: SSP archive") and refusal in lines[0]
    assert list(temp.iterdir()) == []  # nothing unpacked


def test_an_fmu_that_is_a_zip_bomb_is_refused(block_fmus, tmp_path, zeros_member):
    fmu = bomb(block_fmus["state"], tmp_path / "block.fmu", zeros_member,
               "resources/zeros.bin")
    folder = block_scene(tmp_path / "scene", fmu)
    temp = tmp_path / "temp"
    code, lines = dsim_cli("validate", folder, tmpdir=temp)
    assert code == 2 and len(lines) == 1
    # the ratio depends on how well the test's own library compresses: about 970
    assert re.search(r"FMU block\.fmu: FMU archive unpacks to 100 MiB, 9\d\d times its size",
                     lines[0]), lines[0]
    assert "a zip bomb" in lines[0] and list(temp.iterdir()) == []


def test_a_run_whose_results_would_not_fit_the_disk_is_refused(scene, tmp_path):
    code, lines = dsim_cli("run", scene, "--stop", "1e9", "--step", "1e-3", "--out",
                           tmp_path / "out.csv")
    assert code == 2 and len(lines) == 1
    assert "out.csv: the results would take about" in lines[0] and "TB" in lines[0]
    assert " free; " in lines[0] and "--force" in lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.ssp"]


def test_force_runs_past_the_disk_estimate(tmp_path):
    info = RunInfo("s", tmp_path / "s.ssp", ("x",), 0.0, 1e9, 1e-3, 10**12, "causal",
                   "in-process")
    with pytest.raises(InputError, match="would take about"):
        CsvRecorder(tmp_path / "out.csv").started(info)
    recorder = CsvRecorder(tmp_path / "out.csv", force=True)
    recorder.started(info)  # forced: the file is open for the run's rows
    recorder.aborted()
    assert list(tmp_path.iterdir()) == []


# --- 6. a scene reaches only files inside itself ----------------------------------------
def test_an_fmu_source_outside_the_scene_is_refused(block_fmus, tmp_path):
    outside = tmp_path / "x.fmu"
    outside.write_bytes(block_fmus["state"].read_bytes())
    inner = block_scene(tmp_path / "a" / "b" / "scene", block_fmus["state"],
                        source="../../../x.fmu")
    archive = pack(inner, tmp_path / "a" / "b" / "up.ssp")
    absolute = block_scene(tmp_path / "abs", block_fmus["state"], source=str(outside))
    linked = block_scene(tmp_path / "linked", block_fmus["state"],
                         source="resources/link.fmu")
    (linked / "resources" / "link.fmu").symlink_to(outside)
    for scene, problem in ((archive, "FMU source '../../../x.fmu' is outside the scene"),
                           (inner, "FMU source '../../../x.fmu' is outside the scene"),
                           (absolute, f"FMU source '{outside}' is an absolute path"),
                           (linked, "FMU source 'resources/link.fmu' is outside the scene")):
        code, lines = dsim_cli("run", scene, "--out", tmp_path / "out.csv")
        assert code == 2 and len(lines) == 1, lines
        assert "Component 'b1'" in lines[0] and problem in lines[0]
    assert not (tmp_path / "out.csv").exists()


@pytest.mark.parametrize("chosen, problem", [
    ("../../../../etc/shadow", "file '../../../../etc/shadow' is outside the scene"),
    ("/etc/shadow", "file '/etc/shadow' is an absolute path"),
])
def test_a_parameter_set_outside_the_scene_is_refused(scene, tmp_path, chosen, problem):
    code, lines = dsim_cli("run", scene, "--parameter-set", chosen, "--out",
                           tmp_path / "out.csv")
    assert code == 2 and len(lines) == 1 and problem in lines[0]
    with pytest.raises(InputError) as caught:
        dsim.simulate(scene, parameter_set=chosen)
    assert len(caught.value.problems) == 1 and problem in caught.value.problems[0]


def test_a_parameter_file_outside_the_scene_is_refused(block_fmus, tmp_path):
    (tmp_path / "outside.ssv").write_text("<not read/>")
    folder = block_scene(tmp_path / "scene", block_fmus["state"])
    text = (folder / "SystemStructure.ssd").read_text().replace(
        "<ssd:Elements>", '<ssd:ParameterBindings><ssd:ParameterBinding '
        'source="../outside.ssv"/></ssd:ParameterBindings><ssd:Elements>', 1)
    (folder / "SystemStructure.ssd").write_text(text)
    code, lines = dsim_cli("validate", folder)
    assert code == 2 and len(lines) == 1 and "file '../outside.ssv' is outside the scene" \
        in lines[0]


# --- 7. one clear line (the command line) ---------------------------------------------
def test_a_member_name_that_is_not_utf8_is_one_line(scene, tmp_path):
    name = "resources/\u00e9\u00e9.txt"
    data = bomb(scene, tmp_path / "named.ssp", b"x", name).read_bytes()
    assert data.count(name.encode()) == 2  # local and central header, flagged UTF-8
    archive = tmp_path / "bad.ssp"
    archive.write_bytes(data.replace(name.encode(), b"resources/\xff\xfe\xfd\xfc.txt"))
    code, lines = dsim_cli("run", archive, "--out", tmp_path / "out.csv")
    assert code == 2 and lines == [f"dsim: error: {archive}: SSP archive has a member name "
                                   "that is not valid UTF-8"]


def test_sigterm_while_a_scene_is_read_is_one_line_and_leaves_no_folder(tmp_path):
    count = 50_000  # reading takes seconds: time to be interrupted
    folder = tmp_path / "many"
    folder.mkdir()
    (folder / "SystemStructure.ssd").write_text(
        ssd("many", [component(f"c{i}", "resources/none.fmu") for i in range(count)]))
    archive = pack(folder, tmp_path / "many.ssp")
    temp = tmp_path / "temp"
    temp.mkdir()
    process = subprocess.Popen(CLI + ["validate", str(archive)], cwd=ROOT, text=True,
                               stderr=subprocess.PIPE, env=dict(os.environ, TMPDIR=str(temp)))
    deadline = time.monotonic() + 60
    while not list(temp.glob("dsim-ssp-*/SystemStructure.ssd")):
        assert time.monotonic() < deadline and process.poll() is None
        time.sleep(0.01)
    process.send_signal(signal.SIGTERM)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 143
    assert err.strip().splitlines() == ["dsim: interrupted by SIGTERM"]
    assert list(temp.iterdir()) == []


def test_temporary_folders_of_killed_runs_are_removed_by_the_next_run(scene, tmp_path):
    temp = tmp_path / "temp"
    temp.mkdir()
    gone = subprocess.Popen(["true"])
    gone.wait()
    (temp / f"dsim-fmu-{gone.pid}-abc").mkdir()  # no lock file, its process is gone
    (temp / "dsim-point-99999999").mkdir()  # another command's folder: not ours to judge
    (temp / f"dsim-ssp-{os.getpid()}-def").mkdir()  # a lock file nobody holds
    (temp / f"dsim-ssp-{os.getpid()}-def" / ".dsim-lock").write_text("")
    holder = subprocess.Popen([sys.executable, "-c", (
        "import fcntl, os, sys, time; d = sys.argv[1]; os.mkdir(d); "
        "fd = os.open(d + '/.dsim-lock', os.O_CREAT | os.O_RDWR); fcntl.flock(fd, "
        "fcntl.LOCK_EX); print('held', flush=True); time.sleep(60)"),
        str(temp / "dsim-ssp-1-live")], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline() == "held\n"
        code, lines = dsim_cli("validate", scene, tmpdir=temp)
        assert code == 0, lines
        assert sorted(p.name for p in temp.iterdir()) == ["dsim-point-99999999",
                                                          "dsim-ssp-1-live"]  # alive: kept
    finally:
        holder.kill()
        holder.wait()
    assert sweep_dead_folders(temp) == [temp / "dsim-ssp-1-live"]


def test_an_address_answers_the_same_whatever_the_port_state(built, tmp_path):
    listening = socket.socket()  # something that is no Ray cluster
    listening.bind(("127.0.0.1", 0))
    listening.listen()
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        closed = probe.getsockname()[1]
    answers = []
    try:
        for port in (closed, listening.getsockname()[1]):
            started = time.monotonic()
            code, lines = dsim_cli("run", built["ssp"] / "spring_mass_linear.ssp",
                                   "--backend", "ray", "--address", f"127.0.0.1:{port}",
                                   "--out", tmp_path / "out.csv",
                                   env={"RAY_AUTH_MODE": "disabled"})
            assert code == 2 and len(lines) == 1 and time.monotonic() - started < 30
            answers.append(lines[0].replace(str(port), "PORT"))
    finally:
        listening.close()
    assert answers[0] == answers[1] == (
        "dsim: error: setting address '127.0.0.1:PORT': no Ray cluster answers there; "
        "start one with `ray start --head` and give the address it prints"
        + AUTHENTICATION)
