"""The scenes several test modules share: a C block alone, the C oscillator glued to
SpringMass, the shipped chain, spring_mass_linear edited or with placements, an .ssp of
the C test models of every kind (third_party/kinds), and a scene without components."""
from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

from tests.support.scene_files import component, scene_folder, ssd


def block_scene(folder: Path, fmu: Path, stop: float = 0.2, **parameters) -> Path:
    """One C block on its own (u unconnected), with ``parameters``."""
    text = ssd("block", [component("b1", "resources/block.fmu", parameters, outputs=["y"])],
               stop=stop, master='step="0.001"')
    return scene_folder(folder, text, {"block.fmu": fmu})


def archive_with(tmp_path, built, replace=(), drop=()):
    """A copy of spring_mass_linear.ssp with text replaced in its SSD."""
    source = built["ssp"] / "spring_mass_linear.ssp"
    target = tmp_path / "edited.ssp"
    with zipfile.ZipFile(source) as old, zipfile.ZipFile(target, "w") as new:
        for name in old.namelist():
            if name in drop:
                continue
            data = old.read(name)
            if name == "SystemStructure.ssd":
                text = data.decode()
                for before, after in replace:
                    assert before in text
                    text = text.replace(before, after)
                data = text.encode()
            new.writestr(name, data)
    return target


def placed_scene(built, folder: Path, placements: str) -> Path:
    """spring_mass_linear unpacked, with ``placements`` added to its glue:Gluing."""
    with zipfile.ZipFile(built["ssp"] / "spring_mass_linear.ssp") as archive:
        archive.extractall(folder)
    ssd_file = folder / "SystemStructure.ssd"
    text = ssd_file.read_text()
    assert text.count("</glue:Gluing>") == 1
    ssd_file.write_text(text.replace("</glue:Gluing>", placements + "</glue:Gluing>"))
    return folder


def chain_scene(folder, built, n: int):
    """The shipped chain of ``n`` SpringMass FMUs as a scene folder."""
    from dsim.build_fmus.scenes import CHAIN, chain

    chain(n).write(folder, 0.0, CHAIN["stop"], step=CHAIN["step"])
    (folder / "resources").mkdir(exist_ok=True)
    shutil.copy(built["fmus"] / "SpringMass.fmu", folder / "resources" / "SpringMass.fmu")
    return folder


#: the C oscillator (third_party/oscillator.c) glued to dsim's SpringMass through a
#: glue:Port map of its own variable names
OSCILLATOR_SCENE = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="third_party"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">
  <ssd:System name="root">
    <ssd:Elements>
      <ssd:Component name="third" source="resources/oscillator.fmu">
        <ssd:Connectors><ssd:Connector name="s" kind="output"><ssc:Real/></ssd:Connector></ssd:Connectors>
        <ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>
          <ssv:ParameterSet version="1.0" name="third"><ssv:Parameters>
            <ssv:Parameter name="m"><ssv:Real value="2"/></ssv:Parameter>
            <ssv:Parameter name="k"><ssv:Real value="300"/></ssv:Parameter>
            <ssv:Parameter name="s0"><ssv:Real value="0.01"/></ssv:Parameter>
          </ssv:Parameters></ssv:ParameterSet>
        </ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>
      </ssd:Component>
      <ssd:Component name="mass" source="resources/SpringMass.fmu">
        <ssd:Connectors><ssd:Connector name="x[1]" kind="output"><ssc:Real/></ssd:Connector></ssd:Connectors>
        <ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>
          <ssv:ParameterSet version="1.0" name="mass"><ssv:Parameters>
            <ssv:Parameter name="m[1]"><ssv:Real value="3"/></ssv:Parameter>
            <ssv:Parameter name="k_ground[1]"><ssv:Real value="200"/></ssv:Parameter>
            <ssv:Parameter name="x0[1]"><ssv:Real value="0.01"/></ssv:Parameter>
            <ssv:Parameter name="Fa[1]"><ssv:Real value="5"/></ssv:Parameter>
            <ssv:Parameter name="omega[1]"><ssv:Real value="7"/></ssv:Parameter>
          </ssv:Parameters></ssv:ParameterSet>
        </ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>
      </ssd:Component>
    </ssd:Elements>
    <ssd:Annotations>
      <ssc:Annotation type="org.dsim.gluing">
        <glue:Gluing xmlns:glue="urn:dsim:gluing:1">
          <glue:Port component="third" name="P" dofs="x" force="F_in" position="s"
                     velocity="v" acceleration="a"/>
          <glue:Joint name="j" a="third.P" b="mass.P" dofs="x"/>
        </glue:Gluing>
      </ssc:Annotation>
    </ssd:Annotations>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="2">
    <ssd:Annotations><ssc:Annotation type="org.dsim.master">
      <glue:Master xmlns:glue="urn:dsim:gluing:1" step="0.005" tolerance="1e-13"/>
    </ssc:Annotation></ssd:Annotations>
  </ssd:DefaultExperiment>
</ssd:SystemStructureDescription>
"""


def oscillator_scene(folder: Path, built, c_fmu: Path) -> Path:
    """OSCILLATOR_SCENE as a folder, with the C oscillator ``c_fmu`` and SpringMass."""
    (folder / "resources").mkdir(parents=True)
    shutil.copy(c_fmu, folder / "resources" / "oscillator.fmu")
    shutil.copy(built["fmus"] / "SpringMass.fmu", folder / "resources" / "SpringMass.fmu")
    (folder / "SystemStructure.ssd").write_text(OSCILLATOR_SCENE)
    return folder


def archive_scene(path: Path, components: dict, connections=(), stop=2.0, step=0.01,
                  master="", gluing="", units="") -> Path:
    """An .ssp of ``components`` (name -> (fmu, implementation, extra XML inside the
    component)), ``connections`` ((start, connector, end, connector)), a Master
    annotation (``master``: extra attributes) and a gluing annotation."""
    elements = "".join(
        f'<ssd:Component name="{name}" source="resources/{name}.fmu"'
        + (f' implementation="{impl}"' if impl else "") + f">{inside}</ssd:Component>"
        for name, (_, impl, inside) in components.items())
    links = "".join(f'<ssd:Connection startElement="{a}" startConnector="{ac}" '
                    f'endElement="{b}" endConnector="{bc}"/>' for a, ac, b, bc in connections)
    annotations = (f'<ssd:Annotations><ssc:Annotation type="org.dsim.gluing">'
                   f'<glue:Gluing xmlns:glue="urn:dsim:gluing:1">{gluing}</glue:Gluing>'
                   "</ssc:Annotation></ssd:Annotations>") if gluing else ""
    ssd = f"""<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="{path.stem}"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon">
  <ssd:System name="root"><ssd:Elements>{elements}</ssd:Elements>
    {f"<ssd:Connections>{links}</ssd:Connections>" if links else ""}{annotations}</ssd:System>
  {units}
  <ssd:DefaultExperiment startTime="0" stopTime="{stop}"><ssd:Annotations>
    <ssc:Annotation type="org.dsim.master"><glue:Master xmlns:glue="urn:dsim:gluing:1"
      step="{step}" {master}/></ssc:Annotation></ssd:Annotations></ssd:DefaultExperiment>
</ssd:SystemStructureDescription>"""
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("SystemStructure.ssd", ssd)
        for name, (fmu, _, _) in components.items():
            archive.write(fmu, f"resources/{name}.fmu")
    return path


#: a scene without FMU components: system connectors and a parameter set only (a
#: parameter setup exported alone)
EMPTY_SSD = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="setup"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">
  <ssd:System name="root">
    <ssd:Connectors>
      <ssd:Connector name="k" kind="parameter"><ssc:Real/></ssd:Connector>
    </ssd:Connectors>
    <ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>
      <ssv:ParameterSet version="1.0" name="p"><ssv:Parameters>
        <ssv:Parameter name="k"><ssv:Real value="2.5"/></ssv:Parameter>
      </ssv:Parameters></ssv:ParameterSet>
    </ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="0.5"/>
</ssd:SystemStructureDescription>
"""

