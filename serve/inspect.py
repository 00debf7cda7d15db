"""Checks an uploaded FMU or .ssp with dsim's own checks and describes it, in a
child process: ``python -m dsim.serve.inspect fmu|ssp FILE`` prints one JSON
object, ``{"ok": true, "description": {...}}`` or ``{"ok": false, "problems":
[...]}``.  ``python -m dsim.serve.inspect parameters FILE`` checks the model
parameters a run form gives (a JSON object on standard input) against a stored
scene, by ``dsim run --set``'s rules (:func:`dsim.prepare` with ``parameters``), and
answers the values as the run will apply them.

An uploaded FMU's shared library is never loaded here, nor anywhere in the
server: loading a library runs its constructors, so a page that got a file
uploaded (see :class:`dsim.serve.app.Guard`) would run code on this machine.
Only modelDescription.xml is read, and the library for this platform is checked
to be there and, on Linux, to be a whole ELF shared object for this machine
(``dsim.fmu_problem(path, load=False)``, reading bytes only; the
scene checks are ``dsim validate``'s, which load nothing either).  A library runs
only in a run's own worker process, when a user starts a run.

Why a child process besides: reading an upload unpacks archives into temporary
folders and fills caches; all of that ends with the child, so a long-running
server keeps none of it and a file that crashes the checker is only a message
(:func:`dsim.serve.uploads.inspect_file`).
"""
from __future__ import annotations

import json
import shutil
import sys
import tempfile
import zipfile
from contextlib import contextmanager
from pathlib import Path

from dsim import (MAX_UNPACKED, check_archive as shared_check_archive, conventional_ports,
                  describe, fmu_problem, free_settable, InputError, joint_coefficients,
                  prepare, validate)

#: capability flags of <CoSimulation> shown on a model's page
CAPABILITIES = ("canGetAndSetFMUstate", "canSerializeFMUstate",
                "canHandleVariableCommunicationStepSize", "canInterpolateInputs",
                "providesDirectionalDerivative", "canBeInstantiatedOnlyOncePerProcess",
                "needsExecutionTool", "canNotUseMemoryManagementFunctions",
                "canRunAsynchronuously", "maxOutputDerivativeOrder")


class Refused(Exception):
    """The file is not acceptable: the message says why, in one line."""


def check_archive(path: Path, what: str, max_unpacked: int = MAX_UNPACKED) -> list[str]:
    """Member names of a zip archive, refused (:class:`Refused`) on the command line's
    grounds (:func:`dsim.check_archive`: not a zip, a zip bomb, a member outside itself, a
    name that is not UTF-8)."""
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
    dsim's checks of an FMU (:func:`dsim.fmu_problem`)."""
    names = check_archive(path, "FMU", max_unpacked)
    problem = fmu_problem(path, load=False)
    if problem:
        raise Refused(problem)
    description = describe(path)
    cs = description.coSimulation or description.modelExchange
    platforms = sorted({n.split("/")[1] for n in names
                        if n.startswith("binaries/") and n.count("/") >= 2})
    return {
        "kind": "fmu",
        "modelName": description.modelName,
        "fmiVersion": description.fmiVersion,
        "interfaces": list(description.interfaces),
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
                       "unit": v.unit,
                       "start": _start(v), "description": v.description or ""}
                      for v in description.modelVariables],
        "ports": {port: sorted(dofs) for port, dofs in conventional_ports(path).items()},
    }


def _joint(joint) -> dict:
    return {"name": joint.name, "a": ".".join(joint.a), "b": ".".join(joint.b),
            "dofs": list(joint.dofs), "kind": joint.kind, "measure": joint.measure,
            "k0": list(joint.k0), "k1": list(joint.k1), "c0": list(joint.c0),
            "c1": list(joint.c1), "xi": joint.xi, "omega": joint.omega,
            "settable": list(joint_coefficients(joint))}


def _settable(plan, index: int) -> list[dict]:
    """What a run may set in component ``index`` (``dsim info``'s list): the
    parameters, and the inputs that no joint or connection writes, with the value
    the scene binds."""
    component = plan.scene.component(plan.specs[index].name)
    rows = []
    for v in free_settable(plan, index):
        bound = component.parameters.get(v.name)
        rows.append({"name": v.name, "type": v.type, "causality": v.causality,
                     "variability": v.variability, "unit": v.unit, "start": v.start,
                     "min": v.min, "max": v.max, "description": v.description,
                     "items": [list(item) for item in v.items],
                     "value": None if bound is None else bound[1]})
    return rows


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

    names = check_archive(path, "SSP", max_unpacked)
    if "SystemStructure.ssd" not in names:
        raise Refused("not an SSP archive (no SystemStructure.ssd at its root)")
    folder = Path(tempfile.mkdtemp(prefix="dsim-serve-"))
    try:
        with zipfile.ZipFile(path) as archive:
            archive.extractall(folder)
        # the libraries are checked as bytes, never loaded (docs/security.md)
        found = validate(folder, load_libraries=False)
        if not found.ok:
            raise Refused("\n".join(p.replace(str(folder), "scene")
                                     for p in found.errors))
        plan = prepare(folder, load_libraries=False)
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
            "settable": {c.path: _settable(plan, i) for i, c in enumerate(scene.components)},
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


@contextmanager
def _unpacked_scene(path: Path, max_unpacked: int):
    """A new temporary folder holding the stored scene at ``path`` (checked as an
    untrusted archive) unpacked in its ``scene`` subfolder; removed after."""
    check_archive(path, "SSP", max_unpacked)
    folder = Path(tempfile.mkdtemp(prefix="dsim-serve-"))
    try:
        with zipfile.ZipFile(path) as archive:
            archive.extractall(folder / "scene")
        yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _plan(folder: Path, shown: dict, **keywords):
    """``prepare`` of the scene unpacked in ``folder`` (:func:`_unpacked_scene`) with
    ``keywords``, no library loaded; its InputError with each temporary path of
    ``shown`` (path -> name) named as the user knows it."""
    try:
        return prepare(folder / "scene", load_libraries=False, **keywords)
    except InputError as error:
        problems = error.problems
        for temporary, name in {**shown, folder / "scene": "scene"}.items():
            problems = [p.replace(str(temporary), name) for p in problems]
        raise InputError(problems) from None


def check_parameters(path: Path, max_unpacked: int = MAX_UNPACKED, given=None) -> dict:
    """The model parameters ``given`` (name -> value, from a run form) as a run of the
    stored scene at ``path`` applies them, after every check of ``dsim run --set``
    (an InputError lists what is wrong); no library is loaded."""
    if not isinstance(given, dict):
        raise Refused("give the parameters as a JSON object of name: value")
    with _unpacked_scene(path, max_unpacked) as folder:
        return {"parameters": _plan(folder, {}, parameters=given).scene.overrides}


def check_scenario(path: Path, max_unpacked: int = MAX_UNPACKED, given=None) -> dict:
    """A scenario a run form gives (``given``: its ``text``, the suffix it is read by
    as ``format``, ``events`` and the run's ``settings``, its model parameters among
    them) resolved against the stored scene at ``path`` by ``dsim run --scenario``'s
    rules: ``{"lines": ...}``, what ``dsim info --scenario`` says of it (an InputError
    lists what is wrong); no library is loaded."""
    if not isinstance(given, dict) or not isinstance(given.get("text"), str) \
            or given.get("format") not in ("json", "yml", "xml") \
            or not isinstance(given.get("settings"), dict):
        raise Refused("give the scenario as a JSON object with its text, format and the "
                      "run's settings")
    with _unpacked_scene(path, max_unpacked) as folder:
        scenario = folder / f"scenario.{given['format']}"
        scenario.write_text(given["text"], encoding="utf-8")
        plan = _plan(folder, {scenario: "scenario"}, **given["settings"], scenario=scenario,
                     events=given.get("events") or "point")
        return {"lines": [line.replace(str(scenario), "scenario")
                          for line in plan.scenario.lines()]}


def _ssd_root(folder: Path):
    from lxml import etree

    return etree.parse(str(folder / "SystemStructure.ssd")).getroot()


def main(argv=None) -> int:
    """Print the JSON answer for one file; exit 0 whatever the answer."""
    argv = sys.argv[1:] if argv is None else argv
    kind, path = argv[0], Path(argv[1])
    max_unpacked = int(argv[2]) if len(argv) > 2 else MAX_UNPACKED
    try:
        if kind in ("parameters", "scenario"):
            given = json.loads(sys.stdin.read() or "null")
            check = check_parameters if kind == "parameters" else check_scenario
            answer = {"ok": True, "description": check(path, max_unpacked, given)}
        else:
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
