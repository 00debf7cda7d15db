"""The built SpringMass FMU is a real FMI 2.0 co-simulation FMU: fmpy finds
no problem in it, it runs alone in fmpy, and its state restore is exact."""
import numpy as np
from fmpy import read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

from dsim.master.reading.ports import PortDof, conventional_ports
from dsim.master.running.fmi import SubsystemSpec
from dsim.master.running.fmi.cs2 import CoSimulation2Subsystem

#: how a child process that ran pythonfmu FMUs through fmpy ends: as the dsim command
#: does (master/tools/process_exit.py), without the libraries' exit handlers, where
#: pythonfmu 0.7 releases its interpreter state twice (an abort after the child has
#: printed its result, about one run in thirty: tests/running/test_pythonfmu_exit.py)
EXIT = "from dsim.master.tools.process_exit import end_process; end_process(0)"


def test_fmpy_validate_finds_no_problem(built):
    assert validate_fmu(str(built["fmus"] / "SpringMass.fmu")) == []


def test_runs_alone_in_fmpy_as_a_free_oscillator(built):
    """fmpy's own master, no dsim: one mass on a spring oscillates at its
    (trapezoidal) frequency."""
    fmu = str(built["fmus"] / "SpringMass.fmu")
    result = simulate_fmu(fmu, start_time=0.0, stop_time=1.0, output_interval=1e-3,
                          start_values={"m[1]": 1.0, "k_ground[1]": 400.0, "x0[1]": 0.01},
                          output=["x[1]"])
    w = 20.0
    w_h = 2.0 / 1e-3 * np.arctan(w * 1e-3 / 2.0)
    expected = 0.01 * np.cos(w_h * result["time"])
    assert np.max(np.abs(result["x[1]"] - expected)) < 1e-12


def test_ports_follow_the_naming_convention(built):
    ports = conventional_ports(built["fmus"] / "SpringMass.fmu")
    assert set(ports) == {"P", "Q"}
    assert set(ports["P"]["x"]) == {"f", "u", "v", "a"}
    md = read_model_description(str(built["fmus"] / "SpringMass.fmu"))
    assert md.coSimulation.canGetAndSetFMUstate


def test_rollback_through_the_fmu_is_bit_for_bit(built):
    path = built["fmus"] / "SpringMass.fmu"
    ports = conventional_ports(path)
    glued = [PortDof("c", "P", "x", **{k: ports["P"]["x"][s] for k, s in (
        ("force", "f"), ("position", "u"), ("velocity", "v"), ("acceleration", "a"))})]
    parameters = {"n": ("Integer", 2), "m[1]": ("Real", 10.0), "m[2]": ("Real", 10.0),
                  "k[1]": ("Real", 100.0), "k1[1]": ("Real", 1000.0),
                  "c1[1]": ("Real", 1.4e4), "F0[2]": ("Real", 10.0)}
    fmu = CoSimulation2Subsystem(SubsystemSpec(name="c", path=path, port_dofs=tuple(glued),
                                     parameters=parameters,
                                     reads=("x[1]", "x[2]", "v[2]", "a[2]"), writes=(),
                                     start_time=0.0, stop_time=1.0))
    fmu.finish_initialization()
    try:
        for i in range(20):
            fmu.set_forces([0.1 * i])
            fmu.do_step(i * 0.01, 0.01)
        fmu.begin_step()  # the first save allocates the FMU state
        fmu.trial_step(np.array([1.0]), 0.19, 0.01)
        fmu.begin_step()  # later saves overwrite it (fmi2GetFMUstate on a held state)
        first = fmu.trial_step(np.array([3.0]), 0.2, 0.01)
        first_outputs = fmu.read_outputs()
        fmu.trial_step(np.array([-7.0]), 0.2, 0.01)  # a different trial in between
        again = fmu.trial_step(np.array([3.0]), 0.2, 0.01)
        assert all(np.array_equal(a, b) for a, b in zip(first, again))
        assert np.array_equal(fmu.read_outputs(), first_outputs)
        assert fmu.statistics()["fmi2SetFMUstate"][0] == 2
        assert fmu.statistics()["fmi2GetFMUstate"][0] == 2
    finally:
        fmu.terminate()


def test_fmus_run_in_fmpys_own_ssp_master_even_after_another_dsim_fmu(built):
    """Other masters load dsim's FMUs one after another and delete each FMU's
    folder when done; a later FMU must not depend on an earlier one's copy of the
    fmus package.  fmpy's SSP runner ignores the gluing annotation (the parts run
    unglued), which is enough to show the FMUs run there."""
    import subprocess
    import sys

    code = f"""
import sys, types
stale = types.ModuleType("fmus")
stale.__path__ = ["/nonexistent/fmus"]  # what a freed FMU's copy leaves behind
sys.modules["fmus"] = stale
from fmpy.ssp.simulation import simulate_ssp
for scene in ("crank_slider_rigid", "chain_10"):
    result = simulate_ssp("{built['ssp']}/" + scene + ".ssp", stop_time=0.002, step_size=0.001)
    print(scene, len(result))
{EXIT}"""
    process = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             timeout=300)
    assert process.returncode == 0, process.stderr[-2000:]
    assert "crank_slider_rigid 2" in process.stdout and "chain_10 2" in process.stdout


def test_many_instances_share_one_model_class_and_its_variables(built, tmp_path):
    """pythonfmu 0.7 runs the FMU's script again for every instance and keeps what that
    makes, and pythonfmu registers Python variables per instance: 40 more instances in
    one process must add no model class and no pythonfmu variable (a chain of 10,000
    held 1.8 GB so), the script's namespace must keep its references (pythonfmu releases
    one per instance it never took), and every instance must still compute its own
    oscillator (m = 1 kg, k = 100 N/m, x0 = 0.01 m: x after one step of h = 1 ms)."""
    import json
    import subprocess
    import sys

    code = f"""
import gc, json, sys
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
folder = extract({str(built["fmus"] / "SpringMass.fmu")!r}, unzipdir={str(tmp_path / "fmu")!r})
md = read_model_description(folder)
vr = {{v.name: v.valueReference for v in md.modelVariables}}
def counts():
    gc.collect()
    objects = gc.get_objects()
    return {{"classes": sum(isinstance(o, type) and o.__name__ == "SpringMass" for o in objects),
             "variables": sum(type(o).__module__ == "pythonfmu.variables" for o in objects),
             "namespace": sys.getrefcount(sys.modules["spring_mass_fmu"].__dict__)}}
instances, seen = [], []
for i in range(42):
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier="SpringMass",
                    instanceName=f"m{{i}}")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.setInteger([vr["n"]], [1])
    fmu.setReal([vr["m[1]"], vr["k_ground[1]"], vr["x0[1]"]], [1.0, 100.0, 0.01 * (i + 1)])
    fmu.exitInitializationMode()
    instances.append(fmu)
    if i in (1, 41):
        seen.append(counts())
for fmu in instances:
    fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=1e-3)
print(json.dumps({{"seen": seen, "x": [f.getReal([vr["x[1]"]])[0] for f in instances],
                   "n": [f.getInteger([vr["n"]])[0] for f in instances]}}))
{EXIT}"""
    process = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             timeout=300)
    assert process.returncode == 0, process.stderr[-2000:]
    found = json.loads(process.stdout.strip().splitlines()[-1])
    two, forty_two = found["seen"]
    assert forty_two["classes"] == two["classes"] == 1
    assert forty_two["variables"] == two["variables"] == 0  # no pythonfmu variable at run time
    assert forty_two["namespace"] >= two["namespace"]
    # trapezoidal rule, one step: x1 = x0 (1 - h^2 w^2 / 4) / (1 + h^2 w^2 / 4)
    shrink = (1 - 1e-6 * 100 / 4) / (1 + 1e-6 * 100 / 4)
    assert np.allclose(found["x"], [0.01 * (i + 1) * shrink for i in range(42)], rtol=1e-12)
    assert found["n"] == [1] * 42
