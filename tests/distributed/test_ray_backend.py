"""The Ray backends on a real local Ray instance (one per test session, 2 CPUs):
every shipped scene gives the in-process numbers to the last bit; a worker whose
FMU kills its process ends the run with one line naming the component and the time,
the converged steps kept; bad input is one line and exit 2."""
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import dsim
from dsim.master.recording.results import read_csv
from dsim.master.running.execution import Execution
from dsim.master.tools.cli import main
from tests.support.scene_files import component, scene_folder, ssd
from tests.support.distributed import AUTHENTICATION, free_port
from tests.support.paths import DSIM, ROOT
from tests.support.runs import run_cli, same_run, workers
from tests.support.scenes import block_scene, oscillator_scene, placed_scene
from tests.support.third_party.build import OSCILLATOR_VARIABLES, c_fmu

#: every scene dsim ships (ssp/NAME is packed into build/ssp/NAME.ssp)
SHIPPED = sorted(p.name for p in (ROOT / "ssp").iterdir() if p.is_dir())
#: macro steps compared per scene: 20 (each with its Newton iterations, state saves and
#: restores), 60 for the singular four bars (past their first singular point, t = 0.375
#: s), 4 for chain_1000 (it instantiates a thousand FMUs)
STEPS = {"chain_1000": 4, **{f"four_bar_singular_{joint}": 60
                             for joint in ("fixed", "flexible", "penalized")}}


def test_every_shipped_scene_is_packed(built):
    assert SHIPPED and sorted(p.stem for p in built["ssp"].glob("*.ssp")) == SHIPPED


@pytest.mark.parametrize("name", SHIPPED)
def test_the_ray_backend_gives_the_in_process_numbers_to_the_last_bit(built, ray_local, name):
    scene = built["ssp"] / f"{name}.ssp"
    found = dsim.prepare(scene).scene
    stop = found.start_time + STEPS.get(name, 20) * found.master.step
    here = dsim.simulate(scene, stop=stop)
    there = dsim.simulate(scene, stop=stop, backend="ray")
    assert here.steps > 0 and there.statistics["backend"] == "ray"
    same_run(here, there)
    # one worker per FMU, at most one per CPU of the instance (2), none of them this one
    assert len(workers(there)) == min(len(found.components), 2)
    assert os.getpid() not in workers(there)


@pytest.mark.parametrize("backend", ["ray", "isolated"])
def test_error_controlled_steps_on_workers_give_the_in_process_numbers(built, ray_local,
                                                                       backend):
    """step auto on the workers: the snapshots kept there under the driver's keys, the
    same steps taken, taken again and accepted, to the last bit."""
    scene = built["ssp"] / "four_bar_singular_flexible.ssp"
    settings = dict(stop=0.03, step="auto", error_tolerance=1e-5)
    here = dsim.simulate(scene, **settings)
    there = dsim.simulate(scene, backend=backend, **settings)
    assert here.ok and there.ok, there.statistics["message"]
    same_run(here, there)
    assert there.statistics["step_control"] == here.statistics["step_control"]
    assert here.statistics["step_control"]["rejected_steps"] > 0  # steps taken again too


@pytest.fixture(scope="module")
def crashing(tmp_path_factory):
    """The C oscillator built to end its process abruptly at t = 0.4975 s."""
    return c_fmu(tmp_path_factory.mktemp("crash"), "oscillator", "oscillator.c",
                 OSCILLATOR_VARIABLES, defines=("CRASH_TIME=0.4975",))


def test_the_isolated_backend_runs_each_fmu_in_its_own_process(built, ray_local):
    scene = built["ssp"] / "frame_split.ssp"
    here = dsim.simulate(scene, stop=0.02)
    there = dsim.simulate(scene, stop=0.02, backend="isolated")
    same_run(here, there)
    assert len(workers(there)) == len(there.statistics["components"]) == 5


def test_a_glued_third_party_c_fmu_runs_in_a_worker_too(built, ray_local, tmp_path):
    fmu = c_fmu(tmp_path / "c", "oscillator", "oscillator.c", OSCILLATOR_VARIABLES)
    folder = oscillator_scene(tmp_path / "scene", built, fmu)
    same_run(dsim.simulate(folder, stop=0.5), dsim.simulate(folder, stop=0.5, backend="ray"))


def test_the_workers_end_with_the_run_and_the_session_instance_stays(built, ray_local):
    result = dsim.simulate(built["ssp"] / "spring_mass_linear.ssp", stop=0.1, backend="ray")
    assert result.ok and ray_local.is_initialized()  # joined, not owned: not shut down

    def alive(pid):
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        return True

    deadline = time.monotonic() + 30
    while any(alive(pid) for pid in workers(result)) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not any(alive(pid) for pid in workers(result))


def test_a_run_with_no_address_starts_a_local_instance_and_shuts_it_down(built):
    script = ("import dsim, ray\n"
              f"result = dsim.simulate({str(built['ssp'] / 'spring_mass_linear.ssp')!r}, "
              "stop=0.2, backend='ray')\n"
              "print(result.status, result.steps, ray.is_initialized())\n")
    process = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True,
                             text=True, timeout=300)
    assert process.returncode == 0, process.stderr
    assert process.stdout.split() == ["completed", "20", "False"]


def test_ctrl_c_ends_a_ray_run_after_its_step_with_everything_written(built, tmp_path):
    """SIGINT to the whole process group, as a terminal's Ctrl-C sends it: the workers
    live on, the run ends after its current step as interrupted (exit 130)."""
    target = tmp_path / "run.csv"
    process = subprocess.Popen(DSIM + ["run", str(built["ssp"] / "spring_mass_linear.ssp"),
                                       "--stop", "1000", "--backend", "ray", "--out",
                                       str(target), "--quiet"],
                               cwd=ROOT, stderr=subprocess.PIPE, text=True,
                               start_new_session=True)
    partial = tmp_path / ".run.csv.partial"
    try:
        deadline = time.monotonic() + 120
        while not (partial.exists() and partial.stat().st_size > 2000):
            assert time.monotonic() < deadline and process.poll() is None
            time.sleep(0.05)
        os.killpg(process.pid, signal.SIGINT)
        _, err = process.communicate(timeout=120)
    finally:
        process.kill()
    assert process.returncode == 130, err
    lines = err.strip().splitlines()
    assert lines[0].startswith("dsim: interrupted: interrupted by SIGINT (stopped at t = ")
    header, data = read_csv(target)
    stats = json.loads(target.with_suffix(".stats.json").read_text())
    assert stats["status"] == "interrupted" and stats["steps"] == data.shape[0] - 1 > 5


# --- a worker that dies ------------------------------------------------------------
#: the words for an FMU that aborts its process, and for one that _exit()s it (as a
#: kill would end it; the C FMUs cannot serialize their state: not started again)
CRASHED = r"the FMU crashed its worker process \(pid \d+\): Fatal Python error: Aborted"
WORKER_ENDED = (r"the worker process \(pid \d+\) on node \S+ ended without a crash report "
                r"\(killed, or its FMU ended the process\); not started again: component "
                r"'(\w+)': its FMU cannot serialize its state \(canSerializeFMUstate is false\)")
#: said before such a run starts
UP_FRONT = ("dsim: warning: a lost worker ends the run: component '{}': its FMU cannot "
            "serialize its state (canSerializeFMUstate is false)")


def without_ray_log(lines: list[str]) -> list[str]:
    """``lines`` without the last one when it names the file of what Ray's processes
    said (a worker's death notice reaches the driver when it does), which then holds it."""
    from dsim.master.running.backends.ray.cluster import ray_log

    said = re.fullmatch(r"dsim: what Ray's own processes said meanwhile is in (\S+)",
                        lines[-1] if lines else "")
    if said:
        log = Path(said.group(1))
        assert log.parent == ray_log().parent and re.fullmatch(r"ray-\d+\.log", log.name)
        assert log.read_text().strip()
        return lines[:-1]
    return lines


def test_a_crashing_fmu_ends_an_isolated_run_with_one_line_and_the_converged_steps(
        block_fmus, ray_local, tmp_path, capsys):
    """The block aborts its process in the step to t = 0.051 s (failure mode 4)."""
    folder = block_scene(tmp_path / "scene", block_fmus["state"], failure=4, fail_time=0.0505)
    target = tmp_path / "run.csv"
    code, lines = run_cli(capsys, folder, "--isolate", "--out", target)
    lines = without_ray_log(lines)
    assert code == 1 and lines.pop(0) == UP_FRONT.format("b1")
    assert re.fullmatch(r"dsim: simulation failed: step 51 \(t = 0\.051 s\): component 'b1': "
                        + CRASHED, lines[0])
    assert lines[1:] == [f"dsim: the 50 converged steps are in {target}, statistics in "
                         f"{target.with_suffix('.stats.json')}"]
    header, data = read_csv(target)
    assert data.shape[0] == 51 and np.allclose(np.diff(data[:, 0]), 1e-3)
    assert dsim.read_columns(target)["b1.y"][-1] != 0.0


def test_the_same_crash_takes_dsim_down_in_process_and_is_two_lines_isolated(block_fmus,
                                                                           tmp_path):
    folder = block_scene(tmp_path / "scene", block_fmus["state"], failure=4, fail_time=0.0505)
    command = DSIM + ["run", str(folder), "--out", str(tmp_path / "run.csv")]
    process = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=120)
    # the crash takes down the process that steps; dsim run's supervisor says so and
    # finishes its files (master/tools/supervisor.py)
    assert process.returncode == 1, process.stderr
    assert "ended without finishing it (killed by SIGABRT)" in process.stderr.splitlines()[-1]
    process = subprocess.run(command + ["--isolate"], cwd=ROOT, capture_output=True,
                             text=True, timeout=300)
    assert process.returncode == 1 and process.stdout == ""  # Ray's own notice is not shown
    lines = without_ray_log(process.stderr.strip().splitlines())
    assert len(lines) == 3 and lines[0] == UP_FRONT.format("b1")
    assert re.search(CRASHED, lines[1])


def test_a_glued_fmu_that_kills_its_worker_mid_newton_names_itself_and_the_time(
        built, ray_local, crashing, tmp_path, capsys):
    folder = oscillator_scene(tmp_path / "scene", built, crashing)
    target = tmp_path / "run.csv"
    code, lines = run_cli(capsys, folder, "--backend", "ray", "--out", target)
    assert code == 1 and lines.pop(0) == UP_FRONT.format("third")
    assert re.fullmatch(r"dsim: simulation failed: step 100 \(t = 0\.5 s\): component "
                        "'third': " + WORKER_ENDED, lines[0])
    header, data = read_csv(target)
    assert data.shape[0] == 100 and abs(data[-1, 0] - 0.495) < 1e-12
    columns = dsim.read_columns(target)
    assert np.all(np.isfinite(columns["third.s"])) and np.any(columns["j.f_x"] != 0.0)


def test_an_fmu_that_refuses_its_parameters_is_the_same_line_on_the_ray_backend(
        built, ray_local, tmp_path, capsys):
    import zipfile

    folder = tmp_path / "scene"
    with zipfile.ZipFile(built["ssp"] / "frame_split.ssp") as archive:
        archive.extractall(folder)
    ssv = folder / "resources" / "rail_left.ssv"
    ssv.write_text(ssv.read_text().replace('resources/meshes/frame_rail_left_0.025.vtk',
                                           'resources/cross_mid.ssv'))  # not a mesh
    said = {}
    for backend in ("in-process", "ray"):
        code, said[backend] = run_cli(capsys, folder, "--backend", backend, "--out",
                                      tmp_path / "r.csv")
        assert code == 2 and len(said[backend]) == 1
    assert said["ray"] == said["in-process"]
    assert "Component 'rail_left'" in said["ray"][0] and "cross_mid.ssv" in said["ray"][0]
    assert "cannot be read as a mesh" in said["ray"][0]


def test_a_scene_file_reaches_a_worker_that_cannot_see_the_drivers_path(ray_local, tmp_path):
    """A mesh file of the scene goes through Ray's object store as the FMUs do: a
    worker on a node without the driver's file lands a copy of the same name."""
    from dsim.master.running.backends.ray.cluster import Shipment, landed

    mesh = tmp_path / "plate.vtk"
    mesh.write_bytes(b"a mesh")
    shipped = Shipment(ray_local).add(mesh)
    assert landed(shipped) == mesh  # the same content at the same path: used as it is
    mesh.write_bytes(b"another mesh")  # as on another node, or changed since
    copy = landed(shipped)
    assert copy != mesh and copy.name == "plate.vtk" and copy.read_bytes() == b"a mesh"


def test_a_hung_fmu_is_stopped_after_the_call_timeout_with_the_converged_steps(
        built, ray_local, tmp_path, capsys):
    """The oscillator never returns from its step to t = 0.25 s: with --call-timeout the
    worker is stopped, the run fails naming the component and time, the rows stay."""
    fmu = c_fmu(tmp_path / "c", "oscillator", "oscillator.c", OSCILLATOR_VARIABLES,
                defines=("HANG_TIME=0.2475",))
    folder = oscillator_scene(tmp_path / "scene", built, fmu)
    target = tmp_path / "run.csv"
    started = time.monotonic()
    code, lines = run_cli(capsys, folder, "--isolate", "--call-timeout", "2", "--out", target)
    assert code == 1 and time.monotonic() - started < 60
    assert lines.pop(0) == UP_FRONT.format("third")
    assert re.fullmatch(r"dsim: simulation failed: step 50 \(t = 0\.25 s\): component "
                        r"'third': no answer from the worker in 2 s \(--call-timeout\): the "
                        "FMU hangs or is too slow; the worker was stopped", lines[0]), lines
    header, data = read_csv(target)
    assert data.shape[0] == 50 and abs(data[-1, 0] - 0.245) < 1e-12


def test_a_call_timeout_needs_a_backend_that_can_stop_an_fmu(built, capsys):
    code, lines = run_cli(capsys, built["ssp"] / "spring_mass_linear.ssp", "--call-timeout",
                          "5")
    assert code == 2 and lines == ["dsim: error: setting call_timeout: only the ray and "
                                   "isolated backends take it (--backend ray, --isolate): an "
                                   "FMU in dsim's own process cannot be stopped"]
    code, lines = run_cli(capsys, built["ssp"] / "spring_mass_linear.ssp", "--isolate",
                          "--call-timeout", "-1")
    assert code == 2 and "call_timeout must be a finite number greater than 0" in lines[0]


def test_a_worker_that_dies_while_its_fmu_is_instantiated_is_bad_input(
        built, ray_local, tmp_path, capsys):
    fmu = c_fmu(tmp_path / "c", "oscillator", "oscillator.c", OSCILLATOR_VARIABLES,
                defines=("CRASH_TIME=-1",))
    folder = oscillator_scene(tmp_path / "scene", built, fmu)
    code, lines = run_cli(capsys, folder, "--isolate", "--out", tmp_path / "run.csv")
    assert code == 2
    assert lines == ["dsim: error: component 'third': the worker process died while the FMU "
                     "was instantiated (it crashed or was killed)"]
    assert not (tmp_path / "run.csv").exists()


def test_a_dead_worker_that_held_several_components_names_them_all(block_fmus, ray_local,
                                                                   tmp_path, capsys):
    """Three blocks on two CPUs: b1 and b3 share the first worker (dealt round-robin);
    b3 aborts it."""
    blocks = [component(f"b{i}", "resources/block.fmu", {"failure": 4, "fail_time": 0.0105}
                        if i == 3 else {}, outputs=["y"]) for i in (1, 2, 3)]
    folder = scene_folder(tmp_path / "scene", ssd("blocks", blocks, stop=0.1,
                                                  master='step="0.001"'),
                          {"block.fmu": block_fmus["state"]})
    code, lines = run_cli(capsys, folder, "--backend", "ray", "--out", tmp_path / "run.csv")
    assert code == 1 and lines[:2] == [UP_FRONT.format("b1"), UP_FRONT.format("b2")]
    assert re.fullmatch(r"dsim: simulation failed: step 11 \(t = 0\.011 s\): components "
                        r"'b1', 'b3' \(one worker process\): " + CRASHED, lines[2])
    assert read_csv(tmp_path / "run.csv")[1].shape[0] == 11


# --- a lost worker: started again, or the run ends saying so ---------------------------
def run_killing(plan, at: int, delay: float):
    """``plan`` run to its end while the first worker is killed (SIGKILL) ``delay`` s
    after step ``at`` (within the next step, or between two); the result and the
    killed worker's pid and components."""
    execution = Execution(plan)
    execution.start()
    victim = execution.backend.places()[0]["pid"]
    names = [n for n, p in zip(execution.backend.names, execution.backend.places())
             if p["pid"] == victim]
    while execution.step():
        if execution.index == at:
            threading.Timer(delay, os.kill, (victim, signal.SIGKILL)).start()
    return execution.finish(), victim, names


def test_a_killed_worker_is_started_again_and_the_run_gives_the_undisturbed_numbers(
        built, ray_local):
    """frame_split: five elastic bodies on two workers; the one holding three of them
    is killed mid-run.  A fresh worker goes on from their states at the last converged
    step: every column equals the undisturbed run's to the last bit."""
    scene = built["ssp"] / "frame_split.ssp"
    here = dsim.simulate(scene, stop=0.005, backend="ray")
    there, victim, names = run_killing(dsim.prepare(scene, stop=0.005, backend="ray"),
                                       at=10, delay=0.02)
    assert there.status == "completed" and there.steps == here.steps == 50
    assert list(there.signals) == list(here.signals)
    for column, values in here.signals.items():
        assert np.array_equal(there[column], values), column
    [loss] = there.statistics["lost_workers"]
    assert loss["what"] == "killed worker" and loss["pid"] == victim and loss["recovered"]
    assert loss["components"] == names and len(names) >= 2
    assert 0.001 <= loss["time"] <= 0.005 and 0 < loss["recovery_seconds"] < 60
    assert loss["message"].startswith(f"the worker process (pid {victim}) on node ")
    assert loss["message"].endswith(" was killed (no crash report from its FMU)")
    assert {there.statistics["components"][n]["worker"]["pid"] for n in names} == \
        {loss["new_worker"]["pid"]} != {victim}


def test_a_worker_holding_a_subsystem_in_no_joint_is_started_again_to_the_same_bits(
        built, ray_local, tmp_path):
    """chain_4 and a fifth SpringMass in no joint, on the first worker with two of the
    chain: that one is never saved, so the driver's journal of the worker is boiled
    down every few batches (ray_recovery.LOG_BATCHES) instead of cleared each step;
    killed after 20 steps, a fresh worker takes the calls since and the run gives the
    undisturbed numbers to the last bit."""
    import shutil

    from dsim.build_fmus.scenes import CHAIN, chain

    scene = chain(4)
    scene.component("free", "SpringMass", {"n": 1, "m[1]": 2.0, "k_ground[1]": 50.0,
                                           "Fa[1]": 1.0, "omega[1]": 30.0, "P.mass": 1,
                                           "Q.mass": 1}, outputs=["x[1]"], inline=True)
    folder = tmp_path / "scene"
    scene.write(folder, 0.0, 0.03, step=CHAIN["step"], tolerance=1e-13, maxIterations=20,
                predictor="linear", refreshAfter=10)
    (folder / "resources").mkdir(exist_ok=True)
    shutil.copy(built["fmus"] / "SpringMass.fmu", folder / "resources" / "SpringMass.fmu")
    here = dsim.simulate(folder)
    there, victim, names = run_killing(dsim.prepare(folder, backend="ray"), at=20,
                                       delay=0.005)
    assert "free" in names and there.status == "completed" and there.steps == 30
    assert list(there.signals) == list(here.signals)
    for column, values in here.signals.items():
        assert np.array_equal(there[column], values), column
    [loss] = there.statistics["lost_workers"]
    assert loss["recovered"] and loss["pid"] == victim


def test_a_worker_killed_under_step_auto_is_started_again_to_the_same_bits(built, ray_local):
    """four_bar_singular_flexible under step auto (steps taken again too), its first
    worker killed mid-run: the worker's checkpoints are the error control's snapshots
    (none is taken while one lives), so a fresh worker goes on from the last one, keeps
    it under the same key and takes the calls since; every column equals the
    undisturbed run's to the last bit (in-process: a Ray run gives its bits, as
    test_error_controlled_steps_on_workers_give_the_in_process_numbers checks), and so do
    the controller's steps."""
    scene = built["ssp"] / "four_bar_singular_flexible.ssp"
    settings = dict(stop=0.1, step="auto", error_tolerance=1e-5, backend="ray")
    here = dsim.simulate(scene, **{**settings, "backend": "in-process"})
    there, victim, names = run_killing(dsim.prepare(scene, **settings), at=4, delay=0.05)
    assert there.status == "completed", there.message
    assert there.steps == here.steps == 10
    for column, values in here.signals.items():
        assert np.array_equal(there[column], values), column
    assert there.statistics["step_control"] == here.statistics["step_control"]
    [loss] = there.statistics["lost_workers"]
    assert loss["recovered"] and loss["pid"] == victim and loss["components"] == names
    assert not any("a lost worker ends the run" in w for w in there.warnings)


def test_with_no_restarts_a_killed_worker_ends_the_run_saying_so(built, ray_local):
    scene = built["ssp"] / "spring_mass_linear.ssp"
    result, victim, names = run_killing(
        dsim.prepare(scene, stop=0.5, backend="ray", restarts=0), at=20, delay=0.0)
    assert result.status == "failed" and 20 <= result.steps < 50
    assert re.fullmatch(rf"step \d+ \(t = [\d.]+ s\): component '{names[0]}': the worker "
                        rf"process \(pid {victim}\) on node \S+ ended without a crash report "
                        r"\(killed, or its FMU ended the process\); not started again: a run "
                        r"starts 0 lost workers again at most \(--restarts\)", result.message)
    assert [loss["recovered"] for loss in result.statistics["lost_workers"]] == [False]


def test_a_frozen_worker_is_named_with_how_long_it_has_not_answered(built, ray_local):
    """SIGSTOP (a hung node, a worker cut off): what the progress line shows names the
    worker's components and the seconds waited; SIGCONT and the step goes on."""
    from dsim.master.running.backends.ray.recovery import LATE_SECONDS

    execution = Execution(dsim.prepare(built["ssp"] / "spring_mass_linear.ssp", stop=0.5,
                                       backend="ray"))
    execution.start()
    backend = execution.backend
    place = backend.places()[0]
    assert backend.waiting() is None
    os.kill(place["pid"], signal.SIGSTOP)
    try:
        stepping = threading.Thread(target=execution.step)
        stepping.start()
        time.sleep(LATE_SECONDS + 1.5)
        said = backend.waiting()
    finally:
        os.kill(place["pid"], signal.SIGCONT)
    stepping.join(timeout=60)
    assert not stepping.is_alive() and execution.index == 1
    assert re.fullmatch(rf"component '{backend.names[0]}': no answer for (\d+) s", said)
    assert int(said.split()[-2]) >= LATE_SECONDS
    assert backend.waiting() is None and execution.finish().status == "interrupted"


# --- placement ----------------------------------------------------------------------
def test_a_placement_on_a_resource_no_node_has_is_bad_input(built, ray_local, tmp_path,
                                                            capsys):
    folder = placed_scene(built, tmp_path / "scene",
                          '<glue:Placement component="right" resource="gpu_node"/>')
    code, lines = run_cli(capsys, folder, "--backend", "ray", "--out", tmp_path / "r.csv")
    assert code == 2 and len(lines) == 1
    assert lines[0].startswith("dsim: error: component 'right' is placed on Ray resource "
                               "'gpu_node', which no node of the cluster has (it has: ")
    assert not (tmp_path / "r.csv").exists()


def test_a_node_resource_places_a_component_and_in_process_runs_ignore_placement(
        built, ray_local, tmp_path, capsys):
    node = next(r for r in ray_local.cluster_resources() if r.startswith("node:")
                and not r.startswith("node:__"))
    folder = placed_scene(built, tmp_path / "scene",
                          f'<glue:Placement component="right" resource="{node}"/>')
    plan = dsim.prepare(folder)
    assert [s.placement for s in plan.specs] == ["", node]
    assert main(["info", str(folder)]) == 0
    assert f"placed on Ray resource {node} (--backend ray)" in capsys.readouterr().out
    same_run(dsim.simulate(folder, stop=0.1), dsim.simulate(folder, stop=0.1, backend="ray"))


@pytest.mark.parametrize("placements, problem", [
    ('<glue:Placement component="nobody" resource="x"/>', "unknown component 'nobody'"),
    ('<glue:Placement component="right"/>', "attribute 'resource' missing"),
    ('<glue:Placement component="right" resource="a"/>'
     '<glue:Placement component="right" resource="b"/>', "component 'right' is placed twice"),
])
def test_a_bad_placement_is_bad_input_naming_the_element(built, tmp_path, placements, problem):
    with pytest.raises(dsim.InputError) as caught:
        dsim.prepare(placed_scene(built, tmp_path / "scene", placements))
    assert len(caught.value.problems) == 1
    assert "Placement" in caught.value.problems[0] and problem in caught.value.problems[0]


# --- bad input: one line, exit 2, no traceback ----------------------------------------
@pytest.mark.parametrize("arguments, expected", [
    (["--backend", "ray", "--address", "127.0.0.1:{port}"],
     "dsim: error: setting address '127.0.0.1:{port}': no Ray cluster answers there; "
     "start one with `ray start --head` and give the address it prints" + AUTHENTICATION),
    (["--backend", "ray", "--address", "head-node"],
     "dsim: error: setting address 'head-node' is not HOST:PORT, ray://HOST:PORT or auto (the "
     "address that `ray start --head` prints)"),
    (["--address", "127.0.0.1:6379"],
     "dsim: error: setting address: only the ray backend takes it (--backend ray)"),
    (["--isolate", "--backend", "ray"],
     "dsim: error: --isolate runs every FMU in its own local worker process (the isolated "
     "backend): it cannot be combined with --backend ray"),
    (["--backend", "isolated", "--address", "auto"],
     "dsim: error: setting address: the isolated backend runs on this machine; use --backend "
     "ray to run on a cluster"),
])
def test_a_bad_address_or_backend_option_is_one_line(built, tmp_path, arguments, expected):
    port = free_port()
    arguments = [a.format(port=port) for a in arguments]
    started = time.monotonic()
    process = subprocess.run(DSIM + ["run", str(built["ssp"] / "spring_mass_linear.ssp"),
                                     "--out", str(tmp_path / "r.csv"), *arguments],
                             cwd=ROOT, capture_output=True, text=True, timeout=120,
                             env={**os.environ, "RAY_AUTH_MODE": "disabled"})
    assert process.returncode == 2 and process.stdout == ""
    assert process.stderr.strip().splitlines() == [expected.format(port=port)]
    assert time.monotonic() - started < 60 and not (tmp_path / "r.csv").exists()


def test_a_process_set_for_token_authentication_is_not_told_of_it(built, tmp_path):
    port = free_port()
    process = subprocess.run(DSIM + ["run", str(built["ssp"] / "spring_mass_linear.ssp"),
                                     "--out", str(tmp_path / "r.csv"), "--backend", "ray",
                                     "--address", f"127.0.0.1:{port}"],
                             cwd=ROOT, capture_output=True, text=True, timeout=120,
                             env={**os.environ, "RAY_AUTH_MODE": "token"})
    assert process.returncode == 2
    assert process.stderr.strip().splitlines() == [
        f"dsim: error: setting address '127.0.0.1:{port}': no Ray cluster answers there; "
        "start one with `ray start --head` and give the address it prints"]


@pytest.mark.parametrize("arguments", [["--backend", "ray"], ["--isolate"]])
def test_the_ray_backends_without_ray_installed_are_one_line(built, tmp_path, arguments):
    script = ("import sys\nsys.modules['ray'] = None  # as if it were not installed\n"
              "from dsim.master.tools.cli import main\nsys.exit(main(sys.argv[1:]))\n")
    process = subprocess.run([sys.executable, "-c", script, "run",
                              str(built["ssp"] / "spring_mass_linear.ssp"), *arguments,
                              "--out", str(tmp_path / "r.csv")],
                             cwd=ROOT, capture_output=True, text=True, timeout=120)
    backend = "isolated" if arguments == ["--isolate"] else "ray"
    assert process.returncode == 2
    assert process.stderr.strip().splitlines() == [
        f"dsim: error: backend '{backend}' needs the ray package: pip install 'dsim[ray]'"]


def test_a_step_an_fmu_discards_on_its_worker_is_cut_as_in_process(built, ray_local, tmp_path):
    """The fmi2Discard of a C FMU on a Ray worker comes back as the step failure it is
    in-process: the master cuts the step, and the run equals the in-process one."""
    fmu = c_fmu(tmp_path / "fmu", "oscillator", "oscillator.c", OSCILLATOR_VARIABLES)
    folder = oscillator_scene(tmp_path / "scene", built, fmu)
    ssd = folder / "SystemStructure.ssd"
    ssd.write_text(ssd.read_text().replace(
        '<ssv:Parameter name="s0"><ssv:Real value="0.01"/></ssv:Parameter>',
        '<ssv:Parameter name="s0"><ssv:Real value="0.01"/></ssv:Parameter>'
        '<ssv:Parameter name="h_max"><ssv:Real value="0.0025"/></ssv:Parameter>'))
    here = dsim.simulate(folder, stop=0.1)
    there = dsim.simulate(folder, stop=0.1, backend="ray")
    assert there.status == here.status == "completed"
    assert there.statistics["step_cuts"] == here.statistics["step_cuts"] == 20
    assert np.array_equal(there["third.s"], here["third.s"])
