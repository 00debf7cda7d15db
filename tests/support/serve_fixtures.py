"""Fixtures and helpers of the ``dsim serve`` tests: a real application over a
database in a temporary folder (FastAPI's TestClient, or a real uvicorn process
on a free port), the real FMUs and scenes of build/, and waiting for runs.

Imported by the serve test modules (``from tests.support.serve_fixtures import ...``);
they are skipped, saying why, when the ``serve`` extra is not installed."""
from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.support.paths import ROOT

pytest.importorskip("fastapi", reason="dsim serve's tests need the extra: pip install "
                                      "'dsim[serve]' (make test installs it)")
pytest.importorskip("httpx", reason="FastAPI's TestClient needs httpx (make test installs it)")

from fastapi.testclient import TestClient  # noqa: E402

from dsim.serve.app import create_app  # noqa: E402

#: the spring_mass_linear scene assembled in forms, as the shipped one is written
SPRING_MASS_FORM = {
    "name": "two_masses", "description": "spring_mass_linear, assembled in a form",
    "component_name": ["left", "right"],
    "component_parameters": ["n = 1\nm[1] = 10\nk_ground[1] = 100\nP.mass = 1\nQ.mass = 1",
                             "n = 2\nm[1] = 10\nm[2] = 10\nk[1] = 100\nF0[2] = 10\n"
                             "P.mass = 1\nQ.mass = 1"],
    "component_record": ["x[1]", "x[1] x[2] a[2]"],
    "joint_name": ["j1"], "joint_a": ["left.P"], "joint_b": ["right.Q"], "joint_dofs": ["x"],
    "joint_kind": ["flexible"], "joint_measure": ["displacement"], "joint_k0": ["100.0"],
    "joint_c0": ["14.139999999999999"], "joint_k1": [""], "joint_c1": [""],
    "connection_start": [""], "connection_end": [""],
    "start": ["0"], "stop": ["10"], "step": ["0.01"], "tolerance": ["1e-10"],
    "max_iterations": ["20"],
}


def upload(client, path: Path, filename: str | None = None):
    """POST a file to /api/upload; the response."""
    with open(path, "rb") as file:
        return client.post("/api/upload", files={"file": (filename or path.name, file)})


def wait_run(client, run_id: int, timeout: float = 90, until=("completed", "failed",
                                                               "interrupted")) -> dict:
    """The run once its status is one of ``until``."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        run = client.get(f"/api/runs/{run_id}").json()
        if run["status"] in until:
            return run
        time.sleep(0.05)
    raise AssertionError(f"run {run_id} still {run['status']} after {timeout} s")


def launch(client, scene_id: int, signals=("right.x[2]",), **settings) -> int:
    answer = client.post(f"/api/scenes/{scene_id}/runs",
                         json={"settings": settings, "signals": list(signals)})
    assert answer.status_code == 200, answer.text
    return answer.json()["id"]


@pytest.fixture(scope="module")
def server(built, tmp_path_factory):
    """A TestClient of an application over a new database (module-wide), with the
    shipped spring_mass_linear scene uploaded: ``(client, store, scene_id)``."""
    folder = tmp_path_factory.mktemp("serve")
    app = create_app(folder / "db.sqlite", slots=2)
    with TestClient(app, base_url="http://127.0.0.1") as client:
        answer = upload(client, built["ssp"] / "spring_mass_linear.ssp")
        assert answer.status_code == 200, answer.text
        yield client, app.state.store, answer.json()["id"]


class ServerProcess:
    """``dsim serve --port 0`` in its own process: the port the system chose, read from
    the address it prints."""

    def __init__(self, db: Path, *options: str):
        self.db = Path(db)
        self.log = self.db.with_suffix(f".{time.monotonic_ns()}.log")
        with open(self.log, "wb") as log:
            self.process = subprocess.Popen(
                [sys.executable, "-m", "dsim.master.tools.cli", "serve", "--db", str(db), "--port", "0",
                 *options], stdout=log, stderr=subprocess.STDOUT, cwd=ROOT,
                env={**os.environ, "PYTHONPATH": str(ROOT)})
        self.port = self._wait_listening()
        self.url = f"http://127.0.0.1:{self.port}"

    def _wait_listening(self, timeout: float = 30) -> int:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.process.poll() is not None:
                raise AssertionError(f"dsim serve exited: {self.log.read_text()}")
            found = re.search(r"open http://127\.0\.0\.1:(\d+)/", self.log.read_text())
            if found:
                port = int(found.group(1))
                assert port != 0
                socket.create_connection(("127.0.0.1", port), timeout=5).close()
                return port
            time.sleep(0.1)
        raise AssertionError(f"dsim serve not listening after {timeout} s")

    def kill(self, number=signal.SIGKILL) -> None:
        self.process.send_signal(number)
        self.process.wait(timeout=30)

    def stop(self) -> None:
        if self.process.poll() is None:
            self.kill(signal.SIGINT)
