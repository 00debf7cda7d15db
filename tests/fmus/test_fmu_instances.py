"""Many instances of one dsim FMU in one process (a scene of thousands of FE bodies or
links): the FMU's model class is made once and its variables declared once for the
class, and every instance still computes its own model, to the bit of its core run
directly.  (SpringMass's own test: tests/fmus/test_spring_mass_fmu.py.)"""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dsim.build_fmus.build import FMU_SCRIPTS
from tests.support.paths import ROOT

#: instances made in one process, steps of each, step size (s)
COUNT, STEPS, H = 42, 3, 1e-3
#: the outputs compared with the core's, per FMU
OUTPUTS = {"ElasticBody": ("load.u_x", "load.u_y"),
           "Linkage2D": ("x", "y", "theta", "omega"),
           "FlexibleLink2D": ("reference.y", "reference.theta", "deflection", "stretch")}


def parameters(model: str, i: int) -> dict:
    """Instance ``i``'s parameters: each instance a different model (its own load,
    gravity, spin), so that one instance answering for another would show."""
    if model == "ElasticBody":  # the built-in free beam, loaded at its end
        return {"load.point": "1 0.05", "load.probe": 1, "load.F0_x": 5.0,
                "load.F0_y": -10.0 * (i + 1)}
    if model == "Linkage2D":  # the default pendulum under its own gravity
        from dsim.fmus.linkage.parts import PENDULUM

        mechanism = json.loads(PENDULUM)
        mechanism["gravity"] = [0.0, -9.81 * (1.0 + i / 10.0)]
        return {"mechanism": json.dumps(mechanism)}
    return {"omega0": 0.1 * (i + 1), "gravity_y": -0.5 * (i + 1)}


def core_outputs(model: str, values: dict) -> list[float]:
    """The FMU's outputs after :data:`STEPS` steps, from its core run directly (no FMI):
    zero interface forces, initialised at t = 0, as the FMU's binding does."""
    if model == "ElasticBody":
        from dsim.fmus.elastic.body_spec import BodySpec, SlotBody, build_body, set_parameter

        spec = BodySpec()
        for name, value in values.items():
            set_parameter(spec, name, value)
        core = SlotBody(build_body(spec))
    elif model == "Linkage2D":
        from dsim.fmus.linkage.parts import PartCore, PartParameters, build_part

        core = PartCore(build_part(PartParameters(mechanism=values["mechanism"])))
    else:
        from dsim.fmus.flexible_link.core import FlexibleLink

        core = FlexibleLink(length=6.0, density=7850.0, area=0.01, young=210e9,
                            second_moment=0.1 ** 4 / 12.0, elements=6, x=6.0, y=0.0,
                            theta=0.0, vx=0.0, vy=0.0, omega=values["omega0"],
                            gravity=(0.0, values["gravity_y"]), stiffness_damping=0.0,
                            tolerance=1e-10)
    core.set_interface_forces(np.zeros(len(core.interface)))
    core.initialize(0.0)
    for k in range(STEPS):
        core.step(k * H, H)
    found = core.outputs()
    return [float(found[name]) for name in OUTPUTS[model]]


def child(fmu: str, folder: str) -> None:
    """In a fresh process: :data:`COUNT` instances of ``fmu`` made, set and initialised
    one after the other, then each stepped; prints (JSON) the model classes, pythonfmu
    variables and references to the script's namespace alive after 2 and after all
    instances, each instance's outputs, and its core's run directly."""
    import gc

    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    from pythonfmu import Fmi2Slave

    folder = extract(fmu, unzipdir=folder)
    description = read_model_description(folder)
    model = description.coSimulation.modelIdentifier
    variables = {v.name: v for v in description.modelVariables}
    script = Path(FMU_SCRIPTS[model]).stem

    def counts():
        gc.collect()
        objects = gc.get_objects()
        return {"classes": sum(isinstance(o, type) and o.__name__ == model
                               and issubclass(o, Fmi2Slave) for o in objects),
                "variables": sum(type(o).__module__ == "pythonfmu.variables"
                                 for o in objects),
                "namespace": sys.getrefcount(sys.modules[script].__dict__)}

    instances, seen = [], []
    for i in range(COUNT):
        fmu = FMU2Slave(guid=description.guid, unzipDirectory=folder,
                        modelIdentifier=model, instanceName=f"part{i}")
        fmu.instantiate()
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        for name, value in parameters(model, i).items():
            variable = variables[name]
            getattr(fmu, f"set{variable.type}")([variable.valueReference], [value])
        fmu.exitInitializationMode()
        instances.append(fmu)
        if i + 1 in (2, COUNT):
            seen.append(counts())
    for k in range(STEPS):
        for fmu in instances:
            fmu.doStep(currentCommunicationPoint=k * H, communicationStepSize=H)
    vrs = [variables[name].valueReference for name in OUTPUTS[model]]
    found = [fmu.getReal(vrs) for fmu in instances]
    # the parameters read back, each instance its own (fmpy gives a String as bytes)
    read = [{name: getattr(fmu, f"get{variables[name].type}")(
        [variables[name].valueReference])[0] for name in parameters(model, i)}
        for i, fmu in enumerate(instances)]
    read = [{name: value.decode() if isinstance(value, bytes) else value
             for name, value in values.items()} for values in read]
    print(json.dumps({"seen": seen, "outputs": found, "read": read,
                      "cores": [core_outputs(model, parameters(model, i))
                                for i in range(COUNT)]}))
    # its instances stay alive (they are what is counted): it ends as the dsim command
    # does, without pythonfmu 0.7's exit handlers, which release its interpreter state
    # twice (test_spring_mass_fmu.EXIT)
    from dsim.master.tools.process_exit import end_process

    end_process(0)


def instances_in_one_process(fmu: Path, folder: Path) -> dict:
    """What :func:`child` prints, run in a fresh process."""
    code = (f"from {__name__} import child; "
            f"child({str(fmu)!r}, {str(folder)!r})")
    process = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             timeout=600, cwd=ROOT)
    assert process.returncode == 0, process.stderr[-2000:]
    return json.loads(process.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("model", sorted(OUTPUTS))
def test_many_instances_share_one_model_class_and_compute_their_own_models(
        built, tmp_path, model):
    """pythonfmu 0.7 runs the FMU's script again for every instance and keeps what that
    makes, and registers Python variables per instance (an ElasticBody instance held
    2,120 of them, over 3 MB): 40 more instances must add no model class and no
    pythonfmu variable, the script's namespace must keep its references (pythonfmu
    releases one per instance it never took), and each instance must step its own
    model (its own load, gravity, spin) to the bit of its core stepped directly."""
    found = instances_in_one_process(built["fmus"] / f"{model}.fmu", tmp_path / "fmu")
    two, all_of_them = found["seen"]
    assert all_of_them["classes"] == two["classes"] == 1
    assert all_of_them["variables"] == two["variables"] == 0
    assert all_of_them["namespace"] >= two["namespace"]
    assert found["outputs"] == found["cores"]
    assert len({tuple(outputs) for outputs in found["outputs"]}) == COUNT  # all differ
    assert found["read"] == [parameters(model, i) for i in range(COUNT)]
