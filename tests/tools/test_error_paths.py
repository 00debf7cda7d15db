"""No dsim process ends by a signal on an error path.

An FMU that refuses its parameters, fails a step or goes fatal ends the command with
its documented exit code (2 bad input, 1 a failed run) and one line saying why, and
the process ends with that code: the dsim command skips the FMU libraries' exit
handlers (master/tools/process_exit.py), where pythonfmu's crashed it about once in 90
runs.  Every path runs twice, two processes side by side as a loaded machine runs them
(16 runs in all: a handful of runs would catch that abort only by luck; the exit
without a second release is checked deterministically, under valgrind, by
test_pythonfmu_exit.py).  Our own FMUs refuse parameters without going fatal, and dsim
frees an instance that failed initialization unless it went fatal."""
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE

from dsim.master.running.fmi.messages import _MESSAGES
from dsim.master.tools.cli import main
from tests.support.scene_files import component, edited_archive, scene_folder, ssd
from tests.support.paths import ROOT
from tests.support.scenes import block_scene
from tests.support.third_party.build import c_fmu

REPEATS = 2
#: what a failed run prints besides the line saying why
ALSO_SAID = ("dsim: the ", "dsim: warning: ")


@pytest.fixture(scope="module")
def scenes(built, block_fmus, tmp_path_factory):
    """Error path -> (scene, exit code, what the one line says)."""
    folder = tmp_path_factory.mktemp("error_paths")
    block = block_fmus["state"]
    refusing = {status: c_fmu(folder / "fmus", f"block_instantiate_{status}",
                              defines=(f"INSTANTIATE_FAILS={status}",)) for status in (3, 4)}
    bad_mass = ssd("bad_mass", [component("mass", "resources/SpringMass.fmu",
                                          {"n": 1, "m[1]": -2.0}, outputs=["x[1]"])],
                   stop=0.01, master='step="0.001"')

    def failing(name, fmu=block, **parameters):
        return block_scene(folder / name, fmu, stop=0.01, **parameters)

    instantiate = "Component 'b1': FMU block.fmu cannot be initialised with these " \
                  "parameters: block: simulated failure to instantiate"
    initialise = "Component 'b1': FMU block.fmu cannot be initialised with these " \
                 "parameters: block: simulated failure to initialise"
    return {
        "bad-mesh": (edited_archive(built["ssp"] / "frame_nested_flat.ssp",
                                    folder / "bad_mesh.ssp", "resources/plate.ssv",
                                    "resources/meshes/deck_plate.vtk", "elastic_body_fmu.py"),
                     2, "plate: mesh file 'elastic_body_fmu.py': cannot be read as a mesh"),
        "bad-mass": (scene_folder(folder / "bad_mass", bad_mass,
                                  {"SpringMass.fmu": built["fmus"] / "SpringMass.fmu"}),
                     2, "mass: every mass m[i] must be positive"),
        "instantiate-error": (failing("instantiate_error", refusing[3]), 2, instantiate),
        "instantiate-fatal": (failing("instantiate_fatal", refusing[4]), 2, instantiate),
        "initialise-error": (failing("initialise_error", failure=6), 2, initialise),
        "initialise-fatal": (failing("initialise_fatal", failure=7), 2, initialise),
        "step-error": (failing("step_error", failure=2, fail_time=0.0055), 1,
                       "step 6 (t = 0.006 s): component 'b1': fmi2DoStep failed: it returned "
                       "fmi2Error (block: simulated solver failure at t = 0.006)"),
        "step-fatal": (failing("step_fatal", failure=5, fail_time=0.0055), 1,
                       "step 6 (t = 0.006 s): component 'b1': fmi2DoStep failed: it returned "
                       "fmi2Fatal (block: simulated fatal failure at t = 0.006)"),
    }


def run(scene: Path, out: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "dsim.master.tools.cli", "run", str(scene), "--out",
                           str(out), "--quiet"], capture_output=True, text=True, cwd=ROOT,
                          env={**os.environ, "OMP_NUM_THREADS": "1"})


@pytest.mark.parametrize("path", ["bad-mesh", "bad-mass", "instantiate-error",
                                  "instantiate-fatal", "initialise-error", "initialise-fatal",
                                  "step-error", "step-fatal"])
def test_an_error_path_ends_with_its_exit_code_and_one_line_never_a_signal(
        scenes, tmp_path, path):
    scene, code, message = scenes[path]
    with ThreadPoolExecutor(max_workers=2) as pool:
        runs = list(pool.map(lambda i: run(scene, tmp_path / f"run{i}.csv"), range(REPEATS)))
    for process in runs:
        assert process.returncode == code, (process.returncode, process.stderr)
        lines = process.stderr.strip().splitlines()
        said = [line for line in lines if not line.startswith(ALSO_SAID)]
        assert len(said) == 1 and message in said[0], lines
        assert "Traceback" not in process.stderr and process.stdout == ""


def test_our_fmu_refuses_bad_parameters_with_an_error_it_can_be_freed_after(
        built, tmp_path):
    """pythonfmu answers every Python exception with fmi2Fatal (and frees nothing
    after it): the refusal is logged at fmi2Error instead, the call returns, a step
    is discarded, and the instance is freed as any other."""
    logged = []
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(
        lambda env, name, status, category, message: logged.append((status, message)))
    path = built["fmus"] / "SpringMass.fmu"
    description = read_model_description(str(path))
    variables = {v.name: v.valueReference for v in description.modelVariables}
    fmu = FMU2Slave(guid=description.guid,
                    unzipDirectory=extract(str(path), unzipdir=str(tmp_path / "fmu")),
                    modelIdentifier=description.coSimulation.modelIdentifier,
                    instanceName="mass")
    fmu.instantiate(callbacks=callbacks, loggingOn=True)
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.setReal([variables["m[1]"]], [-2.0])
    fmu.exitInitializationMode()  # fmpy raises for any status above fmi2Warning
    assert (3, b"mass: every mass m[i] must be positive") in logged
    with pytest.raises(FMICallException) as refused:
        fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=1e-3)
    assert refused.value.status == 2  # fmi2Discard: never fatal
    assert all(status != 4 for status, _ in logged)
    fmu.terminate()
    fmu.freeInstance()


@pytest.mark.parametrize("failure, freed", [(6, True), (7, False)])
def test_an_instance_that_fails_initialization_is_freed_unless_it_went_fatal(
        block_fmus, tmp_path, capsys, failure, freed):
    folder = block_scene(tmp_path / "scene", block_fmus["state"], stop=0.01, failure=failure)
    assert main(["run", str(folder), "--out", str(tmp_path / "o.csv"), "--quiet"]) == 2
    assert ((0, "block: instance freed") in _MESSAGES["b1"]) == freed
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
