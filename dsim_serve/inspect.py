"""Checks an uploaded FMU or .ssp with dsim's own checks and describes it, in a
child process: ``python -m dsim_serve.inspect fmu|ssp FILE`` prints one JSON
object, ``{"ok": true, "description": {...}}`` or ``{"ok": false, "problems":
[...]}``.

An uploaded FMU's shared library is never loaded here, nor anywhere in the
server: loading a library runs its constructors, so a page that got a file
uploaded (see :class:`dsim_serve.app.Guard`) would run code on this machine.
Only modelDescription.xml is read, and the library for this platform is checked
to be there and, on Linux, to be a whole ELF shared object for this machine
(:func:`library_problem`, reading bytes only).  A library runs only in a run's
own worker process, when a user starts a run.  dsim's check of a scene loads
each FMU's library in a probe process (``master.fmu_archive``); for a scene
this child uses :func:`fmu_problem` instead (:func:`_without_loading`).

Why a child process besides: reading an upload unpacks archives into temporary
folders and fills caches; all of that ends with the child, so a long-running
server keeps none of it and a file that crashes the checker is only a message
(:func:`dsim_serve.uploads.inspect_file`).
"""
from __future__ import annotations

import json
import shutil
import struct
import sys
import tempfile
import zipfile
from contextlib import contextmanager
from pathlib import Path, PurePosixPath

from master.unpacking import MAX_MEMBERS, MAX_UNPACKED  # noqa: F401 (shared)
from master.unpacking import check_archive as shared_check_archive

#: capability flags of <CoSimulation> shown on a model's page
CAPABILITIES = ("canGetAndSetFMUstate", "canSerializeFMUstate",
                "canHandleVariableCommunicationStepSize", "canInterpolateInputs",
                "providesDirectionalDerivative", "canBeInstantiatedOnlyOncePerProcess",
                "needsExecutionTool", "canNotUseMemoryManagementFunctions",
                "canRunAsynchronuously", "maxOutputDerivativeOrder")


#: ELF e_machine of each Linux platform of FMI 2.0
ELF_MACHINES = {"linux64": (2, 62), "linux32": (1, 3)}  # (ELF class, e_machine)


class Refused(Exception):
    """The file is not acceptable: the message says why, in one line."""


def _elf_problem(data: bytes, platform: str) -> str | None:
    """What keeps ``data`` from being a whole ELF shared object for ``platform``,
    from its headers alone (nothing is loaded or run): a library cut short or made
    for another machine is refused here rather than at its first run."""
    if data[:4] != b"\x7fELF":
        return "is not an ELF shared library"
    expected = ELF_MACHINES.get(platform)
    if expected is None:
        return None
    bits, machine = expected
    if data[4] != bits or data[5] != 1:  # class, little-endian
        return f"is not a little-endian {32 * bits}-bit library"
    if bits == 2:
        if len(data) < 64:
            return "is cut short (no whole ELF header)"
        kind, found, phoff, shoff = struct.unpack_from("<HH12xQQ", data, 16)
        phentsize, phnum, shentsize, shnum = struct.unpack_from("<HHHH", data, 54)
    else:
        if len(data) < 52:
            return "is cut short (no whole ELF header)"
        kind, found, phoff, shoff = struct.unpack_from("<HH8xII", data, 16)
        phentsize, phnum, shentsize, shnum = struct.unpack_from("<HHHH", data, 42)
    if kind != 3:
        return "is not a shared object (ELF type %d)" % kind
    if found != machine:
        return f"is built for another machine (ELF machine {found})"
    if phoff + phnum * phentsize > len(data) or shoff + shnum * shentsize > len(data):
        return "is cut short (its headers point past its end)"
    return None


def library_problem(path: Path) -> str | None:
    """The library of this platform that an FMU names is in the archive and looks
    whole (:func:`_elf_problem`), read as bytes, never loaded."""
    from fmpy import platform, sharedLibraryExtension

    from master.ports import model_description

    identifier = model_description(path).coSimulation.modelIdentifier
    member = f"binaries/{platform}/{identifier}{sharedLibraryExtension}"
    with zipfile.ZipFile(path) as archive:
        if member not in archive.namelist():
            found = sorted({n.split("/")[1] for n in archive.namelist()
                            if n.startswith("binaries/") and n.count("/") >= 2})
            return (f"no binary for this platform ({member} missing; the FMU has "
                    f"{', '.join(found) or 'no binaries'})")
        problem = _elf_problem(archive.read(member), platform) if member.endswith(".so") \
            else None
    return f"its library {member} {problem}" if problem else None


def fmu_problem(path: Path) -> str | None:
    """dsim's check of an FMU (:func:`master.fmu_archive.fmu_problem`: a readable
    archive, FMI 2.0 co-simulation) but for its library, which is checked by
    :func:`library_problem` instead of being loaded."""
    from master.fmu_archive import _archive_problem, _description_problem

    return _archive_problem(path) or _description_problem(path) or library_problem(path)


@contextmanager
def _without_loading():
    """dsim's checks of a scene (``dsim validate``, :func:`dsim.prepare`) with
    :func:`fmu_problem` for each FMU: theirs loads the library to probe it.  Only
    in this child process, which ends after one file."""
    import master.plan

    loading = master.plan.fmu_problem
    master.plan.fmu_problem = fmu_problem
    try:
        yield
    finally:
        master.plan.fmu_problem = loading


def check_archive(path: Path, what: str, max_unpacked: int = MAX_UNPACKED) -> list[str]:
    """Member names of a zip archive, refused (:class:`Refused`) on the command line's
    grounds (:func:`master.unpacking.check_archive`: not a zip, a zip bomb, a member
    outside itself, a name that is not UTF-8)."""
    from master.errors import InputError

    try:
        return shared_check_archive(path, what, max_unpacked)
    except InputError as error:
        raise Refused("; ".join(error.problems)) from None


def _start(variable):
    start = variable.start
    if start is None:
        return None
    return start if isinstance(start, (int, float, str, bool)) else str(start)


def describe_fmu(path: Path, max_unpacked: int = MAX_UNPACKED) -> dict:
    """The summary of an FMU's modelDescription that a model's page shows, after
    dsim's checks of an FMU (:func:`master.fmu_archive.fmu_problem`)."""
    from master.ports import conventional_ports, model_description

    names = check_archive(path, "FMU", max_unpacked)
    problem = fmu_problem(path)
    if problem:
        raise Refused(problem)
    description = model_description(path)
    cs = description.coSimulation
    platforms = sorted({n.split("/")[1] for n in names
                        if n.startswith("binaries/") and n.count("/") >= 2})
    return {
        "kind": "fmu",
        "modelName": description.modelName,
        "fmiVersion": description.fmiVersion,
        "guid": description.guid,
        "description": description.description or "",
        "generationTool": description.generationTool or "",
        "author": description.author or "",
        "version": description.version or "",
        "modelIdentifier": cs.modelIdentifier,
        "platforms": platforms,
        "capabilities": {name: getattr(cs, name, None) for name in CAPABILITIES},
        "experiment": ({"startTime": description.defaultExperiment.startTime,
                        "stopTime": description.defaultExperiment.stopTime,
                        "stepSize": description.defaultExperiment.stepSize}
                       if description.defaultExperiment else None),
        "variables": [{"name": v.name, "causality": v.causality,
                       "variability": v.variability, "type": v.type,
                       "unit": v.unit or (v.declaredType.unit if v.declaredType else None),
                       "start": _start(v), "description": v.description or ""}
                      for v in description.modelVariables],
        "ports": {port: sorted(dofs) for port, dofs in conventional_ports(path).items()},
    }


def _joint(joint) -> dict:
    return {"name": joint.name, "a": ".".join(joint.a), "b": ".".join(joint.b),
            "dofs": list(joint.dofs), "kind": joint.kind, "measure": joint.measure,
            "k0": list(joint.k0), "k1": list(joint.k1), "c0": list(joint.c0),
            "c1": list(joint.c1), "xi": joint.xi, "omega": joint.omega}


def _port_map(port_map) -> dict:
    return {"component": port_map.component, "name": port_map.name,
            "dofs": list(port_map.dofs),
            **{key: list(getattr(port_map, key) or ()) for key in
               ("force", "position", "velocity", "acceleration")}}


def _parameter_sets(folder: Path) -> list[dict]:
    """Every .ssv file of a scene; ``bound``: a ParameterBinding of the SSD uses it
    (else it is a set to choose for a run, ``dsim run --parameter-set``)."""
    from lxml import etree

    bound = {binding.get("source") for binding in _ssd_root(folder).iterfind(
        ".//{*}ParameterBinding") if binding.get("source")}
    found = []
    for file in sorted(folder.rglob("*.ssv")):
        try:
            root = etree.parse(str(file)).getroot()
        except etree.XMLSyntaxError:
            continue
        found.append({"path": file.relative_to(folder).as_posix(), "name": root.get("name"),
                      "parameters": len(root.findall(".//{*}Parameter")),
                      "bound": file.relative_to(folder).as_posix() in bound})
    return found


def describe_scene(path: Path, max_unpacked: int = MAX_UNPACKED) -> dict:
    """What a scene's page shows of an .ssp archive, after ``dsim validate``'s
    checks (a scene that does not validate is refused with every problem)."""
    import hashlib

    from master.api import prepare
    from master.validate import validate

    names = check_archive(path, "SSP", max_unpacked)
    if "SystemStructure.ssd" not in names:
        raise Refused("not an SSP archive (no SystemStructure.ssd at its root)")
    folder = Path(tempfile.mkdtemp(prefix="dsim-serve-"))
    try:
        with zipfile.ZipFile(path) as archive:
            archive.extractall(folder)
        with _without_loading():
            found = validate(folder)
            if not found.ok:
                raise Refused("\n".join(p.replace(str(folder), "scene")
                                         for p in found.errors))
            plan = prepare(folder)
        layout, _ = plan.assemble()
        scene = plan.scene
        fmus = {}
        components = []
        for component in scene.components:
            # the server reads each FMU from the archive by this name: it must be a
            # member's own name (no '..', nothing outside the scene)
            try:
                relative = component.source.relative_to(folder)
            except ValueError:
                relative = None
            if relative is None or ".." in relative.parts:
                raise Refused(f"component '{component.path}': its FMU source must name a "
                              "file inside the scene without '..'")
            member = relative.as_posix()
            if member not in fmus:
                fmus[member] = {"sha256": hashlib.sha256(component.source.read_bytes())
                                .hexdigest(), "description": describe_fmu(component.source)}
            components.append({"path": component.path, "fmu": member,
                               "parameters": {k: list(v) for k, v in
                                              component.parameters.items()},
                               "outputs": [c.name for c in component.connectors
                                           if c.kind == "output"]})
        root = _ssd_root(folder)
        return {
            "kind": "ssp",
            "name": scene.name,
            "description": root.get("description", ""),
            "start_time": scene.start_time,
            "stop_time": scene.stop_time,
            "master": dict(scene.master.__dict__),
            "coupling": plan.coupling,
            "components": components,
            "glued": [scene.components[i].path for i in plan.glued],
            "connections": [{"start": ".".join(c.start), "end": ".".join(c.end)}
                            for c in scene.connections],
            "joints": [_joint(j) for j in scene.joints],
            "port_maps": [_port_map(p) for p in scene.port_maps],
            "scene_files": sorted({f"{c.path}.{name}" for c in scene.components
                                   for name in c.files}),
            "columns": list(plan.columns) + list(layout.labels) + list(plan.text_columns),
            "parameter_sets": _parameter_sets(folder),
            "fmus": fmus,
            "summary": found.summary.replace(str(folder), scene.name),
            "warnings": [w.replace(str(folder), "scene") for w in found.warnings],
        }
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _ssd_root(folder: Path):
    from lxml import etree

    return etree.parse(str(folder / "SystemStructure.ssd")).getroot()


def main(argv=None) -> int:
    """Print the JSON answer for one file; exit 0 whatever the answer."""
    from master.errors import InputError

    argv = sys.argv[1:] if argv is None else argv
    kind, path = argv[0], Path(argv[1])
    max_unpacked = int(argv[2]) if len(argv) > 2 else MAX_UNPACKED
    try:
        describe = describe_fmu if kind == "fmu" else describe_scene
        answer = {"ok": True, "description": describe(path, max_unpacked)}
    except Refused as refused:
        answer = {"ok": False, "problems": str(refused).splitlines()}
    except InputError as error:
        answer = {"ok": False, "problems": error.problems}
    except Exception as error:  # a file nobody foresaw: a message, not a traceback
        answer = {"ok": False, "problems": [f"cannot read the file: {type(error).__name__}: "
                                            f"{error}"]}
    print(json.dumps(answer))
    return 0


if __name__ == "__main__":
    sys.exit(main())
