"""Read an SSP 1.0 system (.ssp archive, unpacked folder or .ssd file) into
immutable dataclasses: components with the parameter values every binding gives
them, causal connections between component variables (resolved through system
connectors across levels), units, the dsim gluing annotation (joints, port maps)
and the master settings.  Nested ``ssd:System`` elements are flattened into
dotted paths.

Every problem found is collected and raised together as one
:class:`~dsim.master.errors.InputError`, one line per problem, before anything is
instantiated.
"""
from __future__ import annotations

import re
import zipfile
from collections import Counter
from functools import lru_cache
from pathlib import Path

import fmpy.ssp.ssd as fmpy_ssd
from lxml import etree

from dsim.master.errors import InputError
from dsim.master.reading.fmu_archive import descriptions
from dsim.master.reading.input_tables import TABLE_TYPES, is_table_file
from dsim.master.reading.scene_files import SCENE_RESOURCES, scene_file
from dsim.master.reading.small_files import parse_untrusted
from dsim.master.reading.ssp_gluing import floats, read_joint, read_placement, read_port_map
from dsim.master.reading.ssp_hierarchy import (Binding, RawConnection, resolve_bindings,
                                               resolve_connections)
from dsim.master.reading.ssp_solver import solver_of
from dsim.master.reading.ssp_tools import tool_step
from dsim.master.reading.ssp_values import (NS, TYPES, apply_mapping, parameter_mapping,
                                            parameter_set, transformation, units)
from dsim.master.reading.unpacking import check_archive, extract
from dsim.master.scene import Component, Connector, MasterSettings, Scene


#: the system structure an SSP archive's root holds by default (SSP 1.0, 5.1)
DEFAULT_SSD = "SystemStructure.ssd"


def _ssd_name(name: str | None) -> str:
    """The .ssd file name asked for (``--ssd``): a plain file name of the scene's root."""
    name = name or DEFAULT_SSD
    if "/" in name or "\\" in name or name in (".", "..") or not name.endswith(".ssd"):
        raise InputError(f"ssd '{name}': give the name of an .ssd file at the scene's root "
                         "(dsim info lists them)")
    return name


def ssd_name_given(path: Path, ssd: Path) -> bool:
    """Whether the user named the .ssd (an .ssd file given, or --ssd)."""
    return path.suffix.lower() == ".ssd" or ssd.name != DEFAULT_SSD


def ssd_files(path) -> list[str]:
    """The .ssd files at the root of a scene archive or folder (an .ssd file: itself)."""
    path = Path(path)
    if path.is_dir():
        return sorted(p.name for p in path.glob("*.ssd") if p.is_file())
    if path.suffix.lower() == ".ssd":
        return [path.name]
    try:
        with zipfile.ZipFile(path) as archive:
            return sorted(n for n in archive.namelist() if "/" not in n and n.endswith(".ssd"))
    except (zipfile.BadZipFile, OSError):
        return []


def _open(path: Path, ssd_name: str | None = None) -> tuple[Path, str]:
    """The .ssd to read (``ssd_name``, default SystemStructure.ssd) and the name used
    in messages."""
    if not path.exists():
        raise InputError(f"{path}: no such file")
    name = _ssd_name(ssd_name)
    if path.is_dir():
        ssd = path / name
        if not ssd.is_file():
            raise InputError(f"{path}: folder has no {name} (it has: "
                             f"{', '.join(ssd_files(path)) or 'no .ssd file'})")
        return ssd, str(path)
    if path.suffix.lower() == ".ssd":
        return path, str(path)
    if not zipfile.is_zipfile(path):
        raise InputError(f"{path}: not an SSP archive (not a zip file)")
    try:
        if name not in check_archive(path, "SSP"):
            raise InputError(f"archive has no {name} at its root (it has: "
                             f"{', '.join(ssd_files(path)) or 'no .ssd file'})")
        # removed at exit, or by the next run when this one is killed (dsim.master.reading.unpacking)
        folder = extract(path, "SSP", "ssp")
    except InputError as error:  # one line that names the file
        raise InputError([f"{path}: {problem}" for problem in error.problems]) from None
    return folder / name, str(path)


def _parse_xml(path: Path, shown: str):
    try:
        return parse_untrusted(str(path))
    except etree.XMLSyntaxError as error:
        raise InputError(f"{shown}: malformed XML: {error}") from None
    except OSError as error:
        raise InputError(f"{shown}: cannot read: {error}") from None


@lru_cache(maxsize=4)
def _schema(schema_name: str) -> etree.XMLSchema:
    """An SSP 1.0 schema that fmpy ships (parsed once)."""
    return etree.XMLSchema(file=str(Path(fmpy_ssd.__file__).parent / "schema" / schema_name))


#: an SSP 2.x version attribute: SSP 2.0 keeps the 1.0 namespaces (OMSimulator writes it)
SSP2 = re.compile(r"2[.][0-9]+(-.*)?")
#: schema complaints about content the SSP 1.0 schema does not know
UNKNOWN_CONTENT = ("This element is not expected", "is not allowed")


def _check_schema(root, shown: str, schema_name: str, problems: list, warnings: list) -> None:
    """Problems against the SSP 1.0 schema that fmpy ships.  A 2.x document (its root,
    or an inline parameter set) is checked as 1.0, which it extends: what 2.0 adds
    (elements and attributes the 1.0 schema does not know) is a warning, as dsim does
    not use it; every other violation is a problem."""
    versioned = [e for e in root.iter() if SSP2.fullmatch(e.get("version") or "")]
    originals = [e.get("version") for e in versioned]
    for element in versioned:
        element.set("version", "1.0")
    schema = _schema(schema_name)
    try:
        if schema.validate(root):
            return
    finally:  # the document keeps what it says (dsim info shows the version)
        for element, version in zip(versioned, originals):
            element.set("version", version)
    errors = list(schema.error_log)
    repeated = _merge_repeated(root) if errors else []
    if errors and _only_out_of_order(root, schema):
        # what the elements say is the same in either order, and a repeated element's
        # content is the same in one (OMSimulator reads both)
        if not repeated:
            warnings.append(f"{shown} line {errors[0].line}: elements out of the order "
                            f"SSP 1.0 gives ({errors[0].message}): read as if in order")
        else:
            warnings.append(f"{shown} line {errors[0].line}: {'; '.join(repeated)} (SSP 1.0 "
                            "allows one; the elements read as if in order, the repeated "
                            "ones' content merged in order)")
        return
    if versioned:
        unknown = [e for e in errors if any(text in e.message for text in UNKNOWN_CONTENT)]
        warnings += [f"{shown} line {e.line}: SSP 2.0 content dsim does not use: {e.message}"
                     for e in unknown[:3]]
        errors = [e for e in errors if e not in unknown]
    problems += [f"{shown} line {e.line}: not valid SSP 1.0: {e.message}" for e in errors[:3]]


#: the order SSP 1.0's sequences give the SSD elements that may stand side by side
#: (elements of other namespaces, and those that form a choice, keep their places)
SSD_ORDER = {name: rank for rank, name in enumerate((
    "System", "Enumerations", "Units", "DefaultExperiment", "Connectors", "ElementGeometry",
    "ParameterBindings", "Elements", "Connections", "SignalDictionaries", "SystemGeometry",
    "GraphicalElements", "ParameterValues", "ParameterMapping", "ConnectorGeometry",
    "ConnectionGeometry", "Annotations"), start=1)}


#: the SSD containers SSP 1.0 allows once per parent, whose children the reader reads
#: whichever of several holds them
ONCE = ("Connectors", "ParameterBindings", "Elements", "Connections", "Annotations",
        "SignalDictionaries", "GraphicalElements", "Units", "Enumerations")


def _merge_repeated(root) -> list[str]:
    """Merge, in place, every SSD container that SSP 1.0 allows once but a parent holds
    several times (OMSimulator writes two ssd:ParameterBindings in one system): the
    later ones' children appended to the first, in document order, the later ones
    removed.  What was merged, one text per parent and element ("ssd:ParameterBindings
    2 times in system 'root'")."""
    merged = []
    for parent in list(root.iter()):
        seen: dict[str, list] = {}
        for child in parent:
            if not isinstance(child.tag, str):
                continue
            name = etree.QName(child)
            if name.namespace == NS["ssd"] and name.localname in ONCE:
                seen.setdefault(name.localname, []).append(child)
        for local, found in seen.items():
            if len(found) < 2:
                continue
            for later in found[1:]:
                found[0].extend(list(later))
                parent.remove(later)
            what = etree.QName(parent).localname
            named = f" '{parent.get('name')}'" if parent.get("name") is not None else ""
            merged.append(f"ssd:{local} {len(found)} times in {what.lower()}{named}")
    return merged


def _only_out_of_order(root, schema: etree.XMLSchema) -> bool:
    """Whether the document is valid once the SSD elements of every parent stand in the
    order of SSP 1.0's sequences (an order error that changes nothing the reader reads:
    it finds elements by name)."""
    copy = etree.fromstring(etree.tostring(root))
    for element in copy.iter():
        if SSP2.fullmatch(element.get("version") or ""):
            element.set("version", "1.0")
        children = list(element)
        ranked = sorted(children, key=lambda child: SSD_ORDER.get(
            etree.QName(child).localname, 0) if isinstance(child.tag, str) and
            etree.QName(child).namespace == NS["ssd"] else 0)
        if ranked != children:
            element[:] = ranked
    return bool(schema.validate(copy))


class _Reader:
    """Walks one SystemStructure.ssd, collecting problems instead of stopping."""

    def __init__(self, ssd: Path, shown: str, allow_outside=()):
        self.ssd = ssd
        self.base = ssd.parent
        #: the scene's folder with links resolved: every file it names must be inside
        self.root = self.base.resolve()
        #: folders the user trusts besides it (``--allow-outside``), links resolved
        self.trusted = tuple(Path(folder).resolve() for folder in allow_outside)
        #: components whose FMU was refused before it was read: what depends on them
        #: (their connections, joints, placements) is not checked again
        self.refused: set[str] = set()
        self.shown = shown
        self.problems: list[str] = []
        #: rules broken that do not change what the run computes (``strict`` refuses them)
        self.warnings: list[str] = []
        #: the .ssv file of each ParameterBinding that names one -> (owner, whether a
        #: component, the binding element, where): ``--parameter-set`` applies that file
        #: there, through the binding's mapping and prefix
        self.bound_files: dict[Path, list] = {}
        self.components: list[dict] = []
        self.connections: list[RawConnection] = []
        self.bindings: list[Binding] = []
        self.system_connectors: dict[str, dict[str, Connector]] = {}
        self.joints, self.port_maps = [], []
        #: (component path, Ray resource, where) of each glue:Placement
        self.placements: list[tuple[str, str, str]] = []
        self.files: list[Path] = [ssd]
        #: per document, made once: each system's solver annotation (element -> what it
        #: says), each named file's place (source -> resolved path, or the OS error):
        #: 10,000 components of one FMU file resolve it once
        self._solvers: dict = {}
        self._places: dict[str, tuple] = {}

    def where(self, element) -> str:
        tag = etree.QName(element).localname
        name = element.get("name")
        label = f"{tag} '{name}'" if name else tag
        return f"{self.shown} ({self.ssd.name} line {element.sourceline}): {label}"

    # --- files -----------------------------------------------------------------
    def inside(self, source: str, where: str, what: str) -> Path | None:
        """The file of the scene that ``source`` names, or None with a problem said: a
        scene reaches only files inside its own folder (after resolving links), so an
        absolute path or one that leaves the folder is refused before it is opened."""
        if source.startswith(("/", "\\")) or Path(source).is_absolute():
            self.problems.append(f"{where}: {what} '{source}' is an absolute path: a scene "
                                 "names only files inside itself")
            return None
        file = self.base / source
        if source not in self._places:
            try:  # the name itself may be unusable (too long): one line, not a traceback
                resolved = file.resolve()
                outside = not resolved.is_relative_to(self.root) and not any(
                    resolved.is_relative_to(folder) for folder in self.trusted)
                file.is_file()
                self._places[source] = (outside, None)
            except OSError as error:
                self._places[source] = (None, error)
        outside, error = self._places[source]
        if error is not None:
            shown = source if len(source) <= 80 else source[:80] + "..."
            self.problems.append(f"{where}: {what} '{shown}' ({len(source)} characters) "
                                 f"cannot be a file name: {error.strerror}")
            return None
        if outside:
            self.problems.append(f"{where}: {what} '{source}' is outside the scene"
                                 + (" and the folders --allow-outside trusts"
                                    if self.trusted else
                                    " (--allow-outside DIR trusts a folder: docs/security.md)"))
            return None
        return file

    def _document(self, source: str, where: str, schema: str):
        """The root element of a file the SSD references, or None (a problem said)."""
        file = self.inside(source, where, "file")
        if file is None:
            return None
        if not file.is_file():
            self.problems.append(f"{where}: file '{source}' not found")
            return None
        self.files.append(file)
        try:
            root = parse_untrusted(str(file))
        except etree.XMLSyntaxError as error:
            self.problems.append(f"{self.shown}: {source}: malformed XML: {error}")
            return None
        except OSError as error:  # lxml's error for bytes that are not the declared encoding
            self.problems.append(f"{self.shown}: {source}: cannot read: {error}")
            return None
        _check_schema(root, f"{self.shown}: {source}", schema, self.problems, self.warnings)
        return root

    # --- parameters ------------------------------------------------------------
    def binding_values(self, binding, where: str) -> dict:
        """name -> (type, value) of one ParameterBinding: its parameter set (a file or
        inline), renamed by its parameter mapping, with its prefix prepended."""
        source = binding.get("source")
        if source:
            root = self._document(source, where, "SystemStructureParameterValues.xsd")
        else:
            root = binding.find("ssd:ParameterValues/ssv:ParameterSet", NS)
        if root is None:
            return {}
        return self.mapped(parameter_set(root, where, self.problems), binding, where)

    def mapped(self, values: dict, binding, where: str) -> dict:
        """Parameter values as a ParameterBinding gives them: renamed by its
        parameter mapping, with its prefix prepended."""
        mapping = binding.find("ssd:ParameterMapping", NS)
        if mapping is not None:
            mapping_source = mapping.get("source")
            mapping_root = (self._document(mapping_source, where,
                                           "SystemStructureParameterMapping.xsd")
                            if mapping_source else mapping.find("ssm:ParameterMapping", NS))
            if mapping_root is not None:
                values = apply_mapping(values, parameter_mapping(mapping_root, where,
                                                                 self.problems, self.warnings),
                                       where, self.problems)
        prefix = binding.get("prefix", "")
        return {prefix + name: value for name, value in values.items()}

    def bindings_of(self, element, owner: str, component: bool, depth: int) -> None:
        where = self.where(element)
        for binding in element.iterfind("ssd:ParameterBindings/ssd:ParameterBinding", NS):
            if binding.get("source"):
                file = (self.base / binding.get("source")).resolve()
                self.bound_files.setdefault(file, []).append((owner, component, binding, where))
            self.bindings.append(Binding(owner, component, depth,
                                         self.binding_values(binding, where), where))

    # --- systems ---------------------------------------------------------------
    def connectors_of(self, element) -> dict[str, Connector]:
        result = {}
        for connector in element.iterfind("ssd:Connectors/ssd:Connector", NS):
            typed = next((child for child in connector
                          if etree.QName(child).localname in TYPES), None)
            result[connector.get("name", "")] = Connector(
                connector.get("name", ""), connector.get("kind", ""),
                TYPES[etree.QName(typed).localname] if typed is not None else None,
                typed.get("unit") if typed is not None else None)
        return result

    def system(self, element, path: str, depth: int = 0) -> None:
        prefix = f"{path}." if path else ""
        self.system_connectors[path] = self.connectors_of(element)
        self.bindings_of(element, path, False, depth)
        for child in element.iterfind("ssd:Elements/*", NS):
            tag = etree.QName(child).localname
            name = child.get("name", "")
            if tag == "System":
                self.system(child, prefix + name, depth + 1)
            elif tag == "Component":
                self.component(child, prefix, depth + 1)
            else:
                self.problems.append(f"{self.where(child)}: element kind '{tag}' not supported")
        for connection in element.iterfind("ssd:Connections/ssd:Connection", NS):
            where = f"{self.shown} ({self.ssd.name} line {connection.sourceline}): Connection"
            # startElement="" (or none) names the system itself (OMSimulator writes "")
            self.connections.append(RawConnection(
                path, (connection.get("startElement") or None,
                       connection.get("startConnector", "")),
                (connection.get("endElement") or None, connection.get("endConnector", "")),
                transformation(connection, where, self.problems), where,
                connection.get("suppressUnitConversion", "false") not in ("true", "1")))
        for gluing in element.iterfind(
                "ssd:Annotations/ssc:Annotation[@type='org.dsim.gluing']/glue:Gluing", NS):
            for joint in gluing.iterfind("glue:Joint", NS):
                self.joints.append(read_joint(joint, prefix, self.where(joint), self.problems))
            for port in gluing.iterfind("glue:Port", NS):
                self.port_maps.append(read_port_map(port, prefix, self.where(port),
                                                    self.problems))
            for placement in gluing.iterfind("glue:Placement", NS):
                self.placements.append(read_placement(placement, prefix,
                                                      self.where(placement), self.problems))

    def component(self, element, prefix: str, depth: int) -> None:
        where = self.where(element)
        source = element.get("source", "")
        kind = element.get("type")
        # a table component (OMSimulator's: a .csv or .mat file of the scene) is a
        # source whose outputs are its columns (dsim.master.running.tables)
        table = kind in TABLE_TYPES or (kind is None and is_table_file(source))
        if table and not is_table_file(source):
            self.problems.append(f"{where}: type '{kind}' names a table, but its source "
                                 f"'{source}' is no .csv or .mat file")
            self.refused.add(prefix + element.get("name", ""))
            return
        if not table and (kind or "application/x-fmu-sharedlibrary") != \
                "application/x-fmu-sharedlibrary":
            self.problems.append(f"{where}: type '{kind}' is not an FMU (dsim runs FMU "
                                 "components and tables of .csv or .mat files; a referenced "
                                 "SSP or SSD is not supported)")
            self.refused.add(prefix + element.get("name", ""))
            return
        file = self.inside(source, where, "table source" if table else "FMU source")
        if file is None:
            self.refused.add(prefix + element.get("name", ""))
            return
        if not source or not file.is_file():
            self.problems.append(f"{where}: {'table' if table else 'FMU'} '{source}' "
                                 "not found")
        path = prefix + element.get("name", "")
        self.bindings_of(element, path, True, depth)
        self.components.append(dict(path=path, source=file, location=where,
                                    connectors=self.connectors_of(element),
                                    implementation=element.get("implementation", ""),
                                    solver=solver_of(element, self.warnings, where,
                                                    self._solvers),
                                    substeps=self.substeps_of(element, path)))

    def substeps_of(self, element, path: str) -> tuple:
        """(the text of ``count``, where) of the component's ``glue:Substeps``
        annotation, () without one; a second one is a problem."""
        found = element.findall(
            "ssd:Annotations/ssc:Annotation[@type='org.dsim.substeps']/glue:Substeps", NS)
        if not found:
            return ()
        wheres = [f"{self.shown} ({self.ssd.name} line {node.sourceline}): glue:Substeps of "
                  f"component '{path}'" for node in found]
        if len(found) > 1:
            self.problems.append(f"{wheres[1]}: a second glue:Substeps (one per component)")
        return found[0].get("count"), wheres[0]

    def parameter_set_on_top(self, chosen: str) -> None:
        """Bind a parameter set of the scene above every other binding."""
        where = f"{self.shown}: parameter set '{chosen}'"
        file = self.inside(chosen, where, "file")
        if file is None:
            return
        if not file.is_file():
            named = {}
            for candidate in sorted(self.base.rglob("*.ssv")):
                if not candidate.resolve().is_relative_to(self.root):
                    continue  # a link out of the scene: not one of its files
                try:
                    named[parse_untrusted(str(candidate)).get("name")] = candidate
                except (etree.XMLSyntaxError, OSError):  # unreadable: not a set to choose
                    continue
            if chosen not in named:
                listed = ", ".join(sorted(map(str, named))) or "none"
                self.problems.append(f"{where}: no such .ssv file or ParameterSet in the "
                                     f"scene (it has: {listed})")
                return
            file = named[chosen]
        root = self._document(str(file.relative_to(self.base)), where,
                              "SystemStructureParameterValues.xsd")
        if root is None:
            return
        values = parameter_set(root, where, self.problems)
        # a set the scene binds is meant for that place: its names are those of the
        # binding's ParameterMapping and prefix, relative to the binding's owner
        places = self.bound_files.get(file.resolve(), [("", False, None, where)])
        for owner, component, binding, _ in places:
            given = self.mapped(values, binding, where) if binding is not None else values
            self.bindings.append(Binding(owner, component, -1, given, where))

    # --- the components, as the hierarchy makes them ---------------------------
    def resolve(self) -> tuple[list[Component], list]:
        paths = {c["path"] for c in self.components}
        connectors = {c["path"]: c["connectors"] for c in self.components}
        values, origins, connector_values = resolve_bindings(
            self.bindings, paths, self.system_connectors, self.problems, self.warnings,
            self.refused)
        connections, starts = resolve_connections(
            self.connections, paths, connectors, self.system_connectors, connector_values,
            self.problems, self.refused)
        components = []
        for c in self.components:
            parameters = {**starts[c["path"]], **values[c["path"]]}
            files = self.scene_files(parameters, origins[c["path"]], c["location"])
            components.append(Component(c["path"], c["source"], parameters,
                                        tuple(c["connectors"].values()), c["location"],
                                        origins[c["path"]], files, c["implementation"],
                                        c["solver"], c["substeps"]))
        return components, connections

    def scene_files(self, parameters: dict, origins: dict, location: str) -> dict[str, Path]:
        """name -> the file, of the String parameters that name a file of the scene
        (a value starting with ``resources/``, the folder SSP gives a package's
        resources): an FMU only knows its own resources, so the master hands it the
        file's absolute path (see docs/ssp_support.md)."""
        files = {}
        for name, (kind, value) in parameters.items():
            if kind != "String" or not value.startswith(SCENE_RESOURCES):
                continue
            file, problem = scene_file(self.base, name, value, origins.get(name, location))
            if problem:
                self.problems.append(problem)
            else:
                files[name] = file
                self.files.append(file)
        return files


#: start and stop time (s) of a scene without a DefaultExperiment (dsim info says so)
DEFAULT_START, DEFAULT_STOP = 0.0, 1.0


def _master_annotation(root, shown: str, problems: list) -> tuple[float, float, dict, tuple]:
    """Start and stop time, the ``glue:Master`` attributes as the file writes them, and
    another tool's step where dsim's annotation gives none (the planning layer converts
    and checks both: :mod:`dsim.master.planning.load`)."""
    experiment = root.find("ssd:DefaultExperiment", NS)
    start, stop = DEFAULT_START, DEFAULT_STOP
    attributes = {}
    if experiment is not None:
        where = f"{shown}: DefaultExperiment"
        start = floats(experiment.get("startTime"), 1, start, f"{where}: startTime", problems)[0]
        stop = floats(experiment.get("stopTime"), 1, stop, f"{where}: stopTime", problems)[0]
        node = experiment.find(
            "ssd:Annotations/ssc:Annotation[@type='org.dsim.master']/glue:Master", NS)
        if node is not None:
            attributes = dict(node.attrib)
    # no step of dsim's own: the one OMSimulator or OSP wrote, if any
    other = () if "step" in attributes else (tool_step(root, shown) or ())
    return start, stop, attributes, other


def read_scene(path, parameter_sets=(), strict: bool = True, ssd: str | None = None,
               allow_outside=()) -> Scene:
    """Read and check an SSP system; raise InputError listing every problem (or, not
    ``strict``, keep the problems in ``Scene.problems`` when the system could still be
    read, so that the plan's checks can add theirs).  The master settings are kept as
    the file writes them (``Scene.master_annotation``); :func:`dsim.load_scene`
    (:mod:`dsim.master.planning.load`) converts them.

    ``parameter_sets``: parameter sets applied on top of every binding of the scene,
    as if bound to the root system last: each an .ssv file of the scene (its path in
    the scene, like ``resources/heavy.ssv``) or the name of a ParameterSet in one.
    ``ssd``: which .ssd of the archive or folder (default SystemStructure.ssd).
    ``allow_outside``: folders whose files the scene may name besides its own (the
    user trusts them: docs/security.md)."""
    path = Path(path)
    ssd, shown = _open(path, ssd)
    root = _parse_xml(ssd, shown)
    if etree.QName(root).localname != "SystemStructureDescription":
        raise InputError(f"{shown}: SystemStructure.ssd: root element is "
                         f"'{etree.QName(root).localname}', not ssd:SystemStructureDescription")
    reader = _Reader(ssd, shown, allow_outside)
    _check_schema(root, shown, "SystemStructureDescription.xsd", reader.problems,
                  reader.warnings)
    others = [name for name in ssd_files(path) if name != ssd.name]
    if others and not ssd_name_given(path, ssd):
        reader.warnings.append(f"{shown}: holds other system structures too "
                               f"({', '.join(others)}): this reads {ssd.name} (--ssd NAME "
                               "chooses)")
    system = root.find("ssd:System", NS)
    if system is None:
        raise InputError(reader.problems or [f"{shown}: SystemStructure.ssd has no ssd:System"])
    reader.system(system, "")
    for chosen in parameter_sets:
        reader.parameter_set_on_top(chosen)
    components, connections = reader.resolve()
    start, stop, annotation, other_step = _master_annotation(root, shown, reader.problems)
    scene_units = units(root, shown, reader.problems)
    _check_references(reader, components, connections)
    problems = tuple(dict.fromkeys(reader.problems))
    if problems and strict:
        error = InputError(list(problems))
        error.warnings = list(dict.fromkeys(reader.warnings))
        raise error
    name = root.get("name") or path.stem
    reference = ssd.parent / "resources" / "reference.csv"
    if reference.is_file() and not reference.resolve().is_relative_to(ssd.parent.resolve()):
        reference = None  # a link out of the scene is not its reference
    return Scene(name, path, start, stop, tuple(components), tuple(connections),
                 tuple(reader.joints), tuple(reader.port_maps), MasterSettings(),
                 tuple(reader.files), scene_units,
                 root.find("ssd:DefaultExperiment", NS) is not None, problems,
                 reference if reference and reference.is_file() else None,
                 {path: resource for path, resource, _ in reader.placements},
                 tuple(dict.fromkeys(reader.warnings)), root.get("version", ""),
                 parameter_sets=tuple(parameter_sets), master_annotation=annotation,
                 master_where=f"{shown}: glue:Master", other_step=other_step,
                 descriptions=descriptions(components))


def _check_references(reader: _Reader, components, connections) -> None:
    """Joints, port maps and connections must name components that exist."""
    paths = {c.path for c in components} | reader.refused  # (refused: said once already)
    # every check here is linear in the scene's size: a scene of a million components
    # is read in seconds, never hours
    uses = Counter(c.path for c in components)
    for component in components:
        if uses[component.path] > 1:
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
    placed = set()
    for path, _, where in reader.placements:
        if path not in paths:
            reader.problems.append(f"{where}: unknown component '{path}'")
        elif path in placed:
            reader.problems.append(f"{where}: component '{path}' is placed twice")
        placed.add(path)
    for connection in connections:
        for side in (connection.start, connection.end):
            if side[0] not in paths:
                reader.problems.append(f"{connection.location}: unknown component '{side[0]}'")
