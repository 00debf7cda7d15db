"""The scene writer (:class:`SceneWriter`: SystemStructure.ssd + .ssv files) and the
spring-mass and chain scenes.

The folders of ssp/ are committed; the scene modules of build_fmus are how they were
made and how a family (chain_<n>) is regenerated at another size:
``python -m dsim.build_fmus.write_scenes`` writes them all.  Parameters are those of
SCENES.md.
"""
from __future__ import annotations

import math
import shutil
from pathlib import Path
from typing import Callable

from lxml import etree

from dsim.master.reading.ssp import SCENE_RESOURCES

ROOT = Path(__file__).resolve().parent.parent
SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
GLUE = "urn:dsim:gluing:1"


def _q(ns, tag):
    return f"{{{ns}}}{tag}"


def parameter_set(name: str, values: dict) -> etree._Element:
    """An ssv:ParameterSet; ints become Integer, floats Real, strings String."""
    root = etree.Element(_q(SSV, "ParameterSet"), nsmap={"ssv": SSV}, version="1.0", name=name)
    parameters = etree.SubElement(root, _q(SSV, "Parameters"))
    for key, value in values.items():
        parameter = etree.SubElement(parameters, _q(SSV, "Parameter"), name=key)
        if isinstance(value, str):
            etree.SubElement(parameter, _q(SSV, "String"), value=value)
            continue
        kind = "Integer" if isinstance(value, int) else "Real"
        etree.SubElement(parameter, _q(SSV, kind), value=repr(value))
    return root


def write_parameter_sets(folder: Path, sets: dict[str, dict]) -> None:
    """Named parameter sets of a scene (``dsim run --parameter-set NAME``), one .ssv each
    in ``folder``/resources/fidelity/, values named from the root system (``body.modes``)."""
    target = folder / "resources" / "fidelity"
    target.mkdir(parents=True, exist_ok=True)
    for old in target.glob("*.ssv"):
        old.unlink()
    for name, values in sets.items():
        etree.ElementTree(parameter_set(name, values)).write(
            str(target / f"{name}.ssv"), pretty_print=True, xml_declaration=True,
            encoding="UTF-8")


class SceneWriter:
    """Builds one SystemStructure.ssd with components, joints and master settings."""

    def __init__(self, name: str, description: str):
        self.name = name
        self.root = etree.Element(_q(SSD, "SystemStructureDescription"),
                                  nsmap={"ssd": SSD, "ssc": SSC, "ssv": SSV},
                                  version="1.0", name=name, description=description)
        self.system = etree.SubElement(self.root, _q(SSD, "System"), name="root")
        self.elements = etree.SubElement(self.system, _q(SSD, "Elements"))
        self.parameter_sets: dict[str, etree._Element] = {}
        #: files of the scene (a path in it, like resources/meshes/plate.vtk) -> a
        #: function that writes the file at the path it is given
        self.files: dict[str, Callable[[Path], None]] = {}
        self.joints: list[etree._Element] = []
        #: dotted path ("" for the root) -> (ssd:System, its ssd:Elements, its joints)
        self.systems = {"": (self.system, self.elements, self.joints)}

    def nested_system(self, name: str, parent: str = "") -> str:
        """Add an ssd:System ``name`` inside system ``parent``; returns its dotted path."""
        elements = self.systems[parent][1]
        system = etree.SubElement(elements, _q(SSD, "System"), name=name)
        path = f"{parent}.{name}" if parent else name
        self.systems[path] = (system, etree.SubElement(system, _q(SSD, "Elements")), [])
        return path

    def component(self, name: str, fmu: str, parameters: dict, outputs=(),
                  system: str = "", inline: bool = False) -> None:
        """A component of system ``system`` (a dotted path, "" for the root); its
        parameters go to resources/<path>.ssv, or into the SSD itself if ``inline``."""
        element = etree.SubElement(self.systems[system][1], _q(SSD, "Component"), name=name,
                                   type="application/x-fmu-sharedlibrary",
                                   source=f"resources/{fmu}.fmu")
        if outputs:
            connectors = etree.SubElement(element, _q(SSD, "Connectors"))
            for output in outputs:
                connector = etree.SubElement(connectors, _q(SSD, "Connector"),
                                             name=output, kind="output")
                etree.SubElement(connector, _q(SSC, "Real"))
        bindings = etree.SubElement(element, _q(SSD, "ParameterBindings"))
        path = f"{system}.{name}" if system else name
        if inline:
            binding = etree.SubElement(bindings, _q(SSD, "ParameterBinding"))
            values = etree.SubElement(binding, _q(SSD, "ParameterValues"))
            values.append(parameter_set(path, parameters))
            return
        etree.SubElement(bindings, _q(SSD, "ParameterBinding"),
                         source=f"resources/{path}.ssv")
        self.parameter_sets[path] = parameter_set(path, parameters)

    def file(self, path: str, save: Callable[[Path], None]) -> str:
        """Ship a file in the scene at ``path`` (under ``resources/``; ``save`` writes
        it); returns ``path``, the String parameter value that names it."""
        assert path.startswith(SCENE_RESOURCES), path  # how dsim tells a scene file
        self.files[path] = save
        return path

    def joint(self, name, a, b, dofs="x", kind="fixed", measure="displacement",
              spring=None, damper=None, penalty=None, system: str = "") -> None:
        """A glue joint declared in system ``system``; ``a`` and ``b`` are relative to it."""
        joint = etree.Element(_q(GLUE, "Joint"), name=name, a=a, b=b, dofs=dofs,
                              kind=kind, measure=measure)
        for tag, values in (("Spring", spring), ("Damper", damper), ("Penalty", penalty)):
            if values:
                etree.SubElement(joint, _q(GLUE, tag), {k: repr(v) for k, v in values.items()})
        self.systems[system][2].append(joint)

    def port_map(self, component: str, name: str, dofs: str, force: str, position: str,
                 velocity: str = "", acceleration: str = "", system: str = "") -> None:
        """A glue:Port mapping FMU variables onto port ``name`` of ``component`` (one
        variable name per dof in each of force, position, velocity, acceleration)."""
        attributes = dict(component=component, name=name, dofs=dofs, force=force,
                          position=position)
        attributes.update({k: v for k, v in (("velocity", velocity),
                                             ("acceleration", acceleration)) if v})
        self.systems[system][2].append(etree.Element(_q(GLUE, "Port"), attributes))

    def write(self, folder: Path, start_time: float, stop_time: float, **master) -> None:
        """Write SystemStructure.ssd, the .ssv files and the scene's files into
        ``folder`` (its resources/ folder rewritten whole); ``master`` are the
        glue:Master attributes."""
        for system, _, joints in self.systems.values():
            if not joints:
                continue
            annotations = etree.SubElement(system, _q(SSD, "Annotations"))
            annotation = etree.SubElement(annotations, _q(SSC, "Annotation"),
                                          type="org.dsim.gluing")
            gluing = etree.SubElement(annotation, _q(GLUE, "Gluing"), nsmap={"glue": GLUE})
            gluing.extend(joints)
        experiment = etree.SubElement(self.root, _q(SSD, "DefaultExperiment"),
                                      startTime=repr(start_time), stopTime=repr(stop_time))
        annotations = etree.SubElement(experiment, _q(SSD, "Annotations"))
        annotation = etree.SubElement(annotations, _q(SSC, "Annotation"), type="org.dsim.master")
        etree.SubElement(annotation, _q(GLUE, "Master"), {k: str(v) for k, v in master.items()},
                         nsmap={"glue": GLUE})
        folder.mkdir(parents=True, exist_ok=True)
        shutil.rmtree(folder / "resources", ignore_errors=True)  # nothing left over
        if self.parameter_sets:
            (folder / "resources").mkdir(exist_ok=True)
        etree.ElementTree(self.root).write(str(folder / "SystemStructure.ssd"),
                                           pretty_print=True, xml_declaration=True,
                                           encoding="UTF-8")
        for path, save in self.files.items():
            (folder / path).parent.mkdir(parents=True, exist_ok=True)
            save(folder / path)
        for name, element in self.parameter_sets.items():
            etree.ElementTree(element).write(str(folder / "resources" / f"{name}.ssv"),
                                             pretty_print=True, xml_declaration=True,
                                             encoding="UTF-8")


#: Section 5.3.1 parameters (SCENES.md spring_mass_*).
SPRING_MASS = {"m": 10.0, "k": 100.0, "F": 10.0, "k0": 100.0, "c0": 2 * 0.707 * 10,
               "k1": 1000.0, "c1": 2 * 0.707 * 1e4, "step": 0.01, "stop": 10.0,
               "tolerance": 1e-10}


def spring_mass(nonlinear: bool) -> SceneWriter:
    """Seed section 5.3.1: left (m1 on k to ground) glued to right (m2 -k- m3, F on m3)."""
    p = SPRING_MASS
    name = "spring_mass_nonlinear" if nonlinear else "spring_mass_linear"
    scene = SceneWriter(name, "Seed section 5.3.1: two spring-mass subsystems glued by a "
                        + ("nonlinear" if nonlinear else "linear") + " flexible joint")
    scene.component("left", "SpringMass", {"n": 1, "m[1]": p["m"], "k_ground[1]": p["k"],
                                           "P.mass": 1, "Q.mass": 1}, outputs=["x[1]"])
    scene.component("right", "SpringMass", {"n": 2, "m[1]": p["m"], "m[2]": p["m"],
                                            "k[1]": p["k"], "F0[2]": p["F"],
                                            "P.mass": 1, "Q.mass": 1},
                    outputs=["x[1]", "x[2]", "a[2]"])
    spring = {"k0": p["k0"], "k1": p["k1"] if nonlinear else 0.0}
    damper = {"c0": p["c0"], "c1": p["c1"] if nonlinear else 0.0}
    scene.joint("j1", "left.P", "right.Q", "x", "flexible", "displacement", spring, damper)
    return scene


#: chain_<n> (SCENES.md): unit masses on k = 1e4 to ground, fixed joints, sine at one end.
#: The response peaks near 1e-5 m (chain_100), so the interface tolerance is 1e-13 m.
CHAIN = {"m": 1.0, "k": 1e4, "Fa": 10.0, "frequency": 5.0, "step": 1e-3, "stop": 1.0}


def chain(n: int) -> SceneWriter:
    """n one-mass FMUs in a line, fixed joints chain[i].Q -- chain[i+1].P."""
    p = CHAIN
    scene = SceneWriter(f"chain_{n}", f"{n} spring-mass FMUs glued in a line by fixed joints")
    for i in range(1, n + 1):
        values = {"n": 1, "m[1]": p["m"], "k_ground[1]": p["k"], "P.mass": 1, "Q.mass": 1}
        if i == 1:
            values.update({"Fa[1]": p["Fa"], "omega[1]": 2 * math.pi * p["frequency"]})
        scene.component(f"m{i}", "SpringMass", values, outputs=["x[1]"], inline=True)
    for i in range(1, n):
        scene.joint(f"j{i}", f"m{i}.Q", f"m{i + 1}.P")
    return scene


def write_spring_mass_scenes(root: Path = ROOT) -> None:
    """(Re)write the spring_mass_* scene folders under ``root``/ssp."""
    p = SPRING_MASS
    for nonlinear in (False, True):
        scene = spring_mass(nonlinear)
        scene.write(root / "ssp" / scene.name, 0.0, p["stop"], step=p["step"],
                    tolerance=p["tolerance"], maxIterations=20, predictor="linear",
                    refreshAfter=10)


def write_chain_scenes(root: Path = ROOT) -> None:
    """(Re)write the chain_<n> scene folders under ``root``/ssp."""
    for n in (10, 100, 1000):
        scene = chain(n)
        scene.write(root / "ssp" / scene.name, 0.0, CHAIN["stop"], step=CHAIN["step"],
                    tolerance=1e-13, maxIterations=20, predictor="linear", refreshAfter=10)
