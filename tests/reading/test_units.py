"""Units end to end: dsim's FMUs declare SI units (and pass ``fmpy validate``), joints and
connections refuse mixed units in one line, and the statistics JSON, the .mat file and
every plot carry the units the FMUs declare."""
import json
import shutil
import zipfile

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu
from lxml import etree
from scipy.io import loadmat

import dsim
from dsim.build_fmus.units import UNITS
from dsim.master.recording.results import (plot_overlay, plot_signals, read_units,
                                           set_title, unit_panels)
from dsim.master.sweeps.plots import sweep_units
from dsim.master.sweeps.table import Point
from dsim.master.tools.cli import main
from dsim.master.tools.plot import overlay_files

FMUS = ("SpringMass", "ElasticBody", "Linkage2D", "FlexibleLink2D")
#: the SI base exponents of units a mechanical model must get right
SI = {"m": {"m": 1}, "N": {"kg": 1, "m": 1, "s": -2}, "N.m": {"kg": 1, "m": 2, "s": -2},
      "rad": {"rad": 1}, "m/s2": {"m": 1, "s": -2}, "Pa": {"kg": 1, "m": -1, "s": -2}}
BASES = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")


@pytest.mark.parametrize("identifier", FMUS)
def test_every_built_fmu_declares_si_units_and_validates(built, identifier):
    path = built["fmus"] / f"{identifier}.fmu"
    assert validate_fmu(str(path)) == []  # fmpy validate: no problem
    description = read_model_description(str(path))
    defined = {u.name: u for u in description.unitDefinitions}
    reals = [v for v in description.modelVariables if v.type == "Real"]
    with_unit = [v for v in reals if v.unit]
    assert len(with_unit) >= 0.8 * len(reals)  # the few without are ratios and counts
    for variable in with_unit:
        unit = defined[variable.unit]  # every unit used is defined
        exponents = {b: getattr(unit.baseUnit, b) for b in BASES
                     if getattr(unit.baseUnit, b)}
        assert exponents == UNITS[variable.unit][0]
        if variable.unit in SI:
            assert exponents == SI[variable.unit]
    by_name = {v.name: v for v in reals}
    ports = [v for v in reals if v.name.split(".")[-1][:2] in ("f_", "u_", "v_", "a_")]
    assert ports and all(v.unit for v in ports)  # every port variable
    for variable in ports:
        kind, dof = variable.name.split(".")[-1].split("_")
        turning = dof.startswith("r")
        assert variable.unit == {"f": "N.m" if turning else "N",
                                 "u": "rad" if turning else "m",
                                 "v": "rad/s" if turning else "m/s",
                                 "a": "rad/s2" if turning else "m/s2"}[kind]
    expected = {"SpringMass": {"m[1]": "kg", "x[2]": "m", "k[1]": "N/m", "c[1]": "N.s/m"},
                "ElasticBody": {"youngs_modulus": "Pa", "density": "kg/m3"},
                "Linkage2D": {"theta": "rad", "torque": "N.m", "omega": "rad/s"},
                "FlexibleLink2D": {"reference.theta": "rad", "second_moment": "m4"}}
    for name, unit in expected[identifier].items():
        assert by_name[name].unit == unit
    angles = [v for v in reals if v.unit == "rad"]
    assert all(v.displayUnit == "deg" for v in angles)
    for unit in description.unitDefinitions:  # deg is 180/pi rad, defined properly
        if unit.name == "rad":
            assert unit.displayUnits[0].name == "deg"
            assert unit.displayUnits[0].factor == pytest.approx(180 / np.pi, rel=1e-15)


def test_results_carry_units_in_the_statistics_and_the_mat_file(built, tmp_path):
    result = dsim.simulate(built["ssp"] / "spring_mass_nonlinear.ssp", stop=0.5,
                           out=tmp_path / "run.csv", mat=tmp_path / "run.mat")
    expected = {"time": "s", "left.x[1]": "m", "right.x[1]": "m", "right.x[2]": "m",
                "right.a[2]": "m/s2", "j1.f_x": "N"}
    statistics = json.loads((tmp_path / "run.stats.json").read_text())
    assert statistics["units"] == expected
    assert list(statistics["units"]) == (tmp_path / "run.csv").read_text().splitlines()[0] \
        .split(",")  # one unit per CSV column, in the CSV's order
    assert read_units(tmp_path / "run.csv") == expected
    assert result.statistics["units"] == expected
    content = loadmat(tmp_path / "run.mat")
    names = [str(n[0]) for n in content["names"].ravel()]
    units = [str(u[0]) for u in content["units"].ravel()]
    assert dict(zip(names, units)) == {k: v for k, v in expected.items() if k != "time"}
    assert str(content["time_unit"][0]) == "s"


def test_a_linkage_records_angles_moments_and_joint_forces_in_their_units(built, tmp_path):
    plan = dsim.prepare(built["ssp"] / "crank_slider_rigid.ssp")
    assert plan.units["crank.theta"] == "rad" and plan.units["crank.torque"] == "N.m"
    assert plan.units["slider.P.u_x"] == "m"
    forces = [c for c in plan.units if ".f_" in c]
    assert forces and all(plan.units[c] == "N" for c in forces)


def _with_unit(source, target, variables, unit, factor):
    """A copy of an FMU whose ``variables`` are declared in ``unit`` (value_SI =
    factor * value): the same code, another modelDescription."""
    with zipfile.ZipFile(source) as archive:
        entries = {name: archive.read(name) for name in archive.namelist()}
    root = etree.fromstring(entries["modelDescription.xml"])
    definition = etree.SubElement(root.find("UnitDefinitions"), "Unit", name=unit)
    etree.SubElement(definition, "BaseUnit", m="1", factor=repr(factor))
    for variable in root.find("ModelVariables"):
        if variable.get("name") in variables:
            variable.find("Real").set("unit", unit)
    entries["modelDescription.xml"] = etree.tostring(root, xml_declaration=True,
                                                     encoding="UTF-8")
    with zipfile.ZipFile(target, "w") as archive:
        for name, data in entries.items():
            archive.writestr(name, data)


def _scene(built, tmp_path, right_fmu=None, ssd=lambda text: text):
    folder = tmp_path / "scene"
    shutil.copytree(built["ssp"].parent.parent / "ssp" / "spring_mass_nonlinear", folder)
    shutil.copy(built["fmus"] / "SpringMass.fmu", folder / "resources" / "SpringMass.fmu")
    text = (folder / "SystemStructure.ssd").read_text()
    if right_fmu is not None:
        shutil.copy(right_fmu, folder / "resources" / "Millimetre.fmu")
        first = text.index('source="resources/SpringMass.fmu"')
        second = text.index('source="resources/SpringMass.fmu"', first + 1)
        text = text[:second] + 'source="resources/Millimetre.fmu"' + text[
            second + len('source="resources/SpringMass.fmu"'):]
    (folder / "SystemStructure.ssd").write_text(ssd(text))
    return folder


def test_a_joint_refuses_ports_in_two_units_in_one_line(built, tmp_path, capsys):
    millimetre = tmp_path / "mm.fmu"
    _with_unit(built["fmus"] / "SpringMass.fmu", millimetre, ("Q.u_x",), "mm", 0.001)
    folder = _scene(built, tmp_path, millimetre)
    assert main(["run", str(folder), "--out", str(tmp_path / "r.csv"), "--quiet"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].endswith("joint 'j1' glues left.P.u_x in 'm' to right.Q.u_x in 'mm': a "
                             "joint exchanges values unconverted, so both ports must use "
                             "one unit")
    assert not (tmp_path / "r.csv").exists()
    # the same unit by another name (m, defined with factor 1) glues as before
    metre = tmp_path / "metre.fmu"
    _with_unit(built["fmus"] / "SpringMass.fmu", metre, ("Q.u_x",), "metre", 1.0)
    assert dsim.simulate(_scene(built, tmp_path / "2", metre), stop=0.1).ok


def test_a_connection_between_quantities_is_refused_in_one_line(built, tmp_path, capsys):
    def connect(text):  # left.x[1] (a position, m) feeds right.F0[1] (a load, N)
        text = text.replace('<ssd:Connector name="x[2]" kind="output">',
                            '<ssd:Connector name="F0[1]" kind="parameter"><ssc:Real/>'
                            '</ssd:Connector><ssd:Connector name="x[2]" kind="output">')
        return text.replace("</ssd:Elements>", "</ssd:Elements><ssd:Connections>"
                            '<ssd:Connection startElement="left" startConnector="x[1]" '
                            'endElement="right" endConnector="F0[1]"/></ssd:Connections>')
    folder = _scene(built, tmp_path, ssd=connect)
    assert main(["run", str(folder), "--out", str(tmp_path / "r.csv"), "--quiet"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].endswith(
        "cannot connect 'm' (m) and 'N' (kg m s-2) are not the same dimension")


def test_panels_group_columns_by_unit_and_count_what_they_leave_out():
    names = ["a.theta", "a.x", "b.x", "a.torque", "j.f_x", "j.f_y"] + [
        f"k[{i}].f_x" for i in range(10)] + ["a.count"]
    units = {"a.theta": "rad", "a.x": "m", "b.x": "m", "a.torque": "N.m", "j.f_x": "N",
             "j.f_y": "N", "a.count": ""} | {f"k[{i}].f_x": "N" for i in range(10)}
    panels, left = unit_panels(names, units, max_curves=8)
    assert [(p.unit, p.label) for p in panels] == [
        ("rad", "angle (rad)"), ("m", "position (m)"), ("N.m", "moment (N.m)"),
        ("N", "force (N)"), ("", "no unit declared")]
    assert panels[1].names == ["a.x", "b.x"] and panels[1].left_out == 0
    assert panels[3].names == ["j.f_x", "j.f_y"] + [f"k[{i}].f_x" for i in range(6)]
    assert panels[3].left_out == 4 and left == []
    panels, left = unit_panels(names, units, max_curves=8, max_panels=2)
    assert [p.unit for p in panels] == ["rad", "m"] and left == [
        n for n in names if units[n] not in ("rad", "m")]
    panels, left = unit_panels(["a.x", "j.f_x", "b.x"], None)  # no statistics beside
    assert [(p.label, p.names) for p in panels] == [
        ("outputs (units not recorded)", ["a.x", "b.x"]),
        ("joint forces (units not recorded)", ["j.f_x"])]


def test_plots_are_written_with_their_panels_and_title(built, tmp_path, capsys):
    scene = built["ssp"] / "spring_mass_nonlinear.ssp"
    assert main(["run", str(scene), "--stop", "0.5", "--quiet", "--set", "right.m[1]=20",
                 "--out", str(tmp_path / "a.csv"), "--plot", str(tmp_path / "a.png")]) == 0
    assert (tmp_path / "a.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    statistics = json.loads((tmp_path / "a.stats.json").read_text())
    assert set_title("spring_mass_nonlinear", statistics["parameters"]) == \
        "spring_mass_nonlinear: --set right.m[1]=20"
    signals = dsim.read_columns(tmp_path / "a.csv")
    panels = plot_signals(signals, tmp_path / "b.png", units=statistics["units"])
    assert [(p.unit, p.names) for p in panels] == [
        ("m", ["left.x[1]", "right.x[1]", "right.x[2]"]), ("m/s2", ["right.a[2]"]),
        ("N", ["j1.f_x"])]
    assert (tmp_path / "b.png").is_file()
    panels = plot_overlay({"a": signals, "b": signals}, ["right.x[2]", "j1.f_x"],
                          tmp_path / "c.png", units=statistics["units"])
    assert [p.label for p in panels] == ["position (m)", "force (N)"]
    done = overlay_files([tmp_path / "a.csv"], ["right.*"], tmp_path / "d.png")
    assert done.drawn == ["right.x[1]", "right.x[2]", "right.a[2]"]
    assert (tmp_path / "d.png").is_file()


def test_sweep_axes_name_the_units_of_factors_and_kpis(built, tmp_path):
    plan = dsim.prepare(built["ssp"] / "spring_mass_nonlinear.ssp")
    dsim.simulate(plan.scene.file, stop=0.2, out=tmp_path / "point_001.csv")
    point = Point({"right.m[1]": 2.0}, results=tmp_path / "point_001.csv")
    units = sweep_units(plan, ["right.m[1]", "step", "j1.k0"],
                        ["max(right.x[2])", "maxabs(*.f_x)", "argmax(right.a[2])",
                         "max(right.*)"], [point])
    assert units == {"right.m[1]": "kg", "step": "s", "j1.k0": "",
                     "max(right.x[2])": "m", "maxabs(*.f_x)": "N",
                     "argmax(right.a[2])": "s", "max(right.*)": ""}


def test_a_third_party_fmus_units_are_shown_as_it_declares_them(tmp_path, capsys):
    """The C bouncing ball (tests/support/third_party/kinds) declares h in m and v in m/s in
    its own UnitDefinitions, FMI 2.0 and FMI 3.0 alike: dsim info, the statistics and
    the plot's panels show them."""
    from tests.support.scenes import archive_scene
    from tests.support.third_party.kinds.build import build_fmu

    for version in ("2.0", "3.0"):
        fmu = build_fmu(tmp_path / version, "bouncing_ball", version)
        path = archive_scene(tmp_path / f"ball{version}.ssp", {"ball": (fmu, "CoSimulation", "")},
                     stop=0.2)
        result = dsim.simulate(path, out=tmp_path / f"ball{version}.csv")
        assert result.ok, result.statistics["message"]
        assert result.statistics["units"] == {"time": "s", "ball.h": "m", "ball.v": "m/s"}
        panels = plot_signals(result.signals, tmp_path / "ball.png",
                              units=result.statistics["units"])
        assert [p.label for p in panels] == ["position (m)", "velocity (m/s)"]
        assert main(["info", "--all", str(path)]) == 0
        table = capsys.readouterr().out
        assert any(line.split()[:3] == ["g", "Real", "m/s2"] for line in table.splitlines())
