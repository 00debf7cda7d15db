"""Small scene files written by tests: an SSD from components, connections and
annotations, packed into an .ssp or left as a folder."""
from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

HEADER = ('<ssd:SystemStructureDescription version="1.0" name="{name}" '
          'xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" '
          'xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" '
          'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">')


def component(name: str, source: str, parameters: dict | None = None,
              outputs=(), inputs=()) -> str:
    """An ssd:Component with inline Real/Integer/Boolean parameters and connectors."""
    connectors = "".join(f'<ssd:Connector name="{n}" kind="output"><ssc:Real/></ssd:Connector>'
                         for n in outputs)
    connectors += "".join(f'<ssd:Connector name="{n}" kind="input"><ssc:Real/></ssd:Connector>'
                          for n in inputs)
    values = ""
    for key, value in (parameters or {}).items():
        kind = ("Boolean" if isinstance(value, bool) else "Integer" if isinstance(value, int)
                else "Real")
        text = str(value).lower() if isinstance(value, bool) else repr(value)
        values += f'<ssv:Parameter name="{key}"><ssv:{kind} value="{text}"/></ssv:Parameter>'
    bindings = ("<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>"
                f'<ssv:ParameterSet version="1.0" name="{name}"><ssv:Parameters>{values}'
                "</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>"
                "</ssd:ParameterBinding></ssd:ParameterBindings>") if values else ""
    return (f'<ssd:Component name="{name}" source="{source}">'
            + (f"<ssd:Connectors>{connectors}</ssd:Connectors>" if connectors else "")
            + bindings + "</ssd:Component>")


def ssd(name: str, components, connections=(), gluing: str = "", stop: float = 1.0,
        master: str = 'step="0.01"') -> str:
    """SystemStructure.ssd text; ``connections`` are (start, connector, end, connector)."""
    links = "".join(f'<ssd:Connection startElement="{a}" startConnector="{ac}" '
                    f'endElement="{b}" endConnector="{bc}"/>' for a, ac, b, bc in connections)
    annotations = ('<ssd:Annotations><ssc:Annotation type="org.dsim.gluing">'
                   f'<glue:Gluing xmlns:glue="urn:dsim:gluing:1">{gluing}</glue:Gluing>'
                   "</ssc:Annotation></ssd:Annotations>") if gluing else ""
    return ('<?xml version="1.0" encoding="UTF-8"?>' + HEADER.format(name=name)
            + '<ssd:System name="root"><ssd:Elements>' + "".join(components)
            + "</ssd:Elements>" + (f"<ssd:Connections>{links}</ssd:Connections>" if links else "")
            + annotations + "</ssd:System>"
            + f'<ssd:DefaultExperiment startTime="0" stopTime="{stop!r}"><ssd:Annotations>'
            + '<ssc:Annotation type="org.dsim.master">'
            + f'<glue:Master xmlns:glue="urn:dsim:gluing:1" {master}/>'
            + "</ssc:Annotation></ssd:Annotations></ssd:DefaultExperiment>"
            + "</ssd:SystemStructureDescription>")


def scene_folder(folder: Path, text: str, fmus: dict) -> Path:
    """A scene folder: SystemStructure.ssd and resources/<name> for each FMU."""
    folder = Path(folder)
    (folder / "resources").mkdir(parents=True, exist_ok=True)
    for name, path in fmus.items():
        shutil.copy(path, folder / "resources" / name)
    (folder / "SystemStructure.ssd").write_text(text)
    return folder


def pack(folder: Path, target: Path) -> Path:
    """Zip a scene folder into an .ssp archive."""
    with zipfile.ZipFile(target, "w") as archive:
        for file in sorted(Path(folder).rglob("*")):
            if file.is_file():
                archive.write(file, file.relative_to(folder).as_posix())
    return target


def edited_archive(source: Path, target: Path, member: str, before: str, after: str) -> Path:
    """A copy of the .ssp ``source`` at ``target`` with the first ``before`` in archive
    member ``member`` (which must hold it) replaced by ``after``."""
    with zipfile.ZipFile(source) as old, zipfile.ZipFile(target, "w") as new:
        for name in old.namelist():
            data = old.read(name)
            if name == member:
                assert before.encode() in data, f"{member} has no {before!r}"
                data = data.replace(before.encode(), after.encode(), 1)
            new.writestr(name, data)
    return target
