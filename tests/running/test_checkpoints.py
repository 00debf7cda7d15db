"""Checkpoints (docs/checkpoints.md): a run resumed from any of its checkpoints writes
the CSV of a run never stopped, byte for byte, and statistics that differ only in
the seconds measured; on every coupling that keeps state (iterative, explicit,
strong, the error-controlled step), on FE bodies, Model Exchange and FMI 3.0 FMUs, a
scenario's state; a run killed with SIGKILL at a random point and resumed; a new run
from a checkpoint (--from) with a tunable parameter changed."""
import json
import shutil
import signal
import subprocess
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

import dsim
from dsim.master.errors import InputError
from tests.support.paths import DSIM
from tests.support.checkpoints import (checkpoints_of, killed_and_resumed,
                                       sweep_from_checkpoint, timeless)
from tests.support.scenes import archive_scene

needs_gcc = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")


def resumed_from_each(scene, folder: Path, every: float, **settings) -> int:
    """Run ``scene`` with checkpoints, then resume from every checkpoint:
    each resumed run's CSV must be the uninterrupted run's bytes, its statistics the
    same but for seconds.  The checkpoints resumed from."""
    out = folder / "run.csv"
    full = dsim.simulate(scene, out=out, checkpoint_every=every, checkpoint_keep=100,
                         handle_signals=False, **settings)
    assert full.status == "completed", full.message
    reference, statistics = out.read_bytes(), timeless(json.loads(
        out.with_name("run.stats.json").read_text()))
    taken = sorted((folder / "run.checkpoints").iterdir())
    assert len(taken) >= 2, taken
    for checkpoint in taken:
        again = dsim.simulate(resume=checkpoint, handle_signals=False)
        assert again.status == "completed", again.message
        assert out.read_bytes() == reference, checkpoint.name
        assert timeless(again.statistics) == statistics, checkpoint.name
        assert again.statistics["resumed"]["step"] == int(checkpoint.name[5:])
    return len(taken)


@pytest.mark.parametrize("settings", [
    ("nonlinear", {}), ("nonlinear", {"step": "auto", "error_tolerance": 1e-5}),
    ("linear", {"coupling": "explicit"}),
    ("nonlinear", {"predictor": "quadratic", "refresh": "step"})],
    ids=["iterative", "step-auto", "explicit", "refresh-every-step"])
def test_a_resumed_glued_run_writes_the_bytes_of_one_never_stopped(built, tmp_path,
                                                                   settings):
    kind, settings = settings
    assert resumed_from_each(built["ssp"] / f"spring_mass_{kind}.ssp", tmp_path, 0.5,
                             stop=2.0, **settings) >= 3


def test_a_resumed_fe_frame_writes_the_bytes_of_one_never_stopped(built, tmp_path):
    """frame_split: two FE bodies glued at a node set, a measured flexibility and a
    factored gluing matrix that the resumed run makes again to the same bits."""
    assert resumed_from_each(built["ssp"] / "frame_split.ssp", tmp_path, 0.01,
                             stop=0.03) >= 2


@pytest.fixture(scope="module")
def kinds(tmp_path_factory):
    from tests.support.third_party.kinds.build import build_fmu

    folder = tmp_path_factory.mktemp("kinds")
    made = {}

    def fmu(model, version="2.0", interfaces=("ModelExchange", "CoSimulation")):
        key = (model, version, tuple(interfaces))
        if key not in made:
            made[key] = build_fmu(folder / f"{len(made)}", model, version,
                                  interfaces=interfaces)
        return made[key]
    return fmu


POSITION = ('<ssd:Connectors><ssd:Connector name="P.u_x" kind="output"><ssc:Real/>'
            "</ssd:Connector></ssd:Connectors>")


@needs_gcc
@pytest.mark.parametrize("version, interface", [("2.0", "ModelExchange"),
                                                ("3.0", "ModelExchange"),
                                                ("3.0", "CoSimulation")])
def test_a_resumed_glued_pair_of_c_fmus_writes_the_same_bytes(kinds, tmp_path, version,
                                                              interface):
    """Two C oscillators glued by a fixed joint, integrated by dsim (Model Exchange: the
    FMU state and the integration's own) or stepped by themselves (FMI 3.0)."""
    fmu = kinds("oscillator", version)
    path = archive_scene(tmp_path / "pair.ssp",
                         {"a": (fmu, interface, POSITION), "b": (fmu, interface, "")},
                         gluing='<glue:Joint name="j" a="a.P" b="b.P" dofs="x" kind="fixed"/>',
                         master='tolerance="1e-10"', step=0.01, stop=0.4)
    assert resumed_from_each(path, tmp_path, 0.1) >= 3


@needs_gcc
def test_a_resumed_bouncing_ball_keeps_its_events(kinds, tmp_path):
    """Model Exchange with state events between checkpoints (the ball bounces at
    t = 0.45 s and 1.35 s from 1 m)."""
    path = archive_scene(tmp_path / "ball.ssp", {"b": (kinds("bouncing_ball"),
                                                      "ModelExchange", "")},
                         step=0.01, stop=1.6)
    assert resumed_from_each(path, tmp_path, 0.4) >= 3


@needs_gcc
def test_a_resumed_strong_coupling_writes_the_same_bytes(kinds, tmp_path):
    """Connections iterated by the strong coupling: its Jacobians kept by step size."""
    mass1, mass2 = kinds("mass1"), kinds("mass2")
    path = archive_scene(tmp_path / "two.ssp",
                         {"mass1": (mass1, "ModelExchange", ""),
                          "mass2": (mass2, "ModelExchange", "")},
                         [("mass1", "x1", "mass2", "x1"), ("mass1", "v1", "mass2", "v1"),
                          ("mass2", "F", "mass1", "F")], stop=0.5, step=0.01,
                         master='coupling="strong"')
    assert resumed_from_each(path, tmp_path, 0.1) >= 3


def test_a_resumed_scenario_keeps_what_it_modified(built, tmp_path):
    """A force overridden on a glued port from 0.6 s, biased from 1.1 s, taken back at
    the scenario's end (1.6 s): resumed from every 0.5 s, before, inside and after its
    modifications."""
    scenario = tmp_path / "force.json"
    scenario.write_text(json.dumps({"defaults": {"model": "right", "variable": "P.f_x"},
                                    "events": [
                                        {"time": 0.6, "action": "override", "value": 5.0},
                                        {"time": 1.1, "action": "bias", "value": -2.0}],
                                    "end": 1.6}))
    assert resumed_from_each(built["ssp"] / "spring_mass_nonlinear.ssp", tmp_path, 0.5,
                             stop=2.0, scenario=str(scenario)) >= 3


def _dsim(*args, **kw):
    return subprocess.run([*DSIM, *map(str, args)], capture_output=True, text=True,
                          timeout=300, **kw)


@pytest.mark.parametrize("scene", ["spring_mass_nonlinear", "frame_split"])
def test_a_run_killed_with_sigkill_at_a_random_point_resumes_to_the_same_bytes(
        built, tmp_path, scene):
    """``dsim run --checkpoint-every``, killed with SIGKILL once a checkpoint is on the
    disk (at a random moment after), then ``dsim run --resume``: the CSV and the
    statistics (but for seconds) of the same run never stopped."""
    stop, every = {"spring_mass_nonlinear": (20.0, 2.0), "frame_split": (0.1, 0.01)}[scene]
    (reference, expected), (out, statistics) = killed_and_resumed(
        built["ssp"] / f"{scene}.ssp", tmp_path, stop, every)
    assert out == reference
    assert timeless(statistics) == timeless(expected)
    assert statistics["resumed"]["time"] < stop


@needs_gcc
@pytest.mark.parametrize("stepping", [False, True], ids=["dsim-killed", "child-killed"])
def test_a_model_exchange_run_killed_with_sigkill_resumes_to_the_same_bytes(
        kinds, tmp_path, stepping):
    """Two C oscillators glued as Model Exchange FMUs, integrated by dsim: dsim killed
    and resumed, or its stepping process killed and started again by the supervisor."""
    fmu = kinds("oscillator", "2.0")
    path = archive_scene(tmp_path / "pair.ssp",
                         {"a": (fmu, "ModelExchange", POSITION), "b": (fmu, "ModelExchange", "")},
                         gluing='<glue:Joint name="j" a="a.P" b="b.P" dofs="x" kind="fixed"/>',
                         master='tolerance="1e-10"', step=0.01, stop=1.0)
    (reference, expected), (out, statistics) = killed_and_resumed(
        path, tmp_path, 16.0, 2.0, stepping=stepping)
    assert out == reference
    assert timeless(statistics) == timeless(expected)
    if stepping:
        assert statistics["restarts"][0]["ended"] == "killed by SIGKILL"


def test_the_last_checkpoints_are_kept_each_whole(built, tmp_path):
    result = dsim.simulate(built["ssp"] / "spring_mass_nonlinear.ssp", stop=1.0,
                           out=tmp_path / "run.csv", checkpoint_every=0.1,
                           handle_signals=False)
    folder = tmp_path / "run.checkpoints"
    assert sorted(p.name for p in folder.iterdir()) == ["step-0000000080",
                                                        "step-0000000090"]
    written = result.statistics["checkpoints"]
    assert (written["written"], written["last"]["step"]) == (9, 90)
    for checkpoint in folder.iterdir():
        assert sorted(p.name for p in checkpoint.iterdir()) == ["arrays.npz",
                                                                "manifest.json",
                                                                "state.json"]


def test_a_damaged_checkpoint_is_refused_and_a_folder_falls_back_to_the_one_before(
        built, tmp_path, capsys):
    folder = checkpoints_of(built, tmp_path)
    last = sorted(folder.iterdir())[-1]
    data = bytearray((last / "arrays.npz").read_bytes())
    data[len(data) // 2] ^= 0x01
    (last / "arrays.npz").write_bytes(bytes(data))
    with pytest.raises(InputError, match="does not match its digest"):
        dsim.simulate(resume=last, handle_signals=False)
    reference = (tmp_path / "run.csv").read_bytes()
    result = dsim.simulate(resume=folder, handle_signals=False)
    assert result.status == "completed"
    assert result.statistics["resumed"]["step"] == 50
    assert "does not match its digest" in result.statistics["resumed"]["skipped"][0]
    assert (tmp_path / "run.csv").read_bytes() == reference


def test_a_checkpoint_of_another_version_or_a_changed_fmu_is_refused(built, tmp_path):
    scene = tmp_path / "scene.ssp"
    shutil.copy(built["ssp"] / "spring_mass_nonlinear.ssp", scene)
    folder = checkpoints_of(built, tmp_path / "a")
    checkpoint = sorted(folder.iterdir())[0]
    manifest = json.loads((checkpoint / "manifest.json").read_text())
    (checkpoint / "manifest.json").write_text(json.dumps({**manifest, "dsim": "0.0.1"}))
    with pytest.raises(InputError, match="written by dsim 0.0.1"):
        dsim.simulate(resume=checkpoint, handle_signals=False)
    # the same scene, its archive changed after the checkpoint (a byte of its SSD)
    result = dsim.simulate(scene, stop=1.0, out=tmp_path / "b" / "run.csv",
                           checkpoint_every=0.25, handle_signals=False)
    assert result.status == "completed"
    with zipfile.ZipFile(built["ssp"] / "spring_mass_nonlinear.ssp") as old, \
            zipfile.ZipFile(scene, "w") as new:
        for item in old.infolist():
            data = old.read(item)
            new.writestr(item, data + b"<!-- -->" if item.filename.endswith(".ssd") else data)
    with pytest.raises(InputError, match="changed since the checkpoint was written"):
        dsim.simulate(resume=tmp_path / "b" / "run.checkpoints", handle_signals=False)


def test_a_checkpoint_of_another_scene_is_refused_for_a_new_run(built, tmp_path):
    folder = checkpoints_of(built, tmp_path)
    with pytest.raises(InputError, match="is not the scene of the checkpoint's run"):
        dsim.simulate(built["ssp"] / "spring_mass_linear.ssp", start_from=folder,
                      out=tmp_path / "other.csv", handle_signals=False)


def test_a_resumed_run_goes_on_with_its_own_settings(built, tmp_path):
    folder = checkpoints_of(built, tmp_path)
    with pytest.raises(InputError, match="tolerance cannot change"):
        dsim.simulate(resume=folder, tolerance=1e-3, handle_signals=False)


def test_a_crafted_checkpoint_runs_no_code(built, tmp_path):
    """A checkpoint whose arrays hold a pickle (an object array that would run code when
    loaded), its digests made to match: refused, and the code never ran."""
    import hashlib
    import io

    folder = checkpoints_of(built, tmp_path)
    checkpoint = sorted(folder.iterdir())[0]
    marker = tmp_path / "ran"

    class Payload:
        def __reduce__(self):
            return (Path.touch, (marker,))

    buffer = io.BytesIO()
    np.savez(buffer, a0=np.array([Payload()], dtype=object))
    data = buffer.getvalue()
    assert b"touch" in data  # the payload is in the file
    (checkpoint / "arrays.npz").write_bytes(data)
    manifest = json.loads((checkpoint / "manifest.json").read_text())
    manifest["files"]["arrays.npz"] = {"bytes": len(data),
                                       "sha256": hashlib.sha256(data).hexdigest()}
    (checkpoint / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(InputError):
        dsim.simulate(resume=checkpoint, handle_signals=False)
    assert not marker.exists()


def test_a_checkpoint_folder_that_is_a_link_is_refused(built, tmp_path):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (tmp_path / "run.checkpoints").symlink_to(elsewhere)
    with pytest.raises(InputError, match="not a folder"):
        dsim.simulate(built["ssp"] / "spring_mass_nonlinear.ssp", stop=0.5,
                      out=tmp_path / "run.csv", checkpoint_every=0.1, handle_signals=False)
    assert not list(elsewhere.iterdir())


@needs_gcc
def test_fmus_that_cannot_serialize_their_state_are_refused_in_one_line(tmp_path, capsys):
    from tests.support.scenarios import offset_scenes

    scenes = offset_scenes(tmp_path / "scenes")
    code = subprocess.run([*DSIM, "run", str(scenes["chain"]), "--out",
                           str(tmp_path / "run.csv"), "--checkpoint-every", "0.2"],
                          capture_output=True, text=True)
    assert code.returncode == 2
    lines = code.stderr.strip().splitlines()
    assert lines == [f"dsim: error: checkpoints: component '{c}': its FMU cannot serialize "
                     "its state (canSerializeFMUstate is false)" for c in "ab"], lines


def test_a_new_run_from_a_checkpoint_starts_at_its_time(built, tmp_path):
    """``--from`` with a later stop: the rows from the checkpoint on are the original
    run's (the same state, the same steps); a fixed parameter that differs is refused."""
    folder = checkpoints_of(built, tmp_path)
    checkpoint = folder / "step-0000000050"
    result = dsim.simulate(start_from=checkpoint, stop=1.0, out=tmp_path / "from.csv",
                           handle_signals=False)
    assert result.status == "completed" and result["time"][0] == 0.5
    original = dsim.simulate(built["ssp"] / "spring_mass_nonlinear.ssp", stop=1.0)
    # (its time grid is 0.5 + n h, the original's n h: the same to round-off)
    for column in original.signals:
        assert np.allclose(original[column][50:], result[column], rtol=1e-12, atol=1e-15), \
            column
    assert result.statistics["started_from"]["time"] == 0.5
    with pytest.raises(InputError, match="no tunable parameter"):
        dsim.simulate(start_from=checkpoint, parameters={"right.k[1]": 3.0},
                      handle_signals=False)


@needs_gcc
def test_a_new_run_from_a_checkpoint_sets_a_changed_input_on_the_saved_state(kinds,
                                                                              tmp_path):
    """The C feedthrough y = g u + c (g = 0.5, c = 1), its input u fed by nothing: run to
    1 s at u = 0, then from the checkpoint at 0.5 s with u = 4 (set on top of the saved
    state: y = 3 from there); a fixed parameter given anew (g) is refused."""
    fmu = kinds("feedthrough", "2.0", ("CoSimulation",))
    scene = archive_scene(tmp_path / "f.ssp", {"f": (fmu, "CoSimulation", "")}, stop=1.0,
                          step=0.1)
    first = dsim.simulate(scene, out=tmp_path / "run.csv", checkpoint_every=0.5,
                          handle_signals=False)
    assert first["f.y"].tolist() == [1.0] * 11
    checkpoint = tmp_path / "run.checkpoints" / "step-0000000005"
    result = dsim.simulate(start_from=checkpoint, parameters={"f.u": 4.0},
                           out=tmp_path / "from.csv", handle_signals=False)
    assert result.status == "completed", result.message
    assert result["time"][0] == 0.5 and result["f.y"][1:].tolist() == [3.0] * 5
    with pytest.raises(InputError, match="'f.g' differs .* no tunable parameter"):
        dsim.simulate(start_from=checkpoint, parameters={"f.g": 2.0}, handle_signals=False)


def test_an_interrupted_run_leaves_a_checkpoint_where_it_stopped(built, tmp_path):
    """Ctrl-C (SIGINT) ends the run after its step, as interrupted (exit 130), with a
    checkpoint there, from which --resume writes the bytes of the run never stopped."""
    path = built["ssp"] / "spring_mass_nonlinear.ssp"
    reference = tmp_path / "reference.csv"
    assert _dsim("run", path, "--stop", 30, "--out", reference, "--quiet").returncode == 0
    out = tmp_path / "run.csv"
    process = subprocess.Popen([*DSIM, "run", str(path), "--stop", "30", "--out", str(out),
                                "--checkpoint-every", "10", "--quiet"],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    folder = out.with_name("run.checkpoints")
    deadline = time.monotonic() + 120
    while not (folder.is_dir() and any(folder.glob("step-*"))):
        assert process.poll() is None and time.monotonic() < deadline, "no checkpoint"
        time.sleep(0.02)
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130, err
    statistics = json.loads(out.with_name("run.stats.json").read_text())
    assert statistics["status"] == "interrupted"
    assert statistics["checkpoints"]["last"]["step"] == statistics["steps"]
    assert _dsim("run", "--resume", folder, "--quiet").returncode == 0
    assert out.read_bytes() == reference.read_bytes()


def test_resume_refuses_what_it_cannot_honour_in_one_line(built, tmp_path, capsys):
    from tests.support.runs import one_error
    from dsim.master.tools.cli import main

    folder = checkpoints_of(built, tmp_path)
    assert main(["run", "--resume", str(folder), "--out", str(tmp_path / "x.csv")]) == 2
    assert "--out cannot be given with it" in one_error(capsys)
    assert main(["run", "--resume", str(tmp_path / "nowhere")]) == 2
    assert "no such checkpoint" in one_error(capsys)
    assert main(["run", "--resume", str(folder), "--step", "0.02"]) == 2
    assert "step cannot change" in one_error(capsys)
    assert main(["run"]) == 2
    assert "give a scene" in one_error(capsys)


def test_every_point_of_a_sweep_starts_from_the_checkpoint(built, tmp_path, capsys):
    """``dsim sweep --from`` (on Ray: tests/distributed/test_ray_checkpoints.py)."""
    sweep_from_checkpoint(built, tmp_path, capsys, "in-process")
