"""``dsim serve`` through its HTTP API and pages (FastAPI's TestClient over a real
application: real FMUs, real worker processes, a real SQLite file)."""
from __future__ import annotations

import html
import io
import socket
import zipfile

import numpy as np
import pytest
from lxml import etree

from tests.support.serve_fixtures import (SPRING_MASS_FORM, create_app, launch, server,  # noqa: F401
                                          upload, wait_run)

import dsim
from dsim.master.tools.cli import main as dsim_main


def test_an_fmu_is_stored_once_by_its_content_and_described(server, built):
    client, store, _ = server
    first = upload(client, built["fmus"] / "SpringMass.fmu", "../../../tmp/evil name.fmu")
    again = upload(client, built["fmus"] / "SpringMass.fmu", "copy.fmu")
    assert first.status_code == 200 and first.json()["kind"] == "model"
    assert again.json() == first.json()  # the same content is the same model
    model = client.get(f"/api/models/{first.json()['id']}").json()
    assert store.blob_path(model["sha256"]).is_file()
    # the name a user gave is shown, never used as a path
    names = {p.name for p in store.files.rglob("*")}
    assert not any("evil" in n or n.endswith(".fmu") for n in names)
    page = client.get(f"/models/{model['id']}").text
    for expected in ("k_ground[1]", "spring to ground k0", "canGetAndSetFMUstate",
                     "parameter", "Real", "spring_mass_linear"):
        assert expected in page, expected
    assert [m["id"] for m in client.get("/api/models?q=spring").json()] == [model["id"]]
    assert client.get("/api/models?q=no-such-model").json() == []


def _fmu_bytes(built) -> bytes:
    return (built["fmus"] / "SpringMass.fmu").read_bytes()


@pytest.mark.parametrize("content, expected", [
    (b"hello", "neither an FMU nor an SSP archive (not a zip archive)"),
    ("truncated", "upload.fmu: its library binaries/linux64/SpringMass.so"),
    ("no description", "neither an FMU (no modelDescription.xml)"),
    ("ssp missing fmu", "FMU 'resources/nothing.fmu' not found"),
])
def test_bad_uploads_are_one_clear_line_each(server, built, tmp_path, content, expected):
    client, store, _ = server
    if content == "truncated":  # its shared library cut short
        buffer = io.BytesIO()
        with zipfile.ZipFile(io.BytesIO(_fmu_bytes(built))) as old, \
                zipfile.ZipFile(buffer, "w") as new:
            for name in old.namelist():
                data = old.read(name)
                new.writestr(name, data[:len(data) // 3] if name.endswith(".so") else data)
        content = buffer.getvalue()
    elif content == "no description":
        buffer = io.BytesIO()
        with zipfile.ZipFile(buffer, "w") as archive:
            archive.writestr("readme.txt", "not an FMU")
        content = buffer.getvalue()
    elif content == "ssp missing fmu":
        source = (built["ssp"] / "spring_mass_linear.ssp")
        buffer = io.BytesIO()
        with zipfile.ZipFile(source) as old, zipfile.ZipFile(buffer, "w") as new:
            for name in old.namelist():
                if not name.endswith(".fmu"):
                    data = old.read(name)
                    if name == "SystemStructure.ssd":
                        data = data.replace(b"resources/SpringMass.fmu",
                                            b"resources/nothing.fmu")
                    new.writestr(name, data)
        content = buffer.getvalue()
    path = tmp_path / "upload.bin"
    path.write_bytes(content)
    before = len(list(store.blobs.rglob("*")))
    answer = upload(client, path, "upload.fmu")
    assert answer.status_code == 400
    problems = answer.json()["problems"]
    assert any(expected in p for p in problems), problems
    assert all("Traceback" not in p and "\n" not in p for p in problems)
    assert len(list(store.blobs.rglob("*"))) == before  # nothing kept
    page = client.post("/upload", files={"file": ("x.fmu", content)})
    assert page.status_code == 400 and expected.split(":")[-1] in html.unescape(page.text)


def test_an_upload_over_the_limit_is_refused(tmp_path):
    app = create_app(tmp_path / "db.sqlite", max_upload=1000)
    from fastapi.testclient import TestClient
    with TestClient(app, base_url="http://127.0.0.1") as client:
        answer = client.post("/api/upload", files={"file": ("big.fmu", b"x" * 5000)})
    assert answer.status_code == 413
    assert "larger than" in answer.text


def test_a_run_gives_what_dsim_run_gives_and_its_files(server, tmp_path):
    client, store, scene_id = server
    run_id = launch(client, scene_id, ["right.x[2]", "j1.f_x"], stop="1")
    run = wait_run(client, run_id)
    assert run["status"] == "completed" and run["exit_code"] == 0, run
    assert run["steps"] == 100 and run["time_reached"] == 1.0
    scene = client.get(f"/api/scenes/{scene_id}").json()
    model = client.get("/api/models?q=SpringMass").json()[0]
    assert run["inputs"]["scene.ssp"] == scene["sha256"]
    assert run["inputs"]["resources/SpringMass.fmu"] == model["sha256"]
    assert run["statistics"]["iterations"]["mean_per_step"] > 0
    # bit for bit what the Python API computes
    csv = tmp_path / "run.csv"
    csv.write_bytes(client.get(f"/runs/{run_id}/results.csv").content)
    expected = dsim.simulate(store.blob_path(scene["sha256"]), stop=1.0)
    found = dsim.read_columns(csv)
    for column in expected.signals:
        assert np.array_equal(found[column], expected[column]), column
    mat = client.get(f"/runs/{run_id}/results.mat")
    from scipy.io import loadmat
    assert loadmat(io.BytesIO(mat.content))["time"].shape == (101, 1)
    assert client.get(f"/runs/{run_id}/results.png").content[:4] == b"\x89PNG"
    assert client.get(f"/runs/{run_id}/stats.json").json()["status"] == "completed"
    assert client.get(f"/runs/{run_id}/../../db.sqlite").status_code == 404
    events = client.get(f"/runs/{run_id}/events").text
    assert "event: samples" in events and "event: done\ndata: completed" in events
    assert '"type": "sample", "i": 100' in events
    page = client.get(f"/runs/{run_id}").text
    assert "Re-run exactly" in page and "resources/SpringMass.fmu" in page


def test_a_run_on_the_isolated_backend_gives_the_in_process_numbers(server):
    """The scene page's backend choice reaches the run: each FMU in its own worker
    process, the CSV bit for bit the in-process one."""
    client, store, scene_id = server
    page = client.get(f"/scenes/{scene_id}").text
    assert all(f'value="{name}"' in page for name in ("in-process", "isolated", "ray"))
    runs = [wait_run(client, launch(client, scene_id, stop="0.3", backend=backend))
            for backend in ("in-process", "isolated")]
    assert [r["status"] for r in runs] == ["completed", "completed"], runs
    assert runs[1]["settings"]["backend"] == "isolated"
    csv = [(store.run_folder(r["id"]) / "results.csv").read_bytes() for r in runs]
    assert csv[0] == csv[1] and csv[0].count(b"\n") == 32  # header + 31 steps


def test_a_page_opened_on_a_long_run_gets_its_history_thinned(server):
    """A long run writes 20 samples a second: a page that opens gets every line that
    is not a sample and at most about 4000 samples, the first and the last among them."""
    import json

    client, store, scene_id = server
    run_id = launch(client, scene_id, stop="0.2")
    assert wait_run(client, run_id)["status"] == "completed"
    live = store.run_folder(run_id) / "live.jsonl"
    start = [line for line in live.read_text().splitlines() if '"start"' in line]
    samples = [json.dumps({"type": "sample", "i": i, "t": i * 0.01, "wall": i * 1e-3,
                           "it_mean": 2.0, "it_max": 2, "refreshes": 1, "res": 0.0,
                           "v": [0.0], "fmu": [0.0, 0.0]}) for i in range(100001)]
    live.write_text("\n".join(start + samples) + "\n")
    events = client.get(f"/runs/{run_id}/events").text
    data = "".join(line[len("data: "):] for line in events.split("event: samples\n", 1)[1]
                   .split("\n\n", 1)[0].splitlines())
    sent = json.loads(data)
    numbers = [line["i"] for line in sent if line["type"] == "sample"]
    assert sent[0]["type"] == "start" and 3000 < len(numbers) <= 4002
    assert numbers[0] == 0 and numbers[-1] == 100000 and numbers == sorted(numbers)


def test_a_rerun_uses_the_same_files_and_settings_and_gives_the_same_numbers(server):
    client, store, scene_id = server
    first = wait_run(client, launch(client, scene_id, stop="0.5", predictor="constant"))
    answer = client.post(f"/runs/{first['id']}/rerun", follow_redirects=False)
    assert answer.status_code == 303
    again = wait_run(client, int(answer.headers["location"].rsplit("/", 1)[1]))
    assert again["rerun_of"] == first["id"] and again["settings"] == first["settings"]
    assert again["inputs"] == first["inputs"]
    csv = [(store.run_folder(r["id"]) / "results.csv").read_bytes() for r in (first, again)]
    assert csv[0] == csv[1]


def test_bad_settings_are_refused_before_anything_runs(server):
    client, _, scene_id = server
    answer = client.post(f"/api/scenes/{scene_id}/runs",
                         json={"settings": {"tolerance": "-1", "coupling": "sideways"}})
    assert answer.status_code == 400
    assert "setting coupling 'sideways' is not one of: iterative, explicit, causal, strong" in \
        answer.json()["problems"]
    page = client.post(f"/scenes/{scene_id}/runs", data={"step": "zero"})
    assert page.status_code == 400 and "setting step &#39;zero&#39; is not a number" in page.text


def test_a_run_takes_model_parameters_from_the_scene_form(server, tmp_path):
    """The scene page's form lists what can be set (from the modelDescriptions and the
    joints); what it sends is checked by dsim run --set's rules before anything is
    queued, stored with the run, and gives dsim's own numbers."""
    client, store, scene_id = server
    page = html.unescape(client.get(f"/scenes/{scene_id}").text)
    for expected in ('name="parameter:left.m[1]" placeholder="10"',
                     'name="parameter:right.F0[2]" placeholder="10"',
                     'name="parameter:j1.k0" placeholder="100"', "spring to ground k0, N/m",
                     'name="parameter:right.P.f_x"'):  # a free port's force: a load
        assert expected in page, expected
    for written in ("left.P.f_x", "right.Q.f_x"):  # the joint sets these every step
        assert f'name="parameter:{written}"' not in page
    answer = client.post(f"/scenes/{scene_id}/runs", follow_redirects=False, data={
        "stop": "1", "signal": "right.x[2]", "parameter:right.m[2]": "12.5",
        "parameter:j1.c0": "20", "parameter:left.k_ground[1]": " "})
    assert answer.status_code == 303, answer.text
    run = wait_run(client, int(answer.headers["location"].rsplit("/", 1)[1]))
    assert run["status"] == "completed", run
    given = {"right.m[2]": 12.5, "j1.c0": [20.0]}
    assert run["settings"]["parameters"] == given
    assert run["statistics"]["parameters"] == given
    scene = client.get(f"/api/scenes/{scene_id}").json()
    expected = dsim.simulate(store.blob_path(scene["sha256"]), stop=1.0, out=tmp_path / "e.csv",
                             parameters={"right.m[2]": "12.5", "j1.c0": 20})
    assert (store.run_folder(run["id"]) / "results.csv").read_bytes() == \
        (tmp_path / "e.csv").read_bytes()
    status = client.get(f"/runs/{run['id']}").text
    assert "--set &#39;right.m[2]=12.5&#39; --set j1.c0=20.0" in status
    # every bad field is one line, and nothing is queued
    before = len(client.get("/runs").text)
    answer = client.post(f"/scenes/{scene_id}/runs", data={
        "parameter:right.mm[2]": "1", "parameter:left.n": "1.5",
        'parameter:<b>x</b>.y': "2", "parameter:j1.k0": "-1"})
    assert answer.status_code == 400
    text = html.unescape(answer.text)
    for line in ("parameter 'right.mm[2]': component 'right' (SpringMass.fmu) has no variable "
                 "'mm[2]' (closest: m[2]", "parameter 'left.n': variable 'n' of component "
                 "'left' is Integer: '1.5' is not an integer",
                 "parameter '<b>x</b>.y': no component or joint of the scene is named '<b>x</b>'",
                 "parameter 'j1.k0': -1 is negative"):
        assert line in text, line
    assert "<b>x</b>" not in answer.text  # shown as text, never as markup
    assert len(client.get("/runs").text) == before
    bad = client.post(f"/api/scenes/{scene_id}/runs", json={"parameters": {"left.n": True}})
    assert bad.status_code == 400
    assert bad.json()["problems"] == ["spring_mass_linear.ssp: parameter 'left.n': variable "
                                      "'n' of component 'left' is Integer: 'True' is not an "
                                      "integer"]
    assert client.post(f"/api/scenes/{scene_id}/runs",
                       json={"parameters": ["left.n"]}).status_code == 400


def test_a_cancelled_run_stops_after_a_step_and_keeps_its_results(server):
    client, store, scene_id = server
    run_id = launch(client, scene_id, stop="100000")
    live = store.run_folder(run_id) / "live.jsonl"
    wait_run(client, run_id, until=("running",))
    for _ in range(400):  # until it has stepped for a while
        if live.exists() and live.read_text().count('"sample"') >= 3:
            break
        import time
        time.sleep(0.05)
    assert client.post(f"/api/runs/{run_id}/cancel").json() == {"cancelled": True}
    run = wait_run(client, run_id)
    assert run["status"] == "interrupted" and "SIGTERM" in run["message"], run
    assert run["exit_code"] == 143 and 0 < run["steps"] < 10_000_000
    columns = dsim.read_columns(store.run_folder(run_id) / "results.csv")
    assert len(columns["time"]) == run["steps"] + 1
    assert run["statistics"]["status"] == "interrupted"
    assert client.post(f"/api/runs/{run_id}/cancel").json() == {"cancelled": False}


def test_runs_wait_for_a_free_slot_and_a_queued_run_can_be_cancelled(built, tmp_path):
    from fastapi.testclient import TestClient
    with TestClient(create_app(tmp_path / "db.sqlite", slots=1),
                    base_url="http://127.0.0.1") as client:
        scene_id = upload(client, built["ssp"] / "spring_mass_linear.ssp").json()["id"]
        running = launch(client, scene_id, stop="100000")
        queued = launch(client, scene_id, stop="0.1")
        wait_run(client, running, until=("running",))
        assert client.get(f"/api/runs/{queued}").json()["status"] == "queued"
        assert client.post(f"/api/runs/{queued}/cancel").json() == {"cancelled": True}
        run = wait_run(client, queued)
        assert run["status"] == "interrupted" and run["message"] == "cancelled before it started"
        assert not (client.app.state.store.run_folder(queued) / "results.csv").exists()
        client.post(f"/api/runs/{running}/cancel")
        assert wait_run(client, running)["status"] == "interrupted"


def test_an_assembled_scene_is_a_standard_ssp_that_dsim_runs(server, built, tmp_path):
    client, store, scene_id = server
    upload(client, built["fmus"] / "SpringMass.fmu")
    model = client.get("/api/models?q=SpringMass").json()[0]
    answer = client.post("/scenes/new", data={**SPRING_MASS_FORM,
                                              "component_model": [model["id"]] * 2},
                         follow_redirects=False)
    assert answer.status_code == 303, answer.text
    new_id = int(answer.headers["location"].rsplit("/", 1)[1])
    scene = client.get(f"/api/scenes/{new_id}").json()
    assert scene["origin"] == "assembled" and scene["description"]["columns"] == [
        "left.x[1]", "right.x[1]", "right.x[2]", "right.a[2]", "j1.f_x"]
    archive = tmp_path / "two_masses.ssp"
    archive.write_bytes(client.get(f"/scenes/{new_id}/download").content)
    with zipfile.ZipFile(archive) as packed:  # files named by hash, never by the user
        assert sorted(packed.namelist()) == ["SystemStructure.ssd",
                                             f"resources/{model['sha256'][:16]}.fmu"]
    assert dsim_main(["validate", str(archive)]) == 0
    assert dsim_main(["run", str(archive), "--stop", "2", "--quiet",
                      "--out", str(tmp_path / "two.csv")]) == 0
    # the same physics as the shipped scene: the same numbers
    shipped = dsim.simulate(built["ssp"] / "spring_mass_linear.ssp", stop=2.0)
    found = dsim.read_columns(tmp_path / "two.csv")
    assert np.array_equal(found["right.x[2]"], shipped["right.x[2]"])
    page = client.get(f"/scenes/{new_id}").text
    assert 'class="joint"' in page and "j1 (x, flexible)" in page
    assert client.get(f"/models/{model['id']}").text.count("two_masses") >= 1


#: tests/running/test_third_party_fmu.py's scene (the C oscillator glued through a port map of
#: its own variable names to a SpringMass) as the assembly form describes it
THIRD_PARTY_FORM = {
    "name": "third_party", "component_name": ["third", "mass"],
    "component_parameters": ["m = 2\nk = 300\ns0 = 0.01",
                             "m[1] = 3\nk_ground[1] = 200\nx0[1] = 0.01\nFa[1] = 5\n"
                             "omega[1] = 7"],
    "component_record": ["s", "x[1]"],
    "port_component": ["third"], "port_name": ["P"], "port_dofs": ["x"],
    "port_force": ["F_in"], "port_position": ["s"], "port_velocity": ["v"],
    "port_acceleration": ["a"],
    "joint_name": ["j"], "joint_a": ["third.P"], "joint_b": ["mass.P"], "joint_dofs": ["x"],
    "joint_kind": ["fixed"], "joint_measure": ["displacement"],
    "connection_start": [""], "connection_end": [""],
    "start": ["0"], "stop": ["2"], "step": ["0.005"], "tolerance": ["1e-13"],
}


def test_a_third_party_fmu_is_glued_through_a_port_map_made_in_the_form(server, built,
                                                                       tmp_path):
    """The saved scene runs as the hand-written one does, to the last bit; the same
    joint on the penalized measure runs too."""
    from dsim.serve.forms import scene_form
    from tests.support.scenes import oscillator_scene as hand_written
    from tests.support.third_party.build import OSCILLATOR_VARIABLES, c_fmu

    client, store, _ = server
    oscillator = c_fmu(tmp_path / "c", "oscillator", "oscillator.c", OSCILLATOR_VARIABLES)
    ids = []
    for fmu in (oscillator, built["fmus"] / "SpringMass.fmu"):
        answer = upload(client, fmu)
        assert answer.status_code == 200, answer.text
        ids.append(answer.json()["id"])
    found = {}
    for measure, penalty in (("displacement", {}),
                             ("penalized", {"joint_xi": ["1"], "joint_omega": ["200"]})):
        form = {**THIRD_PARTY_FORM, "name": f"third_party_{measure}",
                "component_model": [str(i) for i in ids], "joint_measure": [measure],
                **penalty}
        answer = client.post("/scenes/new", data=form, follow_redirects=False)
        assert answer.status_code == 303, answer.text
        archive = tmp_path / f"{measure}.ssp"
        archive.write_bytes(client.get(f"{answer.headers['location']}/download").content)
        with zipfile.ZipFile(archive) as packed:
            ssd = packed.read("SystemStructure.ssd").decode()
        assert '<glue:Port component="third" name="P" dofs="x" force="F_in"' in ssd
        found[measure] = dsim.simulate(archive)
        assert found[measure].ok, found[measure].message
        # and the form filled from the saved scene saves it again, port map and penalty
        scene_id = int(answer.headers["location"].rsplit("/", 1)[1])
        again = client.post("/scenes/new", data=scene_form(store.one(
            "SELECT * FROM scenes WHERE id = ?", scene_id)), follow_redirects=False)
        assert again.status_code == 303, again.text
        copy = tmp_path / f"{measure}_again.ssp"
        copy.write_bytes(client.get(f"{again.headers['location']}/download").content)
        assert np.array_equal(dsim.simulate(copy)["j.f_x"], found[measure]["j.f_x"])
    expected = dsim.simulate(hand_written(tmp_path / "scene", built, oscillator))
    for column in ("third.s", "mass.x[1]", "j.f_x"):
        assert np.array_equal(found["displacement"][column], expected[column]), column
    # the penalized measure keeps the displacement only near compatibility (measured
    # 1.5e-4 of the peak, from the first steps): another measure, the same motion
    peak = np.max(np.abs(expected["third.s"]))
    difference = np.max(np.abs(found["penalized"]["third.s"] - expected["third.s"]))
    assert 0.0 < difference < 1e-3 * peak


def test_a_stored_scene_fills_the_form_and_saves_as_a_new_one_with_its_numbers(server,
                                                                              built):
    """"Edit as a new scene": the form holds every component, parameter, joint and
    setting of the shipped spring_mass_linear; saved unchanged, it runs to the same bits.
    A scene the form cannot hold (files of its own) is said so."""
    from dsim.serve.forms import scene_form

    client, store, scene_id = server
    page = client.get(f"/scenes/new?start={scene_id}").text.replace("&#39;", "'")
    assert 'value="spring_mass_linear_edited"' in page and "k_ground[1] = 100.0" in page
    assert 'value="14.139999999999999"' in page  # the damper, in full precision
    fields = scene_form(store.one("SELECT * FROM scenes WHERE id = ?", scene_id))
    answer = client.post("/scenes/new", data=fields, follow_redirects=False)
    assert answer.status_code == 303, answer.text
    new_id = int(answer.headers["location"].rsplit("/", 1)[1])
    runs = [wait_run(client, launch(client, i, ["right.x[2]", "j1.f_x"], stop="1"))
            for i in (scene_id, new_id)]
    csv = [(store.run_folder(r["id"]) / "results.csv").read_bytes() for r in runs]
    assert csv[0] == csv[1] and csv[0].count(b"\n") == 102
    assert f'href="/scenes/new?start={new_id}"' in client.get(f"/scenes/{new_id}").text
    other = upload(client, built["ssp"] / "frame_nested_flat.ssp").json()["id"]
    refused = client.get(f"/scenes/new?start={other}")
    assert refused.status_code == 400
    assert "parameters naming its own files (cross_front.mesh_file" in refused.text


@pytest.mark.parametrize("change, expected", [
    ({"component_parameters": ["mass = 3", ""]}, "component 1 'left': the FMU has no "
                                                 "variable 'mass'"),
    ({"component_parameters": ["m[1] = heavy", ""]}, "parameter 'm[1]' (Real): could not "
                                                     "convert"),
    ({"component_model": ["", "1"]}, "component 1 'left': choose one of the stored FMUs"),
    ({"joint_b": ["right.R"]}, "port 'R'"),
    ({"component_name": ["left", "left"]}, "the name is used twice"),
    ({"step": ["-1"]}, "setting step must be a finite number greater than 0"),
    ({"joint_measure": ["penalized"]}, "joint 1 'j1': the penalized measure needs omega"),
    ({"port_component": ["right"], "port_name": ["R"], "port_force": ["x[1]"],
      "port_position": ["P.u_x"]}, "port 1 'right.R': force 'x[1]' is not an input of the FMU"),
    ({"port_component": ["nobody"], "port_name": ["R"], "port_force": ["a"],
      "port_position": ["b"]}, "port 1 'nobody.R': 'nobody' is not a component of the scene"),
])
def test_assembly_mistakes_are_listed_and_the_form_kept(server, built, change, expected):
    client, _, _ = server
    upload(client, built["fmus"] / "SpringMass.fmu")
    model = client.get("/api/models?q=SpringMass").json()[0]
    fields = {**SPRING_MASS_FORM, "component_model": [model["id"]] * 2, **change}
    answer = client.post("/scenes/new", data=fields)
    assert answer.status_code == 400
    text = answer.text.replace("&#39;", "'")
    assert expected in text, text[text.find("problem"):][:800]
    assert 'value="two_masses"' in text  # what was typed is still there


def test_a_parameter_set_makes_a_new_scene_and_compare_finds_where_runs_differ(server):
    client, store, scene_id = server
    rows = client.get(f"/scenes/{scene_id}/parameters").text
    assert 'data-name="right.F0[2]"' in rows
    index = rows[:rows.index('data-name="right.F0[2]"')].rsplit('name="value_', 1)[1]
    index = int(index.split('"', 1)[0])
    answer = client.post(f"/scenes/{scene_id}/parameters",
                         data={"set_name": "heavy load", f"value_{index}": "20"},
                         follow_redirects=False)
    assert answer.status_code == 303, answer.text
    location = answer.headers["location"]
    assert location.endswith("?parameter_set=resources/parameters_1.ssv")
    new_id = int(location.split("?")[0].rsplit("/", 1)[1])
    scene = client.get(f"/api/scenes/{new_id}").json()
    assert scene["parent_id"] == scene_id and scene["origin"] == "parameters"
    assert {"path": "resources/parameters_1.ssv", "name": "heavy load", "parameters": 1,
            "bound": False} in scene["description"]["parameter_sets"]
    base = wait_run(client, launch(client, scene_id, stop="1"))
    heavy = wait_run(client, launch(client, new_id, stop="1",
                                    parameter_set="resources/parameters_1.ssv"))
    same = wait_run(client, launch(client, new_id, stop="1"))
    assert heavy["status"] == same["status"] == "completed"
    client.post(f"/scenes/{new_id}/baseline", data={"baseline": base["id"]})
    verdicts = client.get(f"/api/scenes/{new_id}/compare?run={heavy['id']}&run={same['id']}"
                          ).json()
    assert verdicts["baseline"] == base["id"]
    assert all(c["passed"] for c in verdicts["verdicts"][str(same["id"])]["columns"])
    differs = {c["column"]: c for c in verdicts["verdicts"][str(heavy["id"])]["columns"]}
    x3 = differs["right.x[2]"]
    assert not x3["passed"] and x3["first"][0] <= x3["worst"][0] <= 1.0
    assert x3["max_difference"] > x3["allowed"]
    page = client.get(f"/scenes/{scene_id}/compare?run={heavy['id']}&run={same['id']}").text
    assert "differs" in page and "passes" in page and "baseline" in page
    overlay = client.get(f"/scenes/{scene_id}/overlay.json?column=right.x[2]"
                         f"&run={heavy['id']}&run={base['id']}").json()
    assert [s["label"] for s in overlay["series"]] == [f"run {heavy['id']}", f"run {base['id']}"]


def test_a_sweep_shows_its_table_pareto_front_and_cheapest_point(server):
    client, store, scene_id = server
    answer = client.post(f"/scenes/{scene_id}/sweeps",
                         # 20 times the steps: the cheaper point by wall time is step=0.02 even on a
                         # busy machine (with 0.01 against 0.02 the order was left to the noise)
                         data={"step": "0.02, 0.001", "stop": "0.5", "reference": "tightest"},
                         follow_redirects=False)
    assert answer.status_code == 303, answer.text
    run_id = int(answer.headers["location"].rsplit("/", 1)[1])
    sweep = wait_run(client, run_id)
    assert sweep["status"] == "completed" and sweep["kind"] == "sweep", sweep
    page = client.get(f"/runs/{run_id}?target=1").text
    assert page.count("<tr class=\"pareto") >= 1 and "sweep.png" in page
    assert "Cheapest for error ≤ 1: <strong>step=0.02</strong>" in page
    # the reference is the tightest point itself: error 0
    assert "<strong>step=0.001</strong>" in client.get(f"/runs/{run_id}?target=0").text
    assert "is not a number" in client.get(f"/runs/{run_id}?target=small").text
    assert client.get(f"/runs/{run_id}/sweep.png").content[:4] == b"\x89PNG"
    bad = client.post(f"/scenes/{scene_id}/sweeps", data={"step": "fast"})
    assert bad.status_code == 400 and "sweep: step &#39;fast&#39; is not a number" in bad.text


def test_the_diagram_draws_every_component_joint_and_connection(server, built):
    client, _, _ = server
    chain = upload(client, built["ssp"] / "chain_10.ssp").json()["id"]
    svg = etree.fromstring(client.get(f"/scenes/{chain}/diagram.svg").content)
    groups = svg.findall(".//{*}g[@class='component']")
    scene = client.get(f"/api/scenes/{chain}").json()["description"]
    assert [g.get("data-name") for g in groups] == [c["path"] for c in scene["components"]]
    assert len(groups) == 10
    assert len(svg.findall(".//{*}path[@class='joint']")) == 9


def test_a_server_bound_beyond_this_machine_needs_its_token(tmp_path):
    from fastapi.testclient import TestClient
    from dsim.serve.command import loopback

    assert loopback("127.0.0.1") and loopback("::1") and loopback("localhost")
    assert not loopback("0.0.0.0") and not loopback("192.0.2.7")
    app = create_app(tmp_path / "db.sqlite", token="s3cret")
    with TestClient(app, base_url="http://127.0.0.1") as client:
        assert client.get("/").status_code == 401
        assert client.get("/api/models").status_code == 401
        assert client.get("/", headers={"Authorization": "Bearer wrong"}).status_code == 401
        assert client.get("/api/models", headers={"Authorization": "Bearer s3cret"}
                          ).status_code == 200
        answer = client.get("/models?token=s3cret&q=x", follow_redirects=False)
        assert answer.status_code == 303 and answer.headers["location"] == "/models?q=x"
        assert client.get("/").status_code == 200  # the cookie carries it now
        forged = client.post("/upload", files={"file": ("a.fmu", b"x")},
                             headers={"Origin": "http://evil.example"})
        assert forged.status_code == 403


def test_dsim_serve_on_the_command_line_refuses_bad_options(capsys, tmp_path):
    assert dsim_main(["serve", "--port", "70000"]) == 2
    assert "--port 70000: not a port number" in capsys.readouterr().err
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        assert dsim_main(["serve", "--db", str(tmp_path / "db.sqlite"), "--port",
                          str(port)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert not (tmp_path / "db.sqlite").exists()
    assert len(lines) == 1 and f"--port {port}: cannot listen there" in lines[0], lines


def test_a_sweep_with_a_failed_point_shows_it_and_the_run_list_says_so(server, built):
    """Regression: a failed point's message (commas and quotes in it) was written JSON-
    quoted into sweep.csv and read back by a CSV reader that took the quotes off, so
    the page's json.loads raised (HTTP 500), and the run list called the sweep
    completed with nothing said of the failure."""
    client, store, _ = server
    answer = upload(client, built["ssp"] / "spring_mass_nonlinear.ssp")
    assert answer.status_code == 200, answer.text
    scene_id = answer.json()["id"]
    # the explicit baseline with the quadratic predictor diverges on the nonlinear joint
    # at H = 0.02 s (docs/sweep.md); the iterative coupling does not
    answer = client.post(f"/scenes/{scene_id}/sweeps",
                         data={"step": "0.02", "coupling": "explicit, iterative",
                               "predictor": "quadratic", "stop": "2"},
                         follow_redirects=False)
    assert answer.status_code == 303, answer.text
    run_id = int(answer.headers["location"].rsplit("/", 1)[1])
    sweep = wait_run(client, run_id)
    assert sweep["status"] == "completed", sweep  # a failed point is a row, not a failed sweep
    assert sweep["message"].startswith("1 of 2 points failed"), sweep
    page = client.get(f"/runs/{run_id}")
    assert page.status_code == 200, page.text[-2000:]
    folder = store.run_folder(run_id)
    failed = [line for line in (folder / "sweep.csv").read_text().splitlines()
              if ",failed," in line]
    assert len(failed) == 1
    message = failed[0].rsplit(",failed,", 1)[1]
    tree = etree.HTML(page.text)
    cells = [" ".join(td.itertext()) for td in tree.iter("td")]
    assert any(c.startswith("failed") for c in cells)
    # the reason is on the page as the run wrote it (no JSON quotes, no escapes)
    reason = [c for c in cells if "diverg" in c or "not finite" in c or "step" in c]
    assert reason and not any(c.startswith('"') for c in reason), cells
    listing = client.get("/runs").text
    row = next(tr for tr in etree.HTML(listing).iter("tr")
               if tr.find(".//a") is not None and tr.find(".//a").text == f"#{run_id}")
    assert "1 of 2 points failed" in " ".join(row.itertext())
    assert message  # something was written for the failed point


def test_a_parameter_sweep_from_the_form_shows_kpis_sensitivity_and_plots(server):
    client, store, scene_id = server
    answer = client.post(f"/scenes/{scene_id}/sweeps", follow_redirects=False, data={
        "vary": "right.k[1]=100:400:log\nright.m[2]=5:20", "design": "lhs", "samples": "6",
        "seed": "3", "kpis": "max(right.x[2])\nargmax(right.x[2])", "stop": "1"})
    assert answer.status_code == 303, answer.text
    run_id = int(answer.headers["location"].rsplit("/", 1)[1])
    sweep = wait_run(client, run_id)
    assert sweep["status"] == "completed" and not sweep["message"], sweep
    tree = etree.HTML(client.get(f"/runs/{run_id}").text)
    table = tree.find(".//table[@id='sweep-table']")
    heads = [" ".join(th.itertext()) for th in table.iter("th")]
    assert heads[:5] == ["point", "right.k[1]", "right.m[2]", "max(right.x[2])",
                         "argmax(right.x[2])"] and "error" not in heads
    rows = store.run_folder(run_id) / "sweep.csv"
    peaks = [float(line.split(",")[3]) for line in rows.read_text().splitlines()[1:]]
    shown = [float(tr.findall("td")[3].text) for tr in table.iter("tr") if tr.findall("td")]
    assert sorted(shown) == pytest.approx(sorted(peaks), rel=1e-4) and len(shown) == 6
    sensitivity = tree.find(".//table[@id='sensitivity-table']")
    measures = {(tds[1].text, tds[3].text) for tds in
                (tr.findall("td") for tr in sensitivity.iter("tr")) if tds}
    assert ("right.k[1]", "SRC") in measures and ("right.m[2]", "SRC") in measures
    for name in ("kpis.png", "scatter.png"):
        assert client.get(f"/runs/{run_id}/{name}").content[:4] == b"\x89PNG"
    design = client.get(f"/runs/{run_id}/design.json").json()
    assert len(design["configurations"]) == 6 and design["spec"]["design"]["seed"] == 3
    bad = client.post(f"/scenes/{scene_id}/sweeps", data={
        "vary": "right.k[1]=100:400:5\nnot a line", "design": "lhs", "samples": "6"})
    assert bad.status_code == 400
    problems = [" ".join(li.itertext()) for li in etree.HTML(bad.text).iter("li")]
    assert any("without a count" in p for p in problems) and \
        any("NAME=SPEC" in p for p in problems), problems
    # parameters are checked against the FMUs before the sweep is queued
    before = store.one("SELECT COUNT(*) AS n FROM runs")["n"]
    bad = client.post(f"/scenes/{scene_id}/sweeps", data={
        "vary": "left.nope=1:2\nright.k[1]=100:400", "design": "lhs", "samples": "4"})
    assert bad.status_code == 400
    problems = [" ".join(li.itertext()) for li in etree.HTML(bad.text).iter("li")]
    assert len(problems) == 1 and "'nope'" in problems[0], problems
    assert store.one("SELECT COUNT(*) AS n FROM runs")["n"] == before  # nothing queued


# --- the first hour (issue 32): the page's command makes the job, the sweep form checks
def _page_command(client, run_id: int) -> list[str]:
    import shlex

    tree = etree.HTML(client.get(f"/runs/{run_id}").text)
    return shlex.split(" ".join(tree.find(".//code[@id='command']").itertext()))


def test_a_runs_command_line_makes_the_same_run(server, tmp_path):
    """The run page's command is the dsim run that gives the same results, bit for bit
    (its settings and --set values, no Python reprs)."""
    client, store, scene_id = server
    answer = client.post(f"/scenes/{scene_id}/runs", follow_redirects=False, data={
        "stop": "0.5", "step": "0.005", "relative_tolerance": "1e-9",
        "signal": "right.x[2]", "parameter:right.m[2]": "12.5", "parameter:j1.c0": "20"})
    assert answer.status_code == 303, answer.text
    run = wait_run(client, int(answer.headers["location"].rsplit("/", 1)[1]))
    assert run["status"] == "completed", run
    words = _page_command(client, run["id"])
    assert words[:3] == ["dsim", "run", "scene.ssp"] and "--relative-tolerance" in words
    scene = tmp_path / "scene.ssp"
    scene.symlink_to(store.blob_path(client.get(f"/api/scenes/{scene_id}").json()["sha256"]))
    out = tmp_path / "again.csv"
    assert dsim_main(words[1:2] + [str(scene)] + words[3:] + ["--out", str(out),
                                                              "--quiet"]) == 0
    assert out.read_bytes() == (store.run_folder(run["id"]) / "results.csv").read_bytes()


def test_a_sweeps_command_line_is_the_dsim_sweep_that_makes_it(server, tmp_path):
    """Regression: a sweep's command was `dsim run ... --grid '{}' --fixed '{...}'
    --reference None`.  Now it is the dsim sweep command; run, it gives the same
    points and KPI values."""
    import csv

    client, store, scene_id = server
    answer = client.post(f"/scenes/{scene_id}/sweeps", follow_redirects=False, data={
        "step": "0.02, 0.01", "vary": "right.m[2]=8,12", "kpis": "max(right.x[2])",
        "stop": "0.3"})
    assert answer.status_code == 303, answer.text
    run_id = int(answer.headers["location"].rsplit("/", 1)[1])
    assert wait_run(client, run_id)["status"] == "completed"
    words = _page_command(client, run_id)
    assert words[:3] == ["dsim", "sweep", "scene.ssp"], words
    assert not any(w in ("--grid", "--fixed", "None", "{}") for w in words), words
    scene = tmp_path / "scene.ssp"
    scene.symlink_to(store.blob_path(client.get(f"/api/scenes/{scene_id}").json()["sha256"]))
    out = tmp_path / "again"
    assert dsim_main(words[1:2] + [str(scene)] + words[3:] + ["--out", str(out)]) == 0

    def table(folder):
        with open(folder / "sweep.csv", newline="") as file:
            return sorted((r["step"], r["right.m[2]"], r["max(right.x[2])"], r["status"])
                          for r in csv.DictReader(file))
    served = table(store.run_folder(run_id))
    assert len(served) == 4 and table(out) == served


def test_the_sweep_form_refuses_a_kpi_of_a_column_the_scene_does_not_record(server):
    client, store, scene_id = server
    before = store.one("SELECT COUNT(*) AS n FROM runs")["n"]
    bad = client.post(f"/scenes/{scene_id}/sweeps", data={
        "step": "0.02, 0.01", "stop": "0.3", "kpis": "max(right.y[2])"})
    assert bad.status_code == 400
    problems = [" ".join(li.itertext()) for li in etree.HTML(bad.text).iter("li")]
    assert len(problems) == 1 and "no recorded column matches 'right.y[2]'" in problems[0] \
        and "closest: right.x[2]" in problems[0], problems
    assert store.one("SELECT COUNT(*) AS n FROM runs")["n"] == before  # nothing queued


def test_the_upload_text_says_the_library_is_never_loaded(server):
    client, _, _ = server
    text = " ".join(etree.HTML(client.get("/").text).itertext())
    assert "library loads on this machine" not in text
    assert "never loaded to inspect it" in text


def test_the_scene_page_shows_numbers_not_reprs(server):
    client, _, scene_id = server
    page = client.get(f"/scenes/{scene_id}").text
    assert "14.139999999999999" not in page and "<td>14.14</td>" in page
