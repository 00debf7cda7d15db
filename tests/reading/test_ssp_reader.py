"""The SSP reader, the shipped archives' validity and the build's up-to-date check."""
import zipfile

from fmpy.ssp.ssd import read_ssd

from dsim.master.planning.load import load_scene
from dsim.master.tools.cli import main

NESTED = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="nested"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">
  <ssd:System name="root">
    <ssd:Elements>
      <ssd:Component name="left" source="resources/SpringMass.fmu">
        <ssd:ParameterBindings>
          <ssd:ParameterBinding>
            <ssd:ParameterValues>
              <ssv:ParameterSet version="1.0" name="inline">
                <ssv:Parameters>
                  <ssv:Parameter name="m[1]"><ssv:Real value="10"/></ssv:Parameter>
                  <ssv:Parameter name="n"><ssv:Integer value="1"/></ssv:Parameter>
                </ssv:Parameters>
              </ssv:ParameterSet>
            </ssd:ParameterValues>
          </ssd:ParameterBinding>
        </ssd:ParameterBindings>
      </ssd:Component>
      <ssd:System name="sub">
        <ssd:Elements>
          <ssd:Component name="a" source="resources/SpringMass.fmu"/>
          <ssd:Component name="b" source="resources/SpringMass.fmu"/>
        </ssd:Elements>
        <ssd:Connections>
          <ssd:Connection startElement="a" startConnector="x[1]" endElement="b" endConnector="P.f_x">
            <ssc:LinearTransformation factor="2" offset="1"/>
          </ssd:Connection>
        </ssd:Connections>
        <ssd:Annotations>
          <ssc:Annotation type="org.dsim.gluing">
            <glue:Gluing xmlns:glue="urn:dsim:gluing:1">
              <glue:Joint name="inner" a="a.Q" b="b.P" dofs="x"/>
            </glue:Gluing>
          </ssc:Annotation>
        </ssd:Annotations>
      </ssd:System>
    </ssd:Elements>
    <ssd:Annotations>
      <ssc:Annotation type="org.dsim.gluing">
        <glue:Gluing xmlns:glue="urn:dsim:gluing:1">
          <glue:Joint name="outer" a="left.P" b="sub.a.P" dofs="x" kind="flexible"
                      measure="penalized" support="1.5">
            <glue:Spring k0="100 " k1="0"/>
            <glue:Damper c0="1.5"/>
            <glue:Penalty xi="0.7" omega="30"/>
          </glue:Joint>
        </glue:Gluing>
      </ssc:Annotation>
    </ssd:Annotations>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0.5" stopTime="2">
    <ssd:Annotations>
      <ssc:Annotation type="org.dsim.master">
        <glue:Master xmlns:glue="urn:dsim:gluing:1" step="0.02" maxIterations="7"
                     predictor="quadratic"/>
      </ssc:Annotation>
    </ssd:Annotations>
  </ssd:DefaultExperiment>
</ssd:SystemStructureDescription>
"""


def test_every_shipped_archive_is_valid_ssp_for_fmpy(built):
    archives = sorted(built["ssp"].glob("*.ssp"))
    assert {"spring_mass_linear.ssp", "spring_mass_nonlinear.ssp", "chain_10.ssp",
            "chain_100.ssp"} <= {a.name for a in archives}
    for archive in archives:
        system = read_ssd(str(archive), validate=True)
        assert system.system.elements
        with zipfile.ZipFile(archive) as content:
            assert all(name in content.namelist() for name in
                       {e.source for e in system.system.elements if hasattr(e, "source")})


def test_nested_systems_inline_parameters_and_annotations(tmp_path, built):
    folder = tmp_path / "scene"
    (folder / "resources").mkdir(parents=True)
    (folder / "resources" / "SpringMass.fmu").write_bytes(
        (built["fmus"] / "SpringMass.fmu").read_bytes())
    (folder / "SystemStructure.ssd").write_text(NESTED)
    scene = load_scene(folder)
    assert [c.path for c in scene.components] == ["left", "sub.a", "sub.b"]
    assert scene.component("left").parameters == {"m[1]": ("Real", 10.0), "n": ("Integer", 1)}
    inner, outer = scene.joints
    assert inner.name == "sub.inner" and inner.a == ("sub.a", "Q") and inner.b == ("sub.b", "P")
    assert outer.a == ("left", "P") and outer.b == ("sub.a", "P")
    assert outer.kind == "flexible" and outer.measure == "penalized"
    assert (outer.k0, outer.c0, outer.xi, outer.omega, outer.support) == (
        (100.0,), (1.5,), 0.7, 30.0, 1.5)
    connection, = scene.connections
    assert connection.start == ("sub.a", "x[1]") and connection.end == ("sub.b", "P.f_x")
    step, = connection.transformations
    assert (step.kind, step.factor, step.offset) == ("linear", 2.0, 1.0)
    assert (scene.start_time, scene.stop_time) == (0.5, 2.0)
    assert (scene.master.step, scene.master.max_iterations, scene.master.predictor) == (
        0.02, 7, "quadratic")


def test_info_lists_components_capabilities_ports_joints_and_settings(built, capsys):
    assert main(["info", str(built["ssp"] / "spring_mass_nonlinear.ssp")]) == 0
    text = capsys.readouterr().out
    for expected in ("step 0.01 s (from glue:Master), tolerance 1e-10", "left: SpringMass.fmu",
                     "state yes", "ports: P(x), Q(x)", "j1: left.P -> right.Q dofs x, flexible"):
        assert expected in text


def test_build_skips_what_is_up_to_date(built):
    from dsim.build_fmus.build import build_fmus, pack_scenes

    messages = []
    build_fmus(log=messages.append)
    pack_scenes(log=messages.append)
    assert messages == []
