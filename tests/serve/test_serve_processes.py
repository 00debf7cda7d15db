"""``dsim serve`` when things go wrong: an FMU that crashes its run, a server that
is killed or stopped while runs are in flight (a real uvicorn process)."""
from __future__ import annotations

import os
import time

import pytest

from tests.support.serve_fixtures import (ServerProcess, launch, server, upload,  # noqa: F401
                                          wait_run)

import dsim
from tests.support.hung_fmu import hung_scene  # noqa: F401 (a fixture)


def test_a_crashing_fmu_ends_its_run_never_the_server(server, block_fmus):
    client, store, scene_id = server
    model = upload(client, block_fmus["state"]).json()["id"]
    answer = client.post("/scenes/new", data={
        "name": "crashing_block", "component_name": ["block"], "component_model": [model],
        "component_parameters": ["failure = 4\nfail_time = 20"], "component_record": [""],
        "joint_name": [""], "joint_a": [""], "joint_b": [""], "connection_start": [""],
        "connection_end": [""], "start": ["0"], "stop": ["30"], "step": ["0.001"],
        "tolerance": ["1e-10"], "max_iterations": [""]}, follow_redirects=False)
    assert answer.status_code == 303, answer.text
    crashing = int(answer.headers["location"].rsplit("/", 1)[1])
    run = wait_run(client, launch(client, crashing, ["block.y"]))
    assert run["status"] == "failed", run
    assert "the run's process was killed by SIGABRT (an FMU may have crashed it)" in \
        run["message"]
    # the steps before the crash are kept in whole rows, but for the last 50 ms
    columns = dsim.read_columns(store.run_folder(run["id"]) / "results.csv")
    assert 2 <= len(columns["time"]) and columns["time"][-1] < 20
    assert run["steps"] == len(columns["time"]) - 1
    assert "SIGABRT" in client.get(f"/runs/{run['id']}").text
    # the server goes on
    assert wait_run(client, launch(client, scene_id, stop="0.2"))["status"] == "completed"


def _gone(pid: int, timeout: float = 20) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            os.kill(pid, 0)
            if b"dsim.serve.worker" not in open(f"/proc/{pid}/cmdline", "rb").read():
                return True
        except (OSError, ProcessLookupError):
            return True
        time.sleep(0.05)
    return False


def _running(client, scene_id: int, store_runs, samples: int = 3) -> dict:
    run_id = launch(client, scene_id, stop="100000")
    run = wait_run(client, run_id, until=("running",))
    live = store_runs / str(run_id) / "live.jsonl"
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        if live.exists() and live.read_text().count('"sample"') >= samples:
            return client.get(f"/api/runs/{run_id}").json()
        time.sleep(0.05)
    raise AssertionError("the run sent no samples")


@pytest.mark.parametrize("how", ["killed", "stopped"])
def test_runs_in_flight_when_the_server_ends_show_as_interrupted(built, tmp_path, how):
    httpx = pytest.importorskip("httpx")
    db = tmp_path / "db.sqlite"
    runs = tmp_path / "db.sqlite.files" / "runs"
    first = ServerProcess(db)
    try:
        with httpx.Client(base_url=first.url, timeout=60) as client:
            with open(built["ssp"] / "spring_mass_linear.ssp", "rb") as file:
                scene_id = client.post("/api/upload", files={"file": file}).json()["id"]
            run = _running(client, scene_id, runs)
        if how == "killed":
            first.kill()
        else:
            first.stop()  # Ctrl-C: the server stops its runs and records them
        assert _gone(run["pid"]), "the worker outlived its server"
    finally:
        first.stop()
    second = ServerProcess(db)
    try:
        with httpx.Client(base_url=second.url, timeout=60) as client:
            found = client.get(f"/api/runs/{run['id']}").json()
            assert found["status"] == "interrupted", found
            assert "the server stopped while it ran" in found["message"] or how == "stopped"
            columns = dsim.read_columns(runs / str(run["id"]) / "results.csv")
            assert len(columns["time"]) >= 2 and found["steps"] == len(columns["time"]) - 1
            assert "interrupted" in client.get(f"/runs/{run['id']}").text
            # the database goes on: a new run on the new server
            assert wait_run(client, launch(client, scene_id, stop="0.1"))["status"] == \
                "completed"
    finally:
        second.stop()


def test_a_second_cancel_ends_a_run_hung_in_an_fmu_with_its_rows_and_step_count(
        server, hung_scene, tmp_path):
    """The oscillator hangs in its 51st step (tests/running/test_hung_fmu.py): the first cancel
    asks for a stop after a step that never ends; the second ends the worker at once
    (not killed after the grace), with the 50 converged rows and the statistics."""
    from dsim.serve.jobs import KILL_GRACE
    from tests.support.scene_files import pack
    from tests.support.hung_fmu import CONVERGED, ROWS
    from tests.support.results import rows_on_disk

    client, store, _ = server
    scene_id = upload(client, pack(hung_scene, tmp_path / "hung.ssp")).json()["id"]
    run_id = launch(client, scene_id, signals=("osc.s",))
    run = wait_run(client, run_id, until=("running",))
    partial = store.run_folder(run_id) / ".results.csv.partial"
    deadline = time.monotonic() + 60
    while rows_on_disk(partial) < ROWS:
        assert time.monotonic() < deadline, rows_on_disk(partial)
        time.sleep(0.05)
    assert client.post(f"/api/runs/{run_id}/cancel").json() == {"cancelled": True}
    time.sleep(0.5)
    assert client.get(f"/api/runs/{run_id}").json()["status"] == "running"  # stuck
    assert client.post(f"/api/runs/{run_id}/cancel").json() == {"cancelled": True}
    sent = time.monotonic()
    run = wait_run(client, run_id, timeout=30)
    assert time.monotonic() - sent < KILL_GRACE  # it ended by itself, nobody killed it
    assert (run["status"], run["exit_code"], run["steps"]) == ("interrupted", 143, CONVERGED)
    columns = dsim.read_columns(store.run_folder(run_id) / "results.csv")
    assert len(columns["time"]) == ROWS and abs(columns["time"][-1] - 0.05) < 1e-12
    assert run["statistics"]["status"] == "interrupted"
    assert run["statistics"]["steps"] == CONVERGED
