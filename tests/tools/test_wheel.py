"""dsim as a user installs it: the built wheel in a fresh virtual environment, used
from a folder that is not the checkout (docs/architecture.md, "One installed name").

* The wheel holds one top-level name, ``dsim`` (and its dist-info); none of the
  repository's folder names (``master``, ``fmus``, ``build_fmus``, ``serve``, and
  ``dsim_serve`` as serve/ was named, ``examples``) is importable after installing it.
* ``dsim build-fmus --out DIR`` builds the shipped FMUs and scenes from the package
  alone; ``dsim run``, ``dsim validate``, ``dsim serve`` and ``import dsim`` work, and a
  run gives the checkout's numbers byte for byte.
* An FMU dsim built runs in an environment that has fmpy, numpy and scipy but no dsim:
  it carries its own code.

The environment is made with ``python -m venv`` (no system site packages).  pip
resolves what the wheel needs from its metadata and the package index (``pip install
--dry-run --report``: the wheel's own requirements, nothing the test's environment
happens to hold), and those releases, which pip installed in the test's environment
from the same pyproject.toml and index, are linked into it rather than unpacked again
(a minute of pip's work, the same files); then pip installs the wheel itself.  A
dependency missing from pyproject.toml is missing there.  The environment without dsim
is a second venv that links every package of the first but dsim.  About a minute.
"""
from __future__ import annotations

import importlib.metadata
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import textwrap
import time
import urllib.request
import zipfile
from pathlib import Path

import numpy as np
import pytest

from dsim.master.recording.results import read_csv
from tests.support.paths import ROOT

#: what a checkout holds that is not the package's source
NOT_SOURCE = shutil.ignore_patterns(".git", ".venv", "build", "results", "__pycache__",
                                    "*.egg-info", ".pytest_cache", "*.pyc")


def _run(command, cwd, timeout=300, **options):
    done = subprocess.run([str(c) for c in command], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout, **options)
    assert done.returncode == 0, f"{command}: exit {done.returncode}\n{done.stdout}\n{done.stderr}"
    return done


def _environment() -> dict:
    """The test's environment without what would make the checkout importable."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    env.update(OMP_NUM_THREADS="1", PIP_DISABLE_PIP_VERSION_CHECK="1", MPLBACKEND="Agg")
    return env


def _site_packages(venv: Path) -> Path:
    [found] = (venv / "lib").glob("python*/site-packages")
    return found


def _venv(folder: Path, wheel: Path, extras: str) -> Path:
    """A fresh virtual environment at ``folder`` with ``wheel[extras]`` installed: its
    requirements as pip resolves them from the wheel's metadata, each release linked
    from this test's environment (the same one, from the same index), then the wheel;
    its python."""
    report = folder.parent / "resolved.json"
    _run([sys.executable, "-m", "pip", "install", "--dry-run", "--quiet", "--ignore-installed",
          "--report", report, f"{wheel}[{extras}]"], cwd=folder.parent, timeout=600,
         env=_environment())
    resolved = {item["metadata"]["name"]: item["metadata"]["version"]
                for item in json.loads(report.read_text())["install"]}
    assert "dsim" in resolved and len(resolved) > 10, resolved
    _run([sys.executable, "-m", "venv", "--without-pip", folder], cwd=folder.parent,
         env=_environment())
    here, linked = _site_packages(folder), set()
    for name, version in resolved.items():
        if name == "dsim":
            continue
        found = importlib.metadata.distribution(name)
        assert found.version == version, (name, found.version, version)
        assert found.files, f"{name} lists no files"
        for file in found.files:
            top = file.parts[0]
            if top != ".." and top not in linked and (here / top).exists() is False:
                (here / top).symlink_to(Path(found.locate_file(top)))
                linked.add(top)
    python = folder / "bin" / "python"
    _run([sys.executable, "-m", "pip", "--python", python, "install", "--quiet", "--no-deps",
          wheel], cwd=folder.parent, timeout=600, env=_environment())
    return python


def _without_dsim(folder: Path, beside: Path) -> Path:
    """A fresh virtual environment at ``folder`` holding, as links, every package of the
    environment at ``beside`` except dsim; its python."""
    _run([sys.executable, "-m", "venv", "--without-pip", folder], cwd=folder.parent,
         env=_environment())
    there, here = _site_packages(beside), _site_packages(folder)
    for entry in there.iterdir():
        if not entry.name.lower().startswith(("dsim", "__editable__")):
            (here / entry.name).symlink_to(entry)
    return folder / "bin" / "python"


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """The wheel built from a copy of the checkout's sources."""
    folder = tmp_path_factory.mktemp("wheel")
    source = folder / "source"
    shutil.copytree(ROOT, source, ignore=NOT_SOURCE)
    _run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", source, "-w",
          folder / "dist"], cwd=folder, timeout=600, env=_environment())
    (built,) = (folder / "dist").glob("dsim-*.whl")
    return built


def test_the_wheel_holds_one_top_level_name(wheel):
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
    tops = {name.split("/")[0] for name in names}
    assert tops == {"dsim", wheel.name.split("-py")[0] + ".dist-info"}
    with zipfile.ZipFile(wheel) as archive:
        listed = archive.read(next(n for n in names if n.endswith("top_level.txt")))
    assert listed.decode().split() == ["dsim"]
    # what build-fmus and serve need at run time travels with it; examples/ does not
    for needed in ("dsim/fmus/spring_mass/spring_mass_fmu.py",
                   "dsim/ssp/chain_10/SystemStructure.ssd", "dsim/build_fmus/twins/__init__.py",
                   "dsim/serve/templates/base.html", "dsim/serve/static/htmx.min.js",
                   "dsim/master/tools/cli.py"):
        assert needed in names, needed
    assert not any(n.startswith(("dsim/examples", "dsim/tests")) for n in names)


def test_installed_from_the_wheel_dsim_works_outside_the_checkout(wheel, built, tmp_path):
    env = _environment()
    python = _venv(tmp_path / "venv", wheel, "serve")
    dsim = tmp_path / "venv" / "bin" / "dsim"
    work = tmp_path / "work"
    work.mkdir()

    # one import name: the repository's folders are not importable names
    _run([python, "-c", textwrap.dedent("""
        import importlib.util, sys
        old = [n for n in ("master", "fmus", "build_fmus", "serve", "dsim_serve",
                          "examples")
               if importlib.util.find_spec(n) is not None]
        assert not old, old
        import dsim
        assert dsim.__file__.startswith(sys.prefix), dsim.__file__
    """)], cwd=work, env=env)

    # the shipped FMUs and scenes, built where the user says
    out = work / "models"
    _run([dsim, "build-fmus", "--out", out], cwd=work, timeout=900, env=env)
    scene = out / "ssp" / "spring_mass_linear.ssp"
    assert sorted(p.name for p in (out / "fmus").glob("*.fmu")) == [
        "ElasticBody.fmu", "FlexibleLink2D.fmu", "Linkage2D.fmu", "SpringMass.fmu"]
    assert {p.name for p in (out / "ssp").glob("*.ssp")} == {
        f"{p.name}.ssp" for p in (ROOT / "ssp").iterdir() if p.is_dir()}
    with zipfile.ZipFile(scene) as archive:  # with its monolithic twin
        assert "resources/reference.csv" in archive.namelist()

    _run([dsim, "run", scene, "--stop", "0.1", "--out", "x.csv", "--quiet"], cwd=work, env=env)
    _run([dsim, "validate", scene], cwd=work, env=env)
    _run([python, "-c", "import dsim; r = dsim.simulate('models/ssp/spring_mass_linear.ssp', "
          "stop=0.1, out='api.csv'); assert r.status == 'completed', r.message"],
         cwd=work, env=env)

    # the numbers of the checkout's dsim and FMUs, byte for byte
    import dsim as here

    here.simulate(built["ssp"] / "spring_mass_linear.ssp", stop=0.1, out=tmp_path / "here.csv")
    reference = (tmp_path / "here.csv").read_bytes()
    assert (work / "x.csv").read_bytes() == reference
    assert (work / "api.csv").read_bytes() == reference
    header, rows = read_csv(work / "x.csv")
    assert len(rows) == 11 and np.isfinite(rows).all() and np.ptp(rows[:, 1:]) > 0

    # the web front end with its templates and static files
    _serve_answers(dsim, work, env)

    # an FMU dsim built carries its own code: it runs where dsim is not installed
    bare = _without_dsim(tmp_path / "bare", tmp_path / "venv")
    _run([bare, "-c", "import importlib.util; assert importlib.util.find_spec('dsim') is None"
          " and importlib.util.find_spec('fmpy') is not None"], cwd=work, env=env)
    for fmu in ("SpringMass", "Linkage2D"):
        probe = textwrap.dedent(f"""
            import numpy as np
            from fmpy import simulate_fmu
            result = simulate_fmu({str(out / "fmus" / (fmu + ".fmu"))!r}, stop_time=0.05,
                                  output_interval=0.01, step_size=0.01)
            np.save("{fmu}.npy", np.array(result.tolist()))
        """)
        _run([bare, "-c", probe], cwd=work, env=env)
        _run([python, "-c", probe.replace(f'"{fmu}.npy"', f'"{fmu}_dsim.npy"')], cwd=work,
             env=env)
        alone, beside_dsim = np.load(work / f"{fmu}.npy"), np.load(work / f"{fmu}_dsim.npy")
        assert alone.shape[0] == 6 and np.isfinite(alone).all()
        assert np.array_equal(alone, beside_dsim)


def _serve_answers(dsim: Path, work: Path, env: dict) -> None:
    """``dsim serve --port 0`` answers its front page and a static file."""
    log = work / "serve.log"
    with open(log, "wb") as output:
        server = subprocess.Popen([str(dsim), "serve", "--db", "models.sqlite", "--port", "0"],
                                  cwd=work, env=env, stdout=output, stderr=subprocess.STDOUT)
    try:
        deadline, port = time.monotonic() + 60, None
        while port is None and time.monotonic() < deadline:
            assert server.poll() is None, log.read_text()
            found = re.search(r"open http://127\.0\.0\.1:(\d+)/", log.read_text())
            port = int(found.group(1)) if found else time.sleep(0.2)
        assert port, log.read_text()
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=30) as page:
            assert page.status == 200 and b"dsim" in page.read()
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/static/dsim.css",
                                    timeout=30) as sheet:
            assert sheet.status == 200 and len(sheet.read()) > 100
    finally:
        server.send_signal(signal.SIGINT)
        server.wait(timeout=30)
