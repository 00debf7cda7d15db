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

    def joint(self, name, a, b, dofs="x", kind="fixed", measure="displacement",
              spring=None, damper=None, penalty=None, system: str = "") -> None:
        """A glue joint declared in system ``system``; ``a`` and ``b`` are relative to it."""
        joint = etree.Element(_q(GLUE, "Joint"), name=name, a=a, b=b, dofs=dofs,
                              kind=kind, measure=measure)
        for tag, values in (("Spring", spring), ("Damper", damper), ("Penalty", penalty)):
            if values:
                etree.SubElement(joint, _q(GLUE, tag), {k: repr(v) for k, v in values.items()})
        self.systems[system][2].append(joint)

    def write(self, folder: Path, start_time: float, stop_time: float, **master) -> None:
        """Write SystemStructure.ssd and the .ssv files into ``folder``; ``master``
        are the glue:Master attributes."""
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
        for old in (folder / "resources").glob("*.ssv"):
            old.unlink()
        if self.parameter_sets:
            (folder / "resources").mkdir(exist_ok=True)
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
        scene.component(f"m{i}", "SpringMass", values, outputs=["x[1]"], inline=True)
    for i in range(1, n):
        scene.joint(f"j{i}", f"m{i}.Q", f"m{i + 1}.P")
    return scene


#: frame_split / frame_nested (SCENES.md; seed section 2.2): Newmark, H = 1e-4 s, 0 to 0.2 s.
#: The glued quantities are global positions (about 1 m) while the response is about
#: 1e-5 m: the tolerance is absolute and near round-off, and the flexibility is measured
#: with a large force perturbation (the bodies are linear, so it has no truncation error).
FRAME = {"step": 1e-4, "stop": 0.2, "tolerance": 1e-14, "perturbation": 1.0,
         "element_size": 0.025}
#: The plate of frame_nested: a steel strip x in [0.05, 3.95], y in [0.55, 0.65] (m),
#: meshed at 0.05 m, pinned at the cross members' mid points; a user mesh file.
PLATE = {"mesh_file": "meshes/deck_plate.vtk", "bounds": (0.05, 3.95, 0.55, 0.65),
         "element_size": 0.05, "points": {"front": (0.05, 0.6), "mid": (2.0, 0.6),
                                          "rear": (3.95, 0.6)}}


def frame_part_parameters(part: str, element_size: float = FRAME["element_size"],
                          center: bool = False, **options) -> dict:
    """Parameters of the ElasticBody2D FMU for one ladder-frame part; ``S.nodes`` is the
    part's node count on every port the scene glues (``center`` only if asked)."""
    from fmus.elastic.parts import frame_port_nodes

    values = {"part": part, "element_size": element_size, "mass": "consistent", "modes": 0}
    values.update(options)
    for port, count in frame_port_nodes(part, element_size).items():
        if port != "center" or center:
            values[f"{port}.nodes"] = count
    return values


def _frame(scene: SceneWriter, system: str = "", center: bool = False,
           cross_element_size: float = FRAME["element_size"],
           element_size: float = FRAME["element_size"]) -> None:
    """The five parts and six edge joints of frame_split, in system ``system`` (rails
    meshed at ``element_size``, cross members at ``cross_element_size``, m)."""
    from fmus.elastic.frame import COMPONENTS, JOINTS

    for part in COMPONENTS:
        outputs = ["load.u_x"] if part == "cross_front" else []
        size = cross_element_size if part.startswith("cross") else element_size
        scene.component(part, "ElasticBody2D",
                        frame_part_parameters(part, size, center=center),
                        outputs=outputs, system=system)
    for a, b in JOINTS:  # a = rail_<side>.<cross>, b = cross_<cross>.<side>
        cross, side = b.split(".")[0].split("_")[1], b.split(".")[1]
        scene.joint(f"{cross}_{side}", a, b, dofs="x y", system=system)


def frame_split(element_size: float = FRAME["element_size"],
                name: str = "frame_split") -> SceneWriter:
    """SCENES.md frame_split: the ladder frame as five FE FMUs glued node to node (every
    part meshed at ``element_size``, m: finer makes heavier subsystems)."""
    scene = SceneWriter(name, "Seed section 2.2.1: a ladder frame split into two "
                        "rails and three cross members, glued node to node on six edges")
    _frame(scene, cross_element_size=element_size, element_size=element_size)
    return scene


#: frame_nonmatching (SCENES.md; seed section 2.2.3): cross members meshed at half the
#: rails' element size, so 9 cross-member nodes face 5 rail nodes on every interface edge.
NONMATCHING_CROSS_SIZE = 0.0125


def frame_nonmatching() -> SceneWriter:
    """SCENES.md frame_nonmatching: frame_split with finer cross members, glued by MLS."""
    scene = SceneWriter("frame_nonmatching", "Seed section 2.2.3: the ladder frame with "
                        "cross members meshed at 0.0125 m and rails at 0.025 m, glued on "
                        "non-matching edges by moving least squares")
    _frame(scene, cross_element_size=NONMATCHING_CROSS_SIZE)
    return scene


def plate_parameters() -> dict:
    """The frame_nested plate: part 'mesh' from the FMU's resources, three one-node ports."""
    values = {"part": "mesh", "mesh_file": PLATE["mesh_file"], "mass": "consistent",
              "load.probe": 1, "load.point_x": PLATE["points"]["mid"][0],
              "load.point_y": PLATE["points"]["mid"][1]}
    for port, (x, y) in PLATE["points"].items():
        values[f"{port}.set"] = f"point {x!r} {y!r}"
        values[f"{port}.nodes"] = 1
    return values


def write_plate_mesh(root: Path = ROOT) -> Path:
    """Write the plate's mesh file (what a user brings) into fmus/elastic/meshes/."""
    from fmus.elastic.geometry import rectangle

    x0, x1, y0, y1 = PLATE["bounds"]
    target = root / "fmus" / "elastic" / PLATE["mesh_file"]
    target.parent.mkdir(parents=True, exist_ok=True)
    rectangle(x0, x1, y0, y1, PLATE["element_size"]).save(str(target))
    return target


def frame_nested(flat: bool = False) -> SceneWriter:
    """SCENES.md frame_nested: the frame as the nested system ``frame`` (level 2), pinned
    (dofs x y) at the cross members' mid points to a plate (level 1). ``flat``: the same
    model with every component and joint in the root system (frame_nested_flat)."""
    name = "frame_nested_flat" if flat else "frame_nested"
    scene = SceneWriter(name, "Seed section 2.2.2: the ladder frame as a nested system "
                        "glued to a plate" + (", flattened" if flat else ""))
    system = "" if flat else scene.nested_system("frame")
    prefix = "" if flat else "frame."
    _frame(scene, system, center=True)
    scene.component("plate", "ElasticBody2D", plate_parameters(), outputs=["load.u_x"])
    for cross in ("front", "mid", "rear"):
        scene.joint(f"plate_{cross}", f"{prefix}cross_{cross}.center", f"plate.{cross}",
                    dofs="x y")
    return scene


def write_frame_scenes(root: Path = ROOT) -> None:
    """frame_split, frame_nested, frame_nested_flat (and the plate's mesh file)."""
    write_plate_mesh(root)
    for scene in (frame_split(), frame_nonmatching(), frame_nested(),
                  frame_nested(flat=True)):
        scene.write(root / "ssp" / scene.name, 0.0, FRAME["stop"], step=FRAME["step"],
                    tolerance=FRAME["tolerance"], maxIterations=20, predictor="linear",
                    refreshAfter=10, perturbation=FRAME["perturbation"])


def write_all(root: Path = ROOT) -> None:
    """(Re)write every generated scene folder."""
    p = SPRING_MASS
    for nonlinear in (False, True):
        scene = spring_mass(nonlinear)
        scene.write(root / "ssp" / scene.name, 0.0, p["stop"], step=p["step"],
                    tolerance=p["tolerance"], maxIterations=20, predictor="linear",
                    refreshAfter=10)
    for n in (10, 100, 1000):
        scene = chain(n)
        scene.write(root / "ssp" / scene.name, 0.0, CHAIN["stop"], step=CHAIN["step"],
                    tolerance=1e-13, maxIterations=20, predictor="linear", refreshAfter=10)
    write_frame_scenes(root)
    from build_fmus.linkage_scenes import write_all as write_linkage_scenes

    write_linkage_scenes(root)


if __name__ == "__main__":
    write_all()
