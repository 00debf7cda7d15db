"""Model parameters for one run (``--set``, ``--set-file``, ``parameters=``): the same
bytes as the value in an .ssv parameter set, checked against the modelDescription
before anything runs (one line per problem, exit 2, nothing written), recorded in
the statistics."""
import json
import shutil
import zipfile

import numpy as np
import pytest

import dsim
from dsim.master.tools.cli import main
from tests.support.scene_files import HEADER

SSV = ('<?xml version="1.0" encoding="UTF-8"?>\n<ssv:ParameterSet version="1.0" name="{name}" '
       'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">'
       "<ssv:Parameters>{values}</ssv:Parameters></ssv:ParameterSet>\n")


def _ssv(name: str, values: dict) -> str:
    """An .ssv parameter set of Real values."""
    return SSV.format(name=name, values="".join(
        f'<ssv:Parameter name="{k}"><ssv:Real value="{v}"/></ssv:Parameter>'
        for k, v in values.items()))


def _unpacked(built, tmp_path, scene: str = "spring_mass_linear"):
    folder = tmp_path / scene
    with zipfile.ZipFile(built["ssp"] / f"{scene}.ssp") as archive:
        archive.extractall(folder)
    return folder


def test_set_gives_the_bytes_of_the_same_value_in_a_parameter_set(built, tmp_path):
    """--set, --set-file (.ssv, .csv, .json), parameters= and --parameter-set of a
    shipped scene: one CSV, byte for byte; a different value: other bytes."""
    folder = _unpacked(built, tmp_path)
    values = {"left.k_ground[1]": "250.0", "right.m[2]": "12.5"}
    (folder / "resources" / "study.ssv").write_text(_ssv("study", values))
    (tmp_path / "values.csv").write_text("name,value\n" + "".join(
        f"{k},{v}\n" for k, v in values.items()))
    (tmp_path / "values.json").write_text(json.dumps({k: float(v) for k, v in values.items()}))
    shutil.copy(folder / "resources" / "study.ssv", tmp_path / "outside.ssv")
    common = [str(folder), "--stop", "2", "--quiet"]
    runs = {
        "parameter_set": ["--parameter-set", "resources/study.ssv"],
        "set": [a for k, v in values.items() for a in ("--set", f"{k}={v}")],
        "ssv": ["--set-file", str(tmp_path / "outside.ssv")],
        "csv": ["--set-file", str(tmp_path / "values.csv")],
        "json": ["--set-file", str(tmp_path / "values.json")],
        "plain": [],
    }
    data = {}
    for label, extra in runs.items():
        out = tmp_path / f"{label}.csv"
        assert main(["run", *common, *extra, "--out", str(out)]) == 0, label
        data[label] = out.read_bytes()
    api = dsim.simulate(folder, stop=2.0, out=tmp_path / "api.csv",
                        parameters={"left.k_ground[1]": 250.0, "right.m[2]": 12.5})
    data["api"] = (tmp_path / "api.csv").read_bytes()
    assert api.status == "completed"
    for label in ("set", "ssv", "csv", "json", "api"):
        assert data[label] == data["parameter_set"], label
    assert data["plain"] != data["parameter_set"]  # the values change the run
    statistics = json.loads((tmp_path / "set.stats.json").read_text())
    assert statistics["parameters"] == {"left.k_ground[1]": 250.0, "right.m[2]": 12.5}
    assert json.loads((tmp_path / "parameter_set.stats.json").read_text())[
        "parameter_sets"] == ["resources/study.ssv"]


def test_set_goes_on_top_of_the_parameter_set(built, tmp_path):
    """Precedence: --parameter-set over the scene's bindings, --set over both."""
    folder = _unpacked(built, tmp_path)
    (folder / "resources" / "heavy.ssv").write_text(_ssv("heavy", {"right.m[2]": 40.0}))
    plan = dsim.prepare(folder, parameter_set="resources/heavy.ssv",
                        parameters={"right.m[2]": "20"})
    assert plan.scene.component("right").parameters["m[2]"] == ("Real", 20.0)
    plan = dsim.prepare(folder, parameter_set="resources/heavy.ssv")
    assert plan.scene.component("right").parameters["m[2]"] == ("Real", 40.0)
    assert dsim.prepare(folder).scene.component("right").parameters["m[2]"] == ("Real", 10.0)


def _nested(built, tmp_path):
    """A scene whose SpringMass component 'inner' sits in system 'sub' (sub.inner),
    glued to 'left' at the root, with a root parameter set of its own."""
    fmu = '<ssd:Component name="{0}" source="resources/SpringMass.fmu"/>'
    text = ('<?xml version="1.0" encoding="UTF-8"?>' + HEADER.format(name="nested")
            + '<ssd:System name="root">'
            '<ssd:ParameterBindings><ssd:ParameterBinding source="resources/base.ssv"/>'
            "</ssd:ParameterBindings><ssd:Elements>" + fmu.format("left")
            + '<ssd:System name="sub"><ssd:Elements>' + fmu.format("inner")
            + "</ssd:Elements></ssd:System></ssd:Elements>"
            '<ssd:Annotations><ssc:Annotation type="org.dsim.gluing">'
            '<glue:Gluing xmlns:glue="urn:dsim:gluing:1">'
            '<glue:Joint name="j1" a="left.P" b="sub.inner.P" dofs="x" kind="flexible">'
            '<glue:Spring k0="100"/><glue:Damper c0="5"/></glue:Joint>'
            "</glue:Gluing></ssc:Annotation></ssd:Annotations></ssd:System>"
            '<ssd:DefaultExperiment startTime="0" stopTime="1"><ssd:Annotations>'
            '<ssc:Annotation type="org.dsim.master"><glue:Master xmlns:glue='
            '"urn:dsim:gluing:1" step="0.01"/></ssc:Annotation></ssd:Annotations>'
            "</ssd:DefaultExperiment></ssd:SystemStructureDescription>")
    folder = tmp_path / "nested"
    (folder / "resources").mkdir(parents=True)
    shutil.copy(built["fmus"] / "SpringMass.fmu", folder / "resources")
    (folder / "resources" / "base.ssv").write_text(_ssv("base", {
        "left.k_ground[1]": 100.0, "left.F0[1]": 5.0, "sub.inner.k_ground[1]": 50.0}))
    (folder / "resources" / "heavy.ssv").write_text(_ssv("heavy", {"sub.inner.m[1]": 3.0}))
    (folder / "SystemStructure.ssd").write_text(text)
    return folder


def test_nested_components_by_their_dotted_path(built, tmp_path):
    folder = _nested(built, tmp_path)
    by_set = dsim.simulate(folder, parameters={"sub.inner.m[1]": 3.0, "j1.k0": 400},
                           out=tmp_path / "a.csv")
    by_file = dsim.simulate(folder, parameter_set="resources/heavy.ssv",
                            out=tmp_path / "b.csv")
    assert by_set.status == by_file.status == "completed"
    # the joint law is no FMU value: without it the bytes match the parameter set's
    assert (tmp_path / "a.csv").read_bytes() != (tmp_path / "b.csv").read_bytes()
    same = dsim.simulate(folder, parameters={"sub.inner.m[1]": "3"}, out=tmp_path / "c.csv")
    assert same.status == "completed"
    assert (tmp_path / "c.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
    # a stiffer joint: the two masses move closer together (less stretch at the end)
    stretch = [abs(r["sub.inner.x[1]"] - r["left.x[1]"]).max() for r in (by_set, by_file)]
    assert stretch[0] < 0.5 * stretch[1]
    assert by_set.statistics["parameters"] == {"sub.inner.m[1]": 3.0, "j1.k0": [400.0]}


BAD = {
    "lef.k_ground[1]=1": "parameter 'lef.k_ground[1]': no component or joint of the scene "
                         "is named 'lef' (closest: left)",
    "left.kground[1]=1": "component 'left' (SpringMass.fmu) has no variable 'kground[1]' "
                         "(closest: k_ground[1]",
    "left.n=1.5": "variable 'n' of component 'left' is Integer: '1.5' is not an integer",
    "left.m[1]=heavy": "variable 'm[1]' of component 'left' is Real: 'heavy' is not a "
                       "finite number",
    "left.m[1]=nan": "is Real: 'nan' is not a finite number",
    "left.x[1]=0.1": "variable 'x[1]' of component 'left' is calculated by the FMU",
    "j1.k0=-5": "parameter 'j1.k0': -5 is negative",
    "j1.omega=3": "joint 'j1' measures displacement: 'omega' is a coefficient of the "
                  "penalized measure",
    "j1.k0=1 2": "2 values for joint 'j1''s 1 dofs (x): give 1 or 1",
    "j1.spring=1": "joint 'j1' has no coefficient 'spring'",
    "k=1": "no component or joint of the scene is named 'k' (give COMPONENT.VARIABLE)",
}


@pytest.mark.parametrize("assignment", list(BAD))
def test_a_bad_value_is_one_line_and_exit_2_with_nothing_written(built, tmp_path, capsys,
                                                                  assignment):
    out = tmp_path / "r.csv"
    code = main(["run", str(built["ssp"] / "spring_mass_linear.ssp"), "--set", assignment,
                 "--out", str(out), "--quiet"])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(lines) == 1 and BAD[assignment] in lines[0], lines
    assert list(tmp_path.iterdir()) == []


def test_every_bad_value_at_once_and_what_the_master_writes(built, capsys, tmp_path):
    with pytest.raises(dsim.InputError) as raised:
        dsim.prepare(built["ssp"] / "spring_mass_linear.ssp",
                     parameters={"lef.k": 1, "left.n": "x", "right.F0[2]": True})
    assert len(raised.value.problems) == 3
    assert "'True' is not a finite number" in raised.value.problems[2]
    # glued port forces: the joints set them every step
    with pytest.raises(dsim.InputError) as raised:
        dsim.prepare(built["ssp"] / "spring_mass_linear.ssp", parameters={"left.P.f_x": 2.0})
    assert raised.value.problems == ["parameter 'left.P.f_x': a joint sets this port force "
                                     "every step, and would replace the value"]
    # a free port force (no joint at Q of left) is a constant applied force
    plan = dsim.prepare(built["ssp"] / "spring_mass_linear.ssp", parameters={"left.Q.f_x": 2})
    assert plan.scene.component("left").parameters["Q.f_x"] == ("Real", 2.0)
    with pytest.raises(dsim.InputError, match="give a mapping"):
        dsim.prepare(built["ssp"] / "spring_mass_linear.ssp", parameters=["left.n=1"])


def test_set_file_problems_are_one_line_each(built, tmp_path, capsys):
    scene = str(built["ssp"] / "spring_mass_linear.ssp")
    files = {"a.txt": ("x", "a parameter file is .ssv"),
             "b.csv": ("left.n,1,2\n", "b.csv line 1: give two fields"),
             "c.json": ("[1, 2]", "give a JSON object of name -> value, not a list"),
             "d.ssv": ("<x", "malformed XML")}
    for name, (text, expected) in files.items():
        (tmp_path / name).write_text(text)
        assert main(["run", scene, "--set-file", str(tmp_path / name), "--out",
                     str(tmp_path / "r.csv")]) == 2
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1 and expected in lines[0], lines
    assert main(["run", scene, "--set", "left.n", "--out", str(tmp_path / "r.csv")]) == 2
    assert "give NAME=VALUE" in capsys.readouterr().err
    assert not (tmp_path / "r.csv").exists()


def test_info_lists_what_can_be_set(built, capsys):
    assert main(["info", "--all", str(built["ssp"] / "spring_mass_linear.ssp")]) == 0
    out = capsys.readouterr().out
    assert "can be set (--set left.NAME=VALUE" in out
    line = next(line for line in out.splitlines() if line.strip().startswith("m[1] "))
    assert "Real" in line and "parameter/fixed" in line and "start 1 scene 10 " in line
    left = out.split("can be set (--set left.")[1].split("right:")[0]
    assert " Q.f_x " in left and " P.f_x " not in left  # the joint writes left.P's force
    assert " x[1] " not in left  # outputs are the FMU's
    assert "(--set j1.k0=VALUE: k0 k1 c0 c1)" in out


# --- types, limits and variabilities, on a plain-C FMU -------------------------------
EXTRA_TYPES = """  <TypeDefinitions>
    <SimpleType name="Mode"><Enumeration><Item name="slow" value="1"/>
      <Item name="fast" value="2"/></Enumeration></SimpleType>
  </TypeDefinitions>
  <ModelVariables>"""
EXTRA_VARIABLES = """
    <ScalarVariable name="mode" valueReference="10" causality="parameter" variability="fixed"><Enumeration declaredType="Mode" start="1"/></ScalarVariable>
    <ScalarVariable name="g" valueReference="20" causality="local" variability="constant" initial="exact"><Real start="9.81"/></ScalarVariable>
    <ScalarVariable name="gain2" valueReference="21" causality="calculatedParameter" variability="fixed" initial="calculated"><Real/></ScalarVariable>
  </ModelVariables>"""


def _described_block(block_fmus, tmp_path):
    """The block FMU with limits on gain and tau, an Enumeration parameter, a constant
    and a calculated parameter in its modelDescription (the checks read only that)."""
    path = tmp_path / "block_described.fmu"
    with zipfile.ZipFile(block_fmus["state"]) as old, zipfile.ZipFile(path, "w") as new:
        for name in old.namelist():
            data = old.read(name)
            if name == "modelDescription.xml":
                text = data.decode()
                text = text.replace('<Real start="0.9"/>', '<Real start="0.9" min="0" max="10"/>')
                text = text.replace('<Real start="0.1"/>', '<Real start="0.1" min="1e-6"/>', 1)
                text = text.replace("  <ModelVariables>", EXTRA_TYPES, 1)
                text = text.replace("\n  </ModelVariables>", EXTRA_VARIABLES, 1)
                data = text.encode()
            new.writestr(name, data)
    return path


def _blocks(tmp_path, fmu):
    """Two blocks, b1.y feeding b2.u, 0.1 s in steps of 0.01 s."""
    from tests.support.scene_files import component, scene_folder, ssd

    text = ssd("blocks", [component("b1", "resources/block.fmu"),
                          component("b2", "resources/block.fmu", outputs=["y"], inputs=["u"])],
               [("b1", "y", "b2", "u")], stop=0.1)
    return scene_folder(tmp_path / "blocks", text, {"block.fmu": fmu})


def test_types_limits_and_variabilities(block_fmus, tmp_path):
    folder = _blocks(tmp_path, _described_block(block_fmus, tmp_path))
    problems = {
        "b1.gain": (11, "variable 'gain' of component 'b1' is 11.0, above its max 10"),
        "b1.tau": ("0", "variable 'tau' of component 'b1' is 0.0, below its min 1e-6"),
        "b1.failure": ("yes", "is Integer: 'yes' is not an integer"),
        "b1.enable": ("maybe", "is Boolean: 'maybe' is not true or false"),
        "b1.label": (3, "is String: '3' is not text"),
        "b1.mode": ("medium", "is Enumeration: 'medium' is not one of slow (1), fast (2)"),
        "b2.mode": (3, "is Enumeration: '3' is not one of slow (1), fast (2)"),
        "b1.g": (9.8, "variable 'g' of component 'b1' is a constant: FMI 2.0 lets no "
                      "master set it"),
        "b1.gain2": (1.0, "variable 'gain2' of component 'b1' is a calculated parameter"),
        "b1.count": (1, "is calculated by the FMU (causality output"),
    }
    with pytest.raises(dsim.InputError) as raised:
        dsim.prepare(folder, load_libraries=False,
                     parameters={name: value for name, (value, _) in problems.items()})
    assert len(raised.value.problems) == len(problems)
    for line, (name, (_, expected)) in zip(raised.value.problems, problems.items()):
        assert line.startswith(f"parameter '{name}': ") and expected in line, (line, expected)
    plan = dsim.prepare(folder, load_libraries=False, parameters={
        "b1.mode": "fast", "b2.mode": "1", "b1.enable": "False", "b2.enable": 1,
        "b1.failure": "0", "b1.gain": "1e1", "b1.label": "x"})
    values = plan.scene.component("b1").parameters
    assert values["mode"] == ("Integer", 2) and values["enable"] == ("Boolean", False)
    assert values["gain"] == ("Real", 10.0) and values["failure"] == ("Integer", 0)
    assert plan.scene.component("b2").parameters["enable"] == ("Boolean", True)


def test_values_of_every_type_reach_the_fmu(block_fmus, tmp_path):
    """Integer, Boolean and String inputs and parameters set for a run change what the
    block computes; an input a connection feeds is refused."""
    folder = _blocks(tmp_path, block_fmus["state"])
    plain = dsim.simulate(folder)
    given = dsim.simulate(folder, parameters={
        "b1.extra": "2", "b1.label": "first", "b1.note": "set", "b2.enable": "false",
        "b2.y0": -1.5, "b1.gain": 0.5})
    assert plain.status == given.status == "completed"
    # b1: tau dy/dt = 0.5 (0 + 2) - y from y0 = 1: stays at 1 exactly; b2 holds y0
    assert given["b1.y"] == pytest.approx(1.0, abs=1e-12)
    assert abs(plain["b1.y"][-1] - 1.0) > 0.05  # the scene's own gain 0.9, u 0: decays
    assert list(set(given["b2.y"])) == [-1.5]
    assert given["b1.status"][-1] == "first:set:10"
    with pytest.raises(dsim.InputError) as raised:
        dsim.prepare(folder, parameters={"b2.u": 1.0})
    assert raised.value.problems == ["parameter 'b2.u': a connection feeds this input, and "
                                     "would replace the value before the first step"]


def test_a_load_set_for_the_run_scales_a_linear_frame(built):
    """frame_split is linear elastic: twice the sine load's amplitude (a parameter of the
    cross member's FE FMU, set with parameters=) gives twice the load point's motion."""
    scene = built["ssp"] / "frame_split.ssp"
    amplitude = dsim.prepare(scene).scene.component("cross_front").parameters["load.F_x"][1]
    base = dsim.simulate(scene, stop=0.002, outputs="*.load.u_x")
    twice = dsim.simulate(scene, stop=0.002, outputs="*.load.u_x",
                          parameters={"cross_front.load.F_x": 2 * amplitude})
    assert list(twice.signals) == ["time", "cross_front.load.u_x"]
    moved = base["cross_front.load.u_x"][1:]
    assert abs(moved).max() > 0
    assert np.allclose(twice["cross_front.load.u_x"][1:], 2 * moved, rtol=1e-8, atol=0)
