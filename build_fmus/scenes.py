"""Write the shipped scene folders of ssp/ (SystemStructure.ssd + .ssv files).

The folders are committed; this module is how they were made and how a scene
family (chain_<n>) is regenerated at another size:
``python -m build_fmus.scenes``.  Parameters are those of SCENES.md.
"""
from __future__ import annotations

import math
from pathlib import Path

from lxml import etree

ROOT = Path(__file__).resolve().parent.parent
SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
GLUE = "urn:dsim:gluing:1"


def _q(ns, tag):
    return f"{{{ns}}}{tag}"


def parameter_set(name: str, values: dict) -> etree._Element:
    """An ssv:ParameterSet; ints become Integer, floats Real."""
    root = etree.Element(_q(SSV, "ParameterSet"), nsmap={"ssv": SSV}, version="1.0", name=name)
    parameters = etree.SubElement(root, _q(SSV, "Parameters"))
    for key, value in values.items():
        parameter = etree.SubElement(parameters, _q(SSV, "Parameter"), name=key)
        kind = "Integer" if isinstance(value, int) else "Real"
        etree.SubElement(parameter, _q(SSV, kind), value=repr(value))
    return root


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
        self.joints: list[etree._Element] = []

    def component(self, name: str, fmu: str, parameters: dict, outputs=()) -> None:
        element = etree.SubElement(self.elements, _q(SSD, "Component"), name=name,
                                   type="application/x-fmu-sharedlibrary",
                                   source=f"resources/{fmu}.fmu")
        if outputs:
            connectors = etree.SubElement(element, _q(SSD, "Connectors"))
            for output in outputs:
                connector = etree.SubElement(connectors, _q(SSD, "Connector"),
                                             name=output, kind="output")
                etree.SubElement(connector, _q(SSC, "Real"))
        bindings = etree.SubElement(element, _q(SSD, "ParameterBindings"))
        etree.SubElement(bindings, _q(SSD, "ParameterBinding"),
                         source=f"resources/{name}.ssv")
        self.parameter_sets[name] = parameter_set(name, parameters)

    def joint(self, name, a, b, dofs="x", kind="fixed", measure="displacement",
              spring=None, damper=None, penalty=None) -> None:
        joint = etree.Element(_q(GLUE, "Joint"), name=name, a=a, b=b, dofs=dofs,
                              kind=kind, measure=measure)
        for tag, values in (("Spring", spring), ("Damper", damper), ("Penalty", penalty)):
            if values:
                etree.SubElement(joint, _q(GLUE, tag), {k: repr(v) for k, v in values.items()})
        self.joints.append(joint)

    def write(self, folder: Path, start: float, stop: float, **master) -> None:
        if self.joints:
            annotations = etree.SubElement(self.system, _q(SSD, "Annotations"))
            annotation = etree.SubElement(annotations, _q(SSC, "Annotation"),
                                          type="org.dsim.gluing")
            gluing = etree.SubElement(annotation, _q(GLUE, "Gluing"), nsmap={"glue": GLUE})
            gluing.extend(self.joints)
        experiment = etree.SubElement(self.root, _q(SSD, "DefaultExperiment"),
                                      startTime=repr(start), stopTime=repr(stop))
        annotations = etree.SubElement(experiment, _q(SSD, "Annotations"))
        annotation = etree.SubElement(annotations, _q(SSC, "Annotation"), type="org.dsim.master")
        etree.SubElement(annotation, _q(GLUE, "Master"), {k: str(v) for k, v in master.items()},
                         nsmap={"glue": GLUE})
        (folder / "resources").mkdir(parents=True, exist_ok=True)
        for old in (folder / "resources").glob("*.ssv"):
            old.unlink()
        etree.ElementTree(self.root).write(str(folder / "SystemStructure.ssd"),
                                           pretty_print=True, xml_declaration=True,
                                           encoding="UTF-8")
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
        scene.component(f"m{i}", "SpringMass", values, outputs=["x[1]"])
    for i in range(1, n):
        scene.joint(f"j{i}", f"m{i}.Q", f"m{i + 1}.P")
    return scene


def write_all(root: Path = ROOT) -> None:
    """(Re)write every generated scene folder."""
    p = SPRING_MASS
    for nonlinear in (False, True):
        scene = spring_mass(nonlinear)
        scene.write(root / "ssp" / scene.name, 0.0, p["stop"], step=p["step"],
                    tolerance=p["tolerance"], maxIterations=20, predictor="linear",
                    refreshAfter=10)
    for n in (10, 100):
        scene = chain(n)
        scene.write(root / "ssp" / scene.name, 0.0, CHAIN["stop"], step=CHAIN["step"],
                    tolerance=1e-13, maxIterations=20, predictor="linear", refreshAfter=10)


if __name__ == "__main__":
    write_all()
