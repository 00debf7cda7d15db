"""The finite-element FMU (ElasticBody) and the frame scenes: frame_split glued equals
the monolithic frame, frame_nested equals its flattened twin, rollback is bit for bit
through the FMU, and a body the parameters cannot make is bad input (exit 2, one line)."""
import subprocess
import sys

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from examples import frame as frame_example
from dsim.build_fmus.frame_scenes import part_parameters
from dsim.fmus.elastic.body_spec import build_body, port_node_counts, spec_from_parameters
from dsim.fmus.elastic.frame import monolithic_frame
from dsim.master.api import prepare, simulate
from dsim.master.planning.load import load_scene
from dsim.master.recording.results import read_csv
from dsim.master.tools.cli import main
from tests.support.paths import ROOT
from tests.support.scene_files import edited_archive

#: the scene folder: the parts' mesh_file values are paths in it
FRAME_SPLIT = ROOT / "ssp" / "frame_split"


def alone(parameters: dict) -> dict:
    """A part's parameters for the FMU run without dsim: the mesh by its absolute path
    (dsim hands the FMU that path when it runs the scene)."""
    return {**parameters, "mesh_file": str(FRAME_SPLIT / parameters["mesh_file"])}


def test_fmu_validates_and_runs_alone(built):
    from fmpy import simulate_fmu
    from fmpy.validation import validate_fmu

    fmu = built["fmus"] / "ElasticBody.fmu"
    assert validate_fmu(str(fmu)) == []
    start = {key: value for key, value in alone(part_parameters("cross_front")).items()
             if not key.startswith("port2")}
    result = simulate_fmu(str(fmu), stop_time=2e-3, output_interval=1e-4,
                          start_values=start, output=["load.u_x", "port1[5].u_x"])
    assert np.all(np.isfinite(result["load.u_x"])) and result["load.u_x"][-1] > 0
    assert result["port1[5].u_x"][0] == pytest.approx(0.1)  # a global position, m


def test_frame_split_glued_equals_monolithic(built, tmp_path):
    """SCENES.md: to 1e-8 of the peak (0.02 s here; the full 0.2 s is in docs/frames.md)."""
    stop = 0.02
    out = tmp_path / "frame_split.csv"
    statistics = simulate(built["ssp"] / "frame_split.ssp", out=out, stop=stop).statistics
    result = frame_example.compare(out, monolithic_frame(stop_time=stop))
    print(f"frame_split: peak {result['peak']:.3e} m, relative error "
          f"{result['relative_error']:.2e}")
    assert statistics["steps"] == 200 and result["peak"] > 1e-5
    assert result["relative_error"] < 1e-8
    assert statistics["lambda_refreshes"] == 1  # linear bodies: one flexibility suffices
    assert statistics["iterations"]["max_per_step"] <= 2
    header, _ = read_csv(out)
    assert header[:3] == ["time", "cross_front.load.u_x", "front_left[1].f_x"]
    assert len(header) == 2 + 6 * 5 * 2  # six edges of five nodes, x and y


def test_node_set_ports_glue_only_the_declared_nodes(built):
    checked = prepare(built["ssp"] / "frame_split.ssp")
    sizes = {spec.name: len(spec.port_dofs) for spec in checked.specs}
    assert sizes == {"rail_left": 30, "rail_right": 30, "cross_front": 20, "cross_mid": 20,
                     "cross_rear": 20}
    front = next(spec for spec in checked.specs if spec.name == "cross_front")
    assert front.port_dofs[-1].port == "port2[5]"


def test_frame_nested_equals_flat(built, tmp_path):
    stop = 0.01
    nested = load_scene(built["ssp"] / "frame_nested.ssp")
    assert {c.path for c in nested.components} >= {"frame.cross_front", "plate"}
    assert [j.name for j in nested.joints][::6] == ["frame.front_left", "plate_front"]
    assert nested.joints[-1].a == ("frame.cross_rear", "port3")
    results = {}
    for name in ("frame_nested", "frame_nested_flat"):
        out = tmp_path / f"{name}.csv"
        simulate(built["ssp"] / f"{name}.ssp", out=out, stop=stop)
        results[name] = read_csv(out)
    (header, nested_data), (flat_header, flat_data) = results.values()
    assert [h.replace("frame.", "", 1) for h in header] == flat_header
    peak = np.max(np.abs(flat_data[:, flat_header.index("cross_front.load.u_x")]))
    assert peak > 1e-6
    assert np.max(np.abs(nested_data - flat_data)) <= 1e-10 * max(peak, 1.0)


def _instance(built, parameters):
    path = built["fmus"] / "ElasticBody.fmu"
    description = read_model_description(str(path))
    variables = {v.name: v for v in description.modelVariables}
    fmu = FMU2Slave(guid=description.guid, unzipDirectory=extract(str(path)),
                    modelIdentifier="ElasticBody", instanceName="cross")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    setters = {"String": fmu.setString, "Integer": fmu.setInteger, "Real": fmu.setReal}
    for name, value in parameters.items():
        setters[variables[name].type]([variables[name].valueReference], [value])
    fmu.exitInitializationMode()
    return fmu, variables


def test_rollback_is_bit_for_bit_through_the_fmu(built):
    fmu, variables = _instance(built, alone(part_parameters("cross_front")))
    forces = [variables[f"{p}[{k}].f_{d}"].valueReference
              for p in ("port1", "port2") for k in range(1, 6) for d in "xy"]
    watched = [variables[n].valueReference for n in ("load.u_x", "port2[3].u_y",
                                                     "port1[2].a_x")]
    rng = np.random.default_rng(3)
    h = 1e-4
    for n in range(3):
        fmu.setReal(forces, list(rng.normal(size=20)))
        fmu.doStep(currentCommunicationPoint=n * h, communicationStepSize=h)
    state = fmu.getFMUstate()
    trial = [list(rng.normal(size=20)) for _ in range(2)]
    histories = []
    for attempt in range(2):
        if attempt:
            fmu.setFMUstate(state)
        values = []
        for n, f in enumerate(trial, start=3):
            fmu.setReal(forces, f)
            fmu.doStep(currentCommunicationPoint=n * h, communicationStepSize=h)
            values.append(fmu.getReal(watched))
        histories.append(np.array(values))
    fmu.freeFMUstate(state)
    fmu.terminate()
    fmu.freeInstance()
    assert np.any(histories[0] != 0.0)
    assert np.array_equal(histories[0], histories[1])  # bit for bit


@pytest.mark.parametrize("part", ["cross_front", "rail_left"])  # a rail has clamped port nodes
def test_a_batch_of_one_kind_reads_what_a_mixed_batch_reads(built, part):
    """A batch of port positions (or velocities) is read straight from the body's state,
    a batch of several kinds through the binding's full vectors: after steps, a restore
    and new forces both give the same numbers to the bit, and they move."""
    fmu, variables = _instance(built, alone(part_parameters(part)))
    pairs = build_body(spec_from_parameters(part_parameters(part)), FRAME_SPLIT).interface
    forces = [variables[f"{q}.f_{d}"].valueReference for q, d in pairs]
    kinds = {kind: [variables[f"{q}.{kind}_{d}"].valueReference for q, d in pairs]
             for kind in "uva"}
    rng, h = np.random.default_rng(5), 1e-4
    readings = []
    state = None
    for n in range(4):
        if n == 3:
            fmu.setFMUstate(state)
        fmu.setReal(forces, list(rng.normal(size=len(forces))))
        fmu.doStep(currentCommunicationPoint=n * h, communicationStepSize=h)
        if n == 1:
            state = fmu.getFMUstate()
        alone_kinds = [fmu.getReal(kinds[kind]) for kind in "uva"]
        mixed = fmu.getReal(kinds["u"] + kinds["v"] + kinds["a"])
        assert np.array(alone_kinds).ravel().tobytes() == np.array(mixed).tobytes()
        readings.append(mixed)
    fmu.freeFMUstate(state)
    fmu.terminate()
    fmu.freeInstance()
    assert not np.array_equal(readings[0], readings[1])


def test_the_fused_glued_trial_gives_the_same_bits_and_counts(built, tmp_path, monkeypatch):
    """A glued trial of an FMU runs as one call (restore, forces, step, positions): the
    run's results are byte-identical to the general path's, with the same FMI calls
    counted."""
    from dsim.master.running.fmi.cs2 import CoSimulation2Subsystem
    from dsim.master.running.subsystem import Subsystem

    runs = {}
    for path in ("fused", "general"):
        if path == "general":
            monkeypatch.setattr(CoSimulation2Subsystem, "trial_step", Subsystem.trial_step)
        out = tmp_path / f"{path}.csv"
        statistics = simulate(built["ssp"] / "frame_split.ssp", out=out, stop=0.003,
                              handle_signals=False).statistics
        counts = {name: sum(c["functions"].get(name, {}).get("calls", 0)
                            for c in statistics["components"].values())
                  for name in ("fmi2SetFMUstate", "fmi2SetReal", "fmi2DoStep", "fmi2GetReal")}
        runs[path] = (out.read_bytes(), counts)
    assert runs["fused"] == runs["general"]
    assert runs["fused"][1]["fmi2SetFMUstate"] > 0 and runs["fused"][1]["fmi2DoStep"] > 0


def test_parts_are_data_and_checked():
    resources = FRAME_SPLIT
    spec = spec_from_parameters(part_parameters("rail_left"))
    assert port_node_counts(spec, resources) == {"port1": 5, "port2": 5, "port3": 5}
    spec = spec_from_parameters({**part_parameters("cross_mid"), "port1.nodes": 4})
    with pytest.raises(ValueError, match="node set has 5 nodes but the parameter port1.nodes"):
        build_body(spec, resources)
    spec = spec_from_parameters({**part_parameters("rail_right"), "port4.nodes": 1})
    with pytest.raises(ValueError, match="port4.nodes = 1 but no node set"):
        build_body(spec, resources)
    spec = spec_from_parameters({**part_parameters("rail_right"), "fidelity": "wing"})
    with pytest.raises(ValueError, match="fidelity = 'wing' must be one of"):
        build_body(spec, resources)


def _edited(built, tmp_path, before, after):
    """frame_nested_flat.ssp with the plate's parameter file edited."""
    return edited_archive(built["ssp"] / "frame_nested_flat.ssp", tmp_path / "edited.ssp",
                          "resources/plate.ssv", before, after)


@pytest.mark.parametrize("before, after, message", [
    ("resources/meshes/deck_plate.vtk", "elastic_body_fmu.py",
     "mesh file 'elastic_body_fmu.py': cannot be read as a mesh"),
    ("resources/meshes/deck_plate.vtk", "meshes/missing.msh",
     "mesh file 'meshes/missing.msh': no such"),
    ("point 0.05 0.6", "box 10 10 11 11", "node set 'port1' is empty"),
], ids=["garbage-mesh", "missing-mesh", "empty-node-set"])
def test_a_body_the_parameters_cannot_make_is_bad_input(built, tmp_path, capsys,
                                                        before, after, message):
    """Relative to the FMU's own resources: what the FMU says of the file."""
    bad = _edited(built, tmp_path, before, after)
    code = main(["run", str(bad), "--out", str(tmp_path / "o.csv"), "--quiet"])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1, lines
    assert "Component 'plate'" in lines[0] and "ElasticBody.fmu" in lines[0]
    assert message in lines[0]


@pytest.mark.parametrize("after, message", [
    ("resources/meshes/missing.vtk",
     "parameter 'mesh_file' = 'resources/meshes/missing.vtk': the scene has no such file"),
    ("resources/../SystemStructure.ssd",
     "parameter 'mesh_file' = 'resources/../SystemStructure.ssd' leaves the scene's "
     "resources folder"),
], ids=["missing", "outside"])
def test_a_scene_file_that_is_not_there_is_bad_input(built, tmp_path, capsys, after, message):
    """A String parameter naming a file of the scene (resources/...) is checked before
    any FMU starts: one line naming the parameter set and the value."""
    bad = _edited(built, tmp_path, "resources/meshes/deck_plate.vtk", after)
    code = main(["validate", str(bad)])
    lines = capsys.readouterr().err.strip().splitlines() + [""]
    assert code == 2 and message in lines[0] and "'plate'" in lines[0], lines


def test_the_scene_hands_its_mesh_files_to_the_fmus(built):
    """frame_nested_flat carries its meshes (resources/meshes/); the FMUs get their
    extracted paths, and the scene lists them among its input files."""
    scene = load_scene(built["ssp"] / "frame_nested_flat.ssp")
    plate = next(c for c in scene.components if c.path == "plate")
    assert plate.parameters["mesh_file"] == ("String", "resources/meshes/deck_plate.vtk")
    mesh = plate.files["mesh_file"]
    assert mesh.is_file() and mesh.name == "deck_plate.vtk" and mesh in scene.inputs
    spec = next(s for s in prepare(built["ssp"] / "frame_nested_flat.ssp").specs
                if s.name == "plate")
    assert spec.parameters["mesh_file"][1].endswith("/resources/meshes/deck_plate.vtk")
    assert spec.files == ("mesh_file",)


def test_info_shows_the_gluable_ports_and_the_scene_files(built, capsys):
    assert main(["info", "--all", str(built["ssp"] / "frame_nested_flat.ssp")]) == 0
    text = capsys.readouterr().out
    rail = text[text.index("  rail_left:"):text.index("  rail_right:")]
    assert ("ports: port1[1..5](x y z), port2[1..5](x y z), port3[1..5](x y z), "
            "rigid1(rx ry rz x y z)") in rail
    ports = next(line for line in rail.splitlines() if "ports:" in line)
    # outputs only: not ports (a probe's point is a parameter a run may set, listed apart)
    assert "probe1" not in ports and "load(" not in ports
    assert "scene file: mesh_file = resources/meshes/frame_rail_left_0.025.vtk (" in rail


def test_bad_mesh_through_the_console_is_one_line(built, tmp_path):
    bad = _edited(built, tmp_path, "resources/meshes/deck_plate.vtk", "elastic_body_fmu.py")
    process = subprocess.run([sys.executable, "-m", "dsim.master.tools.cli", "run", str(bad), "--out",
                              str(tmp_path / "o.csv")], capture_output=True, text=True)
    assert process.returncode == 2
    assert len(process.stderr.splitlines()) == 1 and "Traceback" not in process.stderr, \
        process.stderr
    assert process.stdout == ""


def test_frame_fidelity_sets_apply(built, tmp_path):
    """frame_split --parameter-set coarse is the frame at 0.05 m: it equals the one-mesh
    frame at 0.05 m, not the 0.025 m one; cb40 reduces every part (Craig-Bampton, 40
    modes) and stays within 1e-3 of the full parts over 0.01 s."""
    stop = 0.01
    scene = built["ssp"] / "frame_split.ssp"
    coarse = simulate(scene, out=tmp_path / "coarse.csv", stop=stop, parameter_set="coarse")
    assert coarse.ok
    result = frame_example.compare(tmp_path / "coarse.csv",
                                   monolithic_frame(element_size=0.05, stop_time=stop))
    full = frame_example.compare(tmp_path / "coarse.csv", monolithic_frame(stop_time=stop))
    reduced = simulate(scene, out=tmp_path / "cb40.csv", stop=stop, parameter_set="cb40")
    cb = frame_example.compare(tmp_path / "cb40.csv", monolithic_frame(stop_time=stop))
    print(f"coarse vs 0.05 m frame {result['relative_error']:.1e}, vs 0.025 m frame "
          f"{full['relative_error']:.1e}; cb40 vs full {cb['relative_error']:.1e}")
    assert result["relative_error"] < 1e-8 < 1e-3 < full["relative_error"]
    assert cb["relative_error"] < 1e-3
