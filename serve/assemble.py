"""New scenes from stored FMUs, and new parameter sets for stored scenes, written
as standard SSP 1.0 files with dsim's annotation (docs/annotation.md).

What a user typed goes into XML attributes and values only: every file in an
archive written here is named by the FMU's sha256 or by a counter, so no
user-given name becomes a path, not even inside an archive that dsim unpacks.
The archives are then checked exactly as an upload is (``dsim validate``'s
checks), so a scene that is saved is a scene that ``dsim run`` runs.
"""
from __future__ import annotations

import zipfile
from dataclasses import dataclass, field
from pathlib import Path

from lxml import etree

SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
GLUE = "urn:dsim:gluing:1"
#: the ssc:Annotation types of dsim's annotation (docs/annotation.md): names in the SSP
#: files, not Python modules (serve/ imports the public dsim only, never the master's)
GLUING_TYPE, MASTER_TYPE = "org.dsim.gluing", "org.dsim.master"

#: SSV element for a value of each FMI type (an Enumeration is set by its number)
SSV_TYPES = {"Real": "Real", "Integer": "Integer", "Enumeration": "Integer",
             "Boolean": "Boolean", "String": "String"}
#: experiment fields of the form -> glue:Master attributes
MASTER_ATTRIBUTES = {"step": "step", "tolerance": "tolerance",
                     "max_iterations": "maxIterations", "predictor": "predictor",
                     "refresh_after": "refreshAfter", "coupling": "coupling"}


def _q(namespace: str, tag: str) -> str:
    return f"{{{namespace}}}{tag}"


def typed_value(kind: str, text: str) -> str:
    """The SSV text of a value typed into a form for a variable of FMI type ``kind``
    (ValueError saying what is wrong)."""
    text = text.strip()
    if kind == "Real":
        value = float(text)
        if value != value or abs(value) == float("inf"):
            raise ValueError(f"'{text}' is not a finite number")
        return repr(value)
    if kind in ("Integer", "Enumeration"):
        return str(int(text))
    if kind == "Boolean":
        lowered = text.lower()
        if lowered not in ("true", "false", "1", "0"):
            raise ValueError(f"'{text}' is not true or false")
        return "true" if lowered in ("true", "1") else "false"
    return text


def parameter_set(name: str, values: list[tuple[str, str, str]]) -> etree._Element:
    """An ssv:ParameterSet of (name, FMI type, SSV text) triples."""
    root = etree.Element(_q(SSV, "ParameterSet"), nsmap={"ssv": SSV}, version="1.0",
                         name=name)
    parameters = etree.SubElement(root, _q(SSV, "Parameters"))
    for key, kind, text in values:
        parameter = etree.SubElement(parameters, _q(SSV, "Parameter"), name=key)
        etree.SubElement(parameter, _q(SSV, SSV_TYPES.get(kind, "Real")), value=text)
    return root


@dataclass
class ComponentSpec:
    """One component of a scene to assemble: its name, stored FMU (sha256, path in
    the archive) and parameters as (name, FMI type, SSV text)."""

    name: str
    fmu_sha256: str
    parameters: list = field(default_factory=list)
    #: (variable, FMI type) of the outputs to record; none: dsim records every output
    outputs: list = field(default_factory=list)

    @property
    def member(self) -> str:
        return f"resources/{self.fmu_sha256[:16]}.fmu"


@dataclass
class SceneSpec:
    """A scene to assemble: components, causal connections ((component, variable)
    pairs), joints (dicts of glue:Joint attributes and law), port maps of FMUs whose
    variables are not named as dsim's ports are, the experiment."""

    name: str
    description: str = ""
    components: list = field(default_factory=list)
    connections: list = field(default_factory=list)
    joints: list = field(default_factory=list)
    #: glue:Port maps (dicts of its attributes: component, name, dofs, force, ...)
    ports: list = field(default_factory=list)
    start: float = 0.0
    stop: float = 1.0
    master: dict = field(default_factory=dict)


def _component(elements, spec: ComponentSpec) -> None:
    element = etree.SubElement(elements, _q(SSD, "Component"), name=spec.name,
                               type="application/x-fmu-sharedlibrary", source=spec.member)
    if spec.outputs:
        connectors = etree.SubElement(element, _q(SSD, "Connectors"))
        for variable, kind in spec.outputs:
            connector = etree.SubElement(connectors, _q(SSD, "Connector"), name=variable,
                                         kind="output")
            etree.SubElement(connector, _q(SSC, SSV_TYPES.get(kind, "Real")))
    if spec.parameters:
        binding = etree.SubElement(etree.SubElement(element, _q(SSD, "ParameterBindings")),
                                   _q(SSD, "ParameterBinding"))
        values = etree.SubElement(binding, _q(SSD, "ParameterValues"))
        values.append(parameter_set(spec.name, spec.parameters))


def _joint(gluing, joint: dict) -> None:
    element = etree.SubElement(gluing, _q(GLUE, "Joint"), name=joint["name"], a=joint["a"],
                               b=joint["b"], dofs=joint["dofs"], kind=joint["kind"],
                               measure=joint["measure"])
    for tag, keys in (("Spring", ("k0", "k1")), ("Damper", ("c0", "c1")),
                      ("Penalty", ("xi", "omega"))):
        law = {k: joint[k] for k in keys if joint.get(k)}
        if law:
            etree.SubElement(element, _q(GLUE, tag), law)


def system_structure(spec: SceneSpec) -> bytes:
    """SystemStructure.ssd of an assembled scene."""
    root = etree.Element(_q(SSD, "SystemStructureDescription"),
                         nsmap={"ssd": SSD, "ssc": SSC, "ssv": SSV}, version="1.0",
                         name=spec.name, description=spec.description)
    system = etree.SubElement(root, _q(SSD, "System"), name="root")
    elements = etree.SubElement(system, _q(SSD, "Elements"))
    for component in spec.components:
        _component(elements, component)
    if spec.connections:
        connections = etree.SubElement(system, _q(SSD, "Connections"))
        for (start, output), (end, input_) in spec.connections:
            etree.SubElement(connections, _q(SSD, "Connection"), startElement=start,
                             startConnector=output, endElement=end, endConnector=input_)
    if spec.joints or spec.ports:
        annotation = etree.SubElement(etree.SubElement(system, _q(SSD, "Annotations")),
                                      _q(SSC, "Annotation"), type=GLUING_TYPE)
        gluing = etree.SubElement(annotation, _q(GLUE, "Gluing"), nsmap={"glue": GLUE})
        for joint in spec.joints:
            _joint(gluing, joint)
        for port in spec.ports:
            etree.SubElement(gluing, _q(GLUE, "Port"), {k: v for k, v in port.items() if v})
    experiment = etree.SubElement(root, _q(SSD, "DefaultExperiment"),
                                  startTime=repr(float(spec.start)),
                                  stopTime=repr(float(spec.stop)))
    if spec.master:
        annotation = etree.SubElement(etree.SubElement(experiment, _q(SSD, "Annotations")),
                                      _q(SSC, "Annotation"), type=MASTER_TYPE)
        etree.SubElement(annotation, _q(GLUE, "Master"),
                         {MASTER_ATTRIBUTES[k]: str(v) for k, v in spec.master.items()},
                         nsmap={"glue": GLUE})
    return etree.tostring(root, pretty_print=True, xml_declaration=True, encoding="UTF-8")


def write_scene(spec: SceneSpec, fmu_files: dict, target: Path) -> Path:
    """Pack an assembled scene: SystemStructure.ssd and each FMU once (``fmu_files``:
    sha256 -> stored file)."""
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("SystemStructure.ssd", system_structure(spec))
        for component in {c.member: c for c in spec.components}.values():
            archive.write(fmu_files[component.fmu_sha256], component.member)
    return target


def add_parameter_set(source: Path, name: str, values: list, target: Path) -> str:
    """Copy the scene archive ``source`` to ``target`` with one more .ssv file holding
    ``values`` ((root-relative name, FMI type, SSV text)); the new file's path in the
    archive (``resources/parameters_<n>.ssv``, the first free n)."""
    with zipfile.ZipFile(source) as old, zipfile.ZipFile(target, "w",
                                                         zipfile.ZIP_DEFLATED) as new:
        names = set(old.namelist())
        n = 1
        while f"resources/parameters_{n}.ssv" in names:
            n += 1
        member = f"resources/parameters_{n}.ssv"
        for info in old.infolist():
            new.writestr(info, old.read(info))
        new.writestr(member, etree.tostring(parameter_set(name, values), pretty_print=True,
                                            xml_declaration=True, encoding="UTF-8"))
    return member
