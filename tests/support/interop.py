"""SSD parts as other tools write them (SSP 1.0): a scene folder around an ssd:System,
components, inline parameter sets and bindings, connections, connectors, and a fake FMU
of a description alone."""
from __future__ import annotations

import html
import shutil
import zipfile

HEADER = ('<?xml version="1.0" encoding="UTF-8"?>\n<ssd:SystemStructureDescription '
          'version="1.0" name="interop" '
          'xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" '
          'xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" '
          'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" '
          'xmlns:ssm="http://ssp-standard.org/SSP1/SystemStructureParameterMapping">')
EXPERIMENT = ('<ssd:DefaultExperiment startTime="0" stopTime="{stop}"><ssd:Annotations>'
              '<ssc:Annotation type="org.dsim.master"><glue:Master '
              'xmlns:glue="urn:dsim:gluing:1" step="0.001"/></ssc:Annotation>'
              '</ssd:Annotations></ssd:DefaultExperiment>')


def write_scene(folder, system: str, fmus: dict, stop: float = 0.05, units: str = "",
                files: dict | None = None, experiment: bool = True):
    """A scene folder: the SSD around ``system`` (an ssd:System element), its FMUs
    in resources/, and other ``files`` (path -> text)."""
    (folder / "resources").mkdir(parents=True, exist_ok=True)
    for name, path in fmus.items():
        shutil.copy(path, folder / "resources" / name)
    for name, text in (files or {}).items():
        (folder / name).write_text(text)
    (folder / "SystemStructure.ssd").write_text(
        HEADER + system + units + (EXPERIMENT.format(stop=stop) if experiment else "")
        + "</ssd:SystemStructureDescription>")
    return folder


def block(name: str, source: str = "resources/block.fmu", inside: str = "") -> str:
    return f'<ssd:Component name="{name}" source="{source}">{inside}</ssd:Component>'


def values(**parameters) -> str:
    """An inline ssv:ParameterSet (Real, Integer or Boolean by the Python type)."""
    rows = []
    for key, value in parameters.items():
        kind = ("Boolean" if isinstance(value, bool) else "Integer" if isinstance(value, int)
                else "String" if isinstance(value, str) else "Real")
        text = (str(value).lower() if isinstance(value, bool)
                else html.escape(value) if isinstance(value, str) else repr(value))
        rows.append(f'<ssv:Parameter name="{key}"><ssv:{kind} value="{text}"/></ssv:Parameter>')
    return ('<ssv:ParameterSet version="1.0" name="set"><ssv:Parameters>' + "".join(rows)
            + "</ssv:Parameters></ssv:ParameterSet>")


def binding(prefix: str = "", **parameters) -> str:
    attribute = f' prefix="{prefix}"' if prefix else ""
    return (f"<ssd:ParameterBinding{attribute}><ssd:ParameterValues>{values(**parameters)}"
            "</ssd:ParameterValues></ssd:ParameterBinding>")


def connection(start, start_connector, end, end_connector, inside: str = "",
               attributes: str = "") -> str:
    ends = ((f'startElement="{start}" ' if start else "") + f'startConnector="{start_connector}" '
            + (f'endElement="{end}" ' if end else "") + f'endConnector="{end_connector}"')
    return f"<ssd:Connection {ends}{attributes}>{inside}</ssd:Connection>"


def system(elements: str, connections: str = "", inside: str = "", name: str = "root") -> str:
    links = f"<ssd:Connections>{connections}</ssd:Connections>" if connections else ""
    return (f'<ssd:System name="{name}">{inside}<ssd:Elements>{elements}</ssd:Elements>'
            f"{links}</ssd:System>")


def connectors(*specs) -> str:
    """ssd:Connectors of (name, kind, type, unit or None) tuples."""
    rows = []
    for name, kind, kind_type, unit in specs:
        unit_attribute = f' unit="{unit}"' if unit else ""
        rows.append(f'<ssd:Connector name="{name}" kind="{kind}"><ssc:{kind_type}'
                    f"{unit_attribute}/></ssd:Connector>")
    return "<ssd:Connectors>" + "".join(rows) + "</ssd:Connectors>"


def fake_fmu(path, description: str):
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("modelDescription.xml", description)
    return path

