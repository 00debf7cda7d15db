"""Read an SSP 1.0 system (.ssp archive, unpacked folder or .ssd file) into
immutable dataclasses: components with their parameter bindings, causal
connections, the dsim gluing annotation (joints, port maps) and the master
settings.  Nested ``ssd:System`` elements are flattened into dotted paths.

Every problem found is collected and raised together as one
:class:`~master.errors.InputError`, one line per problem, before anything is
instantiated.
"""
from __future__ import annotations

import atexit
import math
import shutil
import tempfile
import zipfile
from functools import lru_cache
from pathlib import Path

from lxml import etree

from master.errors import InputError
from master.scene import (DOFS, MEASURES, Component, Connection, Joint, MasterSettings,
                          PortMap, Scene)
from master.settings import settings_from_annotation

NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "glue": "urn:dsim:gluing:1",
}
GLUE = "{urn:dsim:gluing:1}"


_EXTRACTED: list[str] = []


@atexit.register
def _clean_extracted() -> None:
    for folder in _EXTRACTED:
        shutil.rmtree(folder, ignore_errors=True)


def _open(path: Path) -> tuple[Path, str]:
    """The SystemStructure.ssd to read and the name used in messages."""
    if not path.exists():
        raise InputError(f"{path}: no such file")
    if path.is_dir():
        ssd = path / "SystemStructure.ssd"
        if not ssd.is_file():
            raise InputError(f"{path}: folder has no SystemStructure.ssd")
        return ssd, str(path)
    if path.suffix.lower() == ".ssd":
        return path, str(path)
    if not zipfile.is_zipfile(path):
        raise InputError(f"{path}: not an SSP archive (not a zip file)")
    with zipfile.ZipFile(path) as archive:
        if "SystemStructure.ssd" not in archive.namelist():
            raise InputError(f"{path}: archive has no SystemStructure.ssd at its root")
        folder = tempfile.mkdtemp(prefix="dsim-ssp-")
        _EXTRACTED.append(folder)
        try:
            archive.extractall(folder)
        except (OSError, zipfile.BadZipFile, EOFError) as error:
            raise InputError(f"{path}: cannot extract the archive: "
                             f"{getattr(error, 'strerror', None) or error}") from None
    return Path(folder) / "SystemStructure.ssd", str(path)


def _parse_xml(path: Path, shown: str):
    try:
        return etree.parse(str(path)).getroot()
    except etree.XMLSyntaxError as error:
        raise InputError(f"{shown}: malformed XML: {error}") from None
    except OSError as error:
        raise InputError(f"{shown}: cannot read: {error}") from None


@lru_cache(maxsize=4)
def _schema(schema_name: str) -> etree.XMLSchema:
    """An SSP 1.0 schema that fmpy ships (parsed once)."""
    import fmpy.ssp.ssd as fmpy_ssd

    return etree.XMLSchema(file=str(Path(fmpy_ssd.__file__).parent / "schema" / schema_name))


def _schema_problems(root, shown: str, schema_name: str) -> list[str]:
    """Problems against the SSP 1.0 schema that fmpy ships."""
    schema = _schema(schema_name)
    if schema.validate(root):
        return []
    return [f"{shown} line {e.line}: not valid SSP 1.0: {e.message}"
            for e in list(schema.error_log)[:3]]


def _floats(text: str | None, n: int, default: float, where: str, problems: list) -> tuple:
    """A space-separated list broadcast to n entries (one value serves all)."""
    if text is None:
        return (default,) * n
    try:
        values = [float(v) for v in text.split()]
    except ValueError:
        problems.append(f"{where}: '{text}' is not a number or list of numbers")
        return (default,) * n
    if len(values) == 1:
        values *= n
    if len(values) != n or not all(math.isfinite(v) for v in values):
        problems.append(f"{where}: expected 1 or {n} finite values, got '{text}'")
        return (default,) * n
    return tuple(values)


class _Reader:
    """Walks one SystemStructure.ssd, collecting problems instead of stopping."""

    def __init__(self, ssd: Path, shown: str):
        self.ssd = ssd
        self.base = ssd.parent
        self.shown = shown
        self.problems: list[str] = []
        self.components: list[Component] = []
        self.connections: list[Connection] = []
        self.joints: list[Joint] = []
        self.port_maps: list[PortMap] = []
        self.files: list[Path] = [ssd]

    def where(self, element) -> str:
        tag = etree.QName(element).localname
        name = element.get("name")
        label = f"{tag} '{name}'" if name else tag
        return f"{self.shown} (SystemStructure.ssd line {element.sourceline}): {label}"

    # --- parameters ------------------------------------------------------------
    def parameter_values(self, binding, where: str) -> dict:
        source = binding.get("source")
        if source:
            file = self.base / source
            if not file.is_file():
                self.problems.append(f"{where}: parameter file '{source}' not found")
                return {}
            self.files.append(file)
            try:
                root = etree.parse(str(file)).getroot()
            except etree.XMLSyntaxError as error:
                self.problems.append(f"{self.shown}: {source}: malformed XML: {error}")
                return {}
            self.problems += _schema_problems(root, f"{self.shown}: {source}",
                                              "SystemStructureParameterValues.xsd")
        else:
            root = binding.find("ssd:ParameterValues/ssv:ParameterSet", NS)
            if root is None:
                return {}
        prefix = binding.get("prefix", "")
        values = {}
        for parameter in root.iterfind(".//ssv:Parameter", NS):
            name = parameter.get("name", "")
            if prefix and name.startswith(prefix):
                name = name[len(prefix):]
            for child in parameter:
                kind = etree.QName(child).localname
                text = child.get("value")
                try:
                    if kind == "Real":
                        values[name] = ("Real", float(text))
                    elif kind in ("Integer", "Enumeration"):
                        values[name] = ("Integer", int(text))
                    elif kind == "Boolean":
                        values[name] = ("Boolean", text in ("true", "1"))
                    elif kind == "String":
                        values[name] = ("String", text or "")
                except (TypeError, ValueError):
                    self.problems.append(
                        f"{where}: parameter '{name}' has bad {kind} value '{text}'")
        return values

    # --- systems ---------------------------------------------------------------
    def system(self, element, prefix: str) -> None:
        for child in element.iterfind("ssd:Elements/*", NS):
            tag = etree.QName(child).localname
            name = child.get("name", "")
            if tag == "System":
                self.system(child, prefix + name + ".")
            elif tag == "Component":
                self.component(child, prefix)
            else:
                self.problems.append(f"{self.where(child)}: element kind '{tag}' not supported")
        for connection in element.iterfind("ssd:Connections/ssd:Connection", NS):
            self.connection(connection, prefix)
        for gluing in element.iterfind(
                "ssd:Annotations/ssc:Annotation[@type='org.dsim.gluing']/glue:Gluing", NS):
            for joint in gluing.iterfind("glue:Joint", NS):
                self.joint(joint, prefix)
            for port in gluing.iterfind("glue:Port", NS):
                self.port_map(port, prefix)

    def component(self, element, prefix: str) -> None:
        where = self.where(element)
        source = element.get("source", "")
        kind = element.get("type", "application/x-fmu-sharedlibrary")
        if kind != "application/x-fmu-sharedlibrary":
            self.problems.append(f"{where}: type '{kind}' is not an FMU")
            return
        file = self.base / source
        if not source or not file.is_file():
            self.problems.append(f"{where}: FMU '{source}' not found")
        parameters = {}
        for binding in element.iterfind("ssd:ParameterBindings/ssd:ParameterBinding", NS):
            parameters.update(self.parameter_values(binding, where))
        connectors = tuple((c.get("name"), c.get("kind"))
                           for c in element.iterfind("ssd:Connectors/ssd:Connector", NS))
        self.components.append(Component(prefix + element.get("name", ""), file,
                                          parameters, connectors, where))

    def connection(self, element, prefix: str) -> None:
        where = f"{self.shown} (SystemStructure.ssd line {element.sourceline}): Connection"
        start, end = element.get("startElement"), element.get("endElement")
        if not start or not end:
            self.problems.append(f"{where}: connections to system connectors are not supported")
            return
        factor, offset = 1.0, 0.0
        linear = element.find("ssc:LinearTransformation", NS)
        if linear is not None:
            factor = float(linear.get("factor", 1.0))
            offset = float(linear.get("offset", 0.0))
        self.connections.append(Connection(
            (prefix + start, element.get("startConnector")),
            (prefix + end, element.get("endConnector")), factor, offset, where))

    def _port_ref(self, text: str | None, where: str, prefix: str):
        if not text or "." not in text:
            self.problems.append(f"{where}: port reference '{text}' is not 'component.port'")
            return ("", "")
        component, port = text.rsplit(".", 1)
        return (prefix + component, port)

    def joint(self, element, prefix: str) -> None:
        where = self.where(element)
        dofs = tuple((element.get("dofs") or "").split())
        if not dofs or any(d not in DOFS for d in dofs):
            self.problems.append(f"{where}: dofs '{element.get('dofs')}' must be a list of {DOFS}")
            dofs = dofs or ("x",)
        kind = element.get("kind", "fixed")
        if kind not in ("fixed", "flexible"):
            self.problems.append(f"{where}: kind '{kind}' must be fixed or flexible")
        measure = element.get("measure", "displacement")
        if measure not in MEASURES:
            self.problems.append(f"{where}: measure '{measure}' must be one of {MEASURES}")
        n = len(dofs)
        spring = element.find("glue:Spring", NS)
        damper = element.find("glue:Damper", NS)
        values = {}
        for key, node in (("k0", spring), ("k1", spring), ("c0", damper), ("c1", damper)):
            text = node.get(key) if node is not None else None
            values[key] = _floats(text, n, 0.0, f"{where}: {key}", self.problems)
        if kind == "flexible" and spring is None:
            self.problems.append(f"{where}: a flexible joint needs a glue:Spring")
        xi, omega = 1.0, 0.0
        penalty = element.find("glue:Penalty", NS)
        if measure == "penalized":
            if penalty is None:
                self.problems.append(f"{where}: measure 'penalized' needs a glue:Penalty")
            else:
                xi = _floats(penalty.get("xi"), 1, 1.0, f"{where}: xi", self.problems)[0]
                omega = _floats(penalty.get("omega"), 1, 0.0, f"{where}: omega",
                                self.problems)[0]
        support = _floats(element.get("support"), 1, 1.0, f"{where}: support",
                          self.problems)[0]
        if not support > 0:
            self.problems.append(f"{where}: support must be positive")
        self.joints.append(Joint(
            name=prefix + element.get("name", ""),
            a=self._port_ref(element.get("a"), where, prefix),
            b=self._port_ref(element.get("b"), where, prefix),
            dofs=dofs, kind=kind, measure=measure, xi=xi, omega=omega,
            support=support, location=where, **values))

    def port_map(self, element, prefix: str) -> None:
        where = self.where(element)
        dofs = tuple((element.get("dofs") or "").split())

        def names(attribute, required=True):
            text = element.get(attribute)
            if text is None:
                if required:
                    self.problems.append(f"{where}: attribute '{attribute}' missing")
                return None
            listed = tuple(text.split())
            if len(listed) != len(dofs):
                self.problems.append(f"{where}: '{attribute}' names {len(listed)} variables "
                                     f"for {len(dofs)} dofs")
            return listed

        self.port_maps.append(PortMap(
            prefix + element.get("component", ""), element.get("name", ""), dofs,
            names("force"), names("position"), names("velocity", False),
            names("acceleration", False), where))


def _master_settings(root, shown: str, problems: list) -> tuple[float, float, MasterSettings]:
    experiment = root.find("ssd:DefaultExperiment", NS)
    start, stop = 0.0, 1.0
    attributes = {}
    if experiment is not None:
        where = f"{shown}: DefaultExperiment"
        start = _floats(experiment.get("startTime"), 1, 0.0, f"{where}: startTime", problems)[0]
        stop = _floats(experiment.get("stopTime"), 1, 1.0, f"{where}: stopTime", problems)[0]
        node = experiment.find(
            "ssd:Annotations/ssc:Annotation[@type='org.dsim.master']/glue:Master", NS)
        if node is not None:
            attributes = dict(node.attrib)
    return start, stop, settings_from_annotation(attributes, f"{shown}: glue:Master", problems)


def load_scene(path) -> Scene:
    """Read and check an SSP system; raise InputError listing every problem."""
    path = Path(path)
    ssd, shown = _open(path)
    root = _parse_xml(ssd, shown)
    if etree.QName(root).localname != "SystemStructureDescription":
        raise InputError(f"{shown}: SystemStructure.ssd: root element is "
                         f"'{etree.QName(root).localname}', not ssd:SystemStructureDescription")
    reader = _Reader(ssd, shown)
    reader.problems += _schema_problems(root, shown, "SystemStructureDescription.xsd")
    system = root.find("ssd:System", NS)
    if system is None:
        raise InputError(reader.problems or [f"{shown}: SystemStructure.ssd has no ssd:System"])
    reader.system(system, "")
    start, stop, master = _master_settings(root, shown, reader.problems)
    _check_references(reader)
    if reader.problems:
        raise InputError(reader.problems)
    name = root.get("name") or path.stem
    return Scene(name, path, start, stop, tuple(reader.components),
                 tuple(reader.connections), tuple(reader.joints),
                 tuple(reader.port_maps), master, tuple(reader.files))


def _check_references(reader: _Reader) -> None:
    """Joints, port maps and connections must name components that exist."""
    paths = {c.path for c in reader.components}
    for component in reader.components:
        if sum(c.path == component.path for c in reader.components) > 1:
            reader.problems.append(f"{component.location}: component name used twice")
    seen = set()
    for joint in reader.joints:
        if joint.name in seen:
            reader.problems.append(f"{joint.location}: joint name used twice")
        seen.add(joint.name)
        for side in (joint.a, joint.b):
            if side[0] and side[0] not in paths:
                reader.problems.append(f"{joint.location}: unknown component '{side[0]}'")
        if joint.a == joint.b:
            reader.problems.append(f"{joint.location}: joins port {joint.a[0]}.{joint.a[1]} "
                                   "to itself")
    for port in reader.port_maps:
        if port.component not in paths:
            reader.problems.append(f"{port.location}: unknown component '{port.component}'")
    for connection in reader.connections:
        for side in (connection.start, connection.end):
            if side[0] not in paths:
                reader.problems.append(f"{connection.location}: unknown component '{side[0]}'")
