"""``dsim serve`` under attack, as the hardening issue found each attack: a web page
on a DNS-rebinding name, an FMU whose library runs code when it is loaded, a second
server on one database, and requests that used to end in an HTTP 500.  Against a
real ``dsim serve`` process (docs/security.md, sections 1, 2 and 7)."""
from __future__ import annotations

import io
import os
import subprocess
import sys
import threading
import time
import zipfile

import pytest

from tests.support.serve_fixtures import ROOT, ServerProcess, create_app, wait_run

httpx = pytest.importorskip("httpx")


@pytest.fixture(scope="module")
def process(tmp_path_factory):
    """A real ``dsim serve --port 0`` on a new database: ``(server, client)``."""
    folder = tmp_path_factory.mktemp("security")
    server = ServerProcess(folder / "db.sqlite")
    try:
        with httpx.Client(base_url=server.url, timeout=120) as client:
            yield server, client
    finally:
        server.stop()


def _blobs(server) -> list:
    return sorted(p.name for p in (server.db.parent / "db.sqlite.files" / "blobs").rglob("*")
                  if p.is_file())


def _one_line(answer) -> str:
    """The single problem line of an error answer (JSON or text)."""
    try:
        problems = answer.json()["problems"]
    except ValueError:
        problems = [answer.text.strip()]
    assert len(problems) == 1 and "\n" not in problems[0], problems
    assert "Traceback" not in answer.text
    return problems[0]


# --- 1. no code from a web page ----------------------------------------------------------

def test_a_dns_rebinding_page_is_refused_by_its_host_name(process, built):
    server, client = process
    evil = f"evil.example:{server.port}"
    fmu = (built["fmus"] / "SpringMass.fmu").read_bytes()
    before = _blobs(server)
    # the rebinding page: its Host and Origin agree, as the old same-origin check wanted
    answer = client.post("/api/upload", files={"file": ("a.fmu", fmu)},
                         headers={"Host": evil, "Origin": f"http://{evil}"})
    assert answer.status_code == 421, answer.text
    line = _one_line(answer)
    assert f"answers only to 127.0.0.1:{server.port}, localhost:{server.port}" in line, line
    assert _blobs(server) == before  # nothing was received, let alone inspected
    assert client.get("/api/models", headers={"Host": evil}).status_code == 421
    # another port of this machine is another origin
    assert client.get("/", headers={"Host": f"127.0.0.1:{server.port + 1}"}
                      ).status_code == 421
    for name in ("127.0.0.1", "localhost", "[::1]"):
        assert client.get("/api/models", headers={"Host": f"{name}:{server.port}"}
                          ).status_code == 200, name
    # the right Host, a request made by another site's page: 403 as before
    forged = client.post("/api/upload", files={"file": ("a.fmu", fmu)},
                         headers={"Origin": f"http://{evil}"})
    assert forged.status_code == 403 and _blobs(server) == before


def test_hosts_are_the_bound_names_and_any_host_needs_a_token(tmp_path):
    from dsim.serve.app import accepted_hosts

    assert accepted_hosts("127.0.0.1", 80) == ("127.0.0.1:80", "localhost:80", "[::1]:80")
    assert accepted_hosts("::1", 80) == ("127.0.0.1:80", "localhost:80", "[::1]:80")
    assert accepted_hosts("192.0.2.7", 80)[-1] == "192.0.2.7:80"
    assert accepted_hosts("0.0.0.0", 80) is None and accepted_hosts("::", 80) is None
    with pytest.raises(ValueError, match="needs a token"):
        create_app(tmp_path / "db.sqlite", hosts=None)


def test_an_uploaded_fmu_is_never_loaded_until_a_user_runs_it(process, tmp_path):
    from tests.support.third_party.build import causal_ring_ssp, c_fmu

    server, client = process
    marker = tmp_path / "constructor-ran"
    fmu = c_fmu(tmp_path, "marker", source="marker.c", defines=[f'MARKER_FILE="{marker}"'])
    ssp = causal_ring_ssp(tmp_path / "ring.ssp", fmu, 2, stop=0.01, step=0.001)
    model = client.post("/api/upload", files={"file": ("marker.fmu", fmu.read_bytes())})
    assert model.status_code == 200 and model.json()["kind"] == "model", model.text
    page = client.get(f"/models/{model.json()['id']}")
    assert page.status_code == 200 and "fail_time" in page.text
    scene = client.post("/api/upload", files={"file": ("ring.ssp", ssp.read_bytes())})
    assert scene.status_code == 200 and scene.json()["kind"] == "scene", scene.text
    assert client.get(f"/scenes/{scene.json()['id']}").status_code == 200
    assert not marker.exists(), "inspecting the upload ran its library's constructor"
    # the run, a user's choice, loads the library in the run's own process: the marker
    # FMU does write its marker when it is loaded
    run_id = client.post(f"/api/scenes/{scene.json()['id']}/runs",
                         json={"settings": {}, "signals": []}).json()["id"]
    assert wait_run(client, run_id)["status"] == "completed"
    assert marker.read_text().startswith("loaded")


# --- 2. one server per database ----------------------------------------------------------

def test_a_second_server_on_one_database_exits_2_naming_the_first(process, built):
    server, client = process
    with open(built["ssp"] / "spring_mass_linear.ssp", "rb") as file:
        scene_id = client.post("/api/upload", files={"file": file}).json()["id"]
    run_id = client.post(f"/api/scenes/{scene_id}/runs",
                         json={"settings": {"stop": "100000"}, "signals": []}).json()["id"]
    run = wait_run(client, run_id, until=("running",))
    second = subprocess.run(
        [sys.executable, "-m", "dsim.master.tools.cli", "serve", "--db", str(server.db), "--port", "0"],
        capture_output=True, text=True, timeout=60, cwd=ROOT,
        env={**os.environ, "PYTHONPATH": str(ROOT)})
    lines = second.stderr.strip().splitlines()
    assert second.returncode == 2, second.stdout + second.stderr
    assert len(lines) == 1 and f"another dsim serve (pid {server.process.pid})" in lines[0]
    # the first server and its run go on, untouched
    time.sleep(0.5)
    assert server.process.poll() is None
    assert client.get(f"/api/runs/{run_id}").json()["status"] == "running"
    assert not (server.db.parent / "db.sqlite.files" / "runs" / str(run_id) /
                "results.csv").exists()  # its temporary CSV was not moved into place
    assert client.post(f"/api/runs/{run['id']}/cancel").json()["cancelled"]
    assert wait_run(client, run_id)["status"] == "interrupted"


def test_only_runs_of_a_dead_server_are_taken_over(tmp_path):
    """Runs recorded by a server that is alive (this test's process) are left alone;
    those of a dead one (a process that has ended) are recorded as interrupted."""
    from fastapi.testclient import TestClient

    from dsim import process_start_time
    from dsim.serve.owner import server_identity
    from dsim.serve.store import Store

    ended = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    dead = f"{ended.pid}:{process_start_time(ended.pid)}:0"
    ended.kill()
    ended.wait()
    store = Store(tmp_path / "db.sqlite")
    scene = store.add_scene("0" * 64, 1, "s.ssp", {}, {})
    runs = {}
    for name, owner in (("alive", server_identity()), ("dead", dead), ("none", None)):
        runs[name] = store.add_run("run", scene, {}, [])
        store.update_run(runs[name], status="running", owner=owner, pid=None)
    with TestClient(create_app(tmp_path / "db.sqlite"), base_url="http://127.0.0.1"):
        found = {name: store.run(i) for name, i in runs.items()}
    assert found["alive"]["status"] == "running"
    assert found["dead"]["status"] == "interrupted", found["dead"]
    assert found["none"]["status"] == "interrupted", found["none"]


# --- 7. one clear line, never an HTTP 500 ------------------------------------------------

def _zip_with_bad_name(fmu: bytes) -> bytes:
    """``fmu`` with one more member whose name is flagged UTF-8 but is not."""
    buffer = io.BytesIO(fmu)
    with zipfile.ZipFile(buffer, "a") as archive:
        archive.writestr("bad_\u00e9.txt", b"x")  # not ASCII: flagged UTF-8 (bit 11)
    data = buffer.getvalue()
    assert data.count("bad_\u00e9".encode()) == 2  # local header and central directory
    return data.replace("bad_\u00e9".encode(), b"bad_\xff\xfe")


def _ssp_through_dotdot(built) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(built["ssp"] / "spring_mass_linear.ssp") as old, \
            zipfile.ZipFile(buffer, "w") as new:
        for name in old.namelist():
            data = old.read(name)
            if name == "SystemStructure.ssd":
                data = data.replace(b'source="resources/SpringMass.fmu"',
                                    b'source="resources/../resources/SpringMass.fmu"')
                assert b"../" in data
            new.writestr(name, data)
    return buffer.getvalue()


@pytest.mark.parametrize("case", ["bad utf-8 name", "fmu through ../", "huge id",
                                  "malformed json", "json not an object", "bad signals",
                                  "unknown setting", "malformed multipart"])
def test_bad_requests_are_one_line_and_a_4xx(process, built, case):
    server, client = process
    fmu = (built["fmus"] / "SpringMass.fmu").read_bytes()
    scene_runs = "/api/scenes/1/runs"
    if case == "bad utf-8 name":
        answer = client.post("/api/upload", files={"file": ("a.fmu", _zip_with_bad_name(fmu))})
        expected = "a member's name is not valid UTF-8"
    elif case == "fmu through ../":
        answer = client.post("/api/upload", files={"file": ("s.ssp", _ssp_through_dotdot(built))})
        expected = "its FMU source must name a file inside the scene without '..'"
    elif case == "huge id":
        for path in ("/api/models/", "/api/scenes/", "/api/runs/", "/models/", "/runs/"):
            huge = client.get(path + "99999999999999999999999")
            assert huge.status_code == 404, (path, huge.text)
        answer = client.get("/api/models/99999999999999999999999")
        expected = "no such model"
    elif case == "malformed json":
        answer = client.post(scene_runs, content=b'{"settings": {"stop": ',
                             headers={"Content-Type": "application/json"})
        expected = "the body is not JSON"
    elif case == "json not an object":
        answer = client.post(scene_runs, json=["stop", 1])
        expected = "the body must be a JSON object"
    elif case == "bad signals":
        answer = client.post(scene_runs, json={"signals": "right.x[2]"})
        expected = '"signals" must be a JSON list of column names'
    elif case == "unknown setting":
        answer = client.post(scene_runs, json={"settings": {"stpo": "1"}})
        expected = "unknown setting 'stpo'"
    else:
        answer = client.post("/api/upload", content=b"garbage", headers={
            "Content-Type": "multipart/form-data; boundary=x"})
        expected = "Invalid multipart data"
    assert 400 <= answer.status_code < 500, answer.text
    assert expected in _one_line(answer)


def test_parallel_uploads_of_one_fmu_are_one_model(process, built):
    server, client = process
    fmu = (built["fmus"] / "SpringMass.fmu").read_bytes()
    answers = [None] * 20

    def send(i):
        with httpx.Client(base_url=server.url, timeout=300) as own:
            answers[i] = own.post("/api/upload", files={"file": (f"{i}.fmu", fmu)})

    threads = [threading.Thread(target=send, args=(i,)) for i in range(len(answers))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert [a.status_code for a in answers] == [200] * 20, [a.text for a in answers
                                                           if a.status_code != 200]
    assert len({a.json()["id"] for a in answers}) == 1


def test_one_content_added_at_once_by_many_threads_is_one_row(tmp_path):
    """The race under the parallel uploads, made likely: every thread has the
    inspection behind it and adds the same model and scene at the same moment."""
    from dsim.serve.store import Store

    store = Store(tmp_path / "db.sqlite")
    barrier = threading.Barrier(20)
    ids, errors = [], []

    def add(i):
        barrier.wait()
        try:
            model = store.add_model("a" * 64, 1, f"{i}.fmu", {"modelName": "m"})
            ids.append((model, store.add_scene("b" * 64, 1, f"{i}.ssp", {}, {"c": model})))
        except Exception as error:  # the IntegrityError the issue found
            errors.append(f"{type(error).__name__}: {error}")

    threads = [threading.Thread(target=add, args=(i,)) for i in range(20)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert errors == [] and len(set(ids)) == 1 and len(ids) == 20, errors[:3]
    assert store.one("SELECT COUNT(*) AS n FROM scene_models")["n"] == 1
