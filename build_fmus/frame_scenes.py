"""The ladder-frame scenes as data (SCENES.md frame_split, frame_nonmatching,
frame_nested, frame_nested_flat; seed section 2.2).

Every part is the generic ``ElasticBody`` FMU given a mesh file and parameters: the rails
and cross members are rectangles meshed at 0.025 m (cross members at 0.0125 m in
frame_nonmatching), files of the scene itself (resources/meshes/, named by the
``mesh_file`` values: dsim hands the FMU their paths); clamps, ports, the load and its
probe are node-set strings and numbers in each part's .ssv. The geometry is :mod:`dsim.fmus.elastic.frame`'s, so the
glued scenes and the monolithic frame describe the same body.

Port slots: a rail's ``port1``, ``port2``, ``port3`` are its front, mid and rear edges
facing the cross members; a cross member's ``port1`` and ``port2`` its edges on
rail_left and rail_right, ``port3`` its mid point (frame_nested).
"""
from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Callable

import numpy as np

from dsim.build_fmus.scenes import ROOT, SceneWriter, write_parameter_sets
from dsim.fmus.elastic import frame
from dsim.fmus.elastic.body_spec import BodySpec, port_node_counts
from dsim.fmus.elastic.geometry import rectangle

#: frame_split / frame_nested: Newmark, H = 1e-4 s, 0 to 0.2 s. The glued quantities are
#: global positions (about 1 m) while the response is about 1e-5 m: the tolerance is
#: absolute and near round-off, and the flexibility is measured with a large force
#: perturbation (the bodies are linear, so it has no truncation error).
FRAME = {"step": 1e-4, "stop": 0.2, "tolerance": 1e-14, "perturbation": 1.0,
         "element_size": 0.025}
#: frame_nonmatching: cross members at half the rails' size (9 nodes face 5 on an edge).
NONMATCHING_CROSS_SIZE = 0.0125
#: frame_split's fidelity parameter sets: every part at twice the element size (3 nodes
#: on an interface edge), or Craig-Bampton with N fixed-interface modes per part
COARSE_SIZE = 0.05
FIDELITY = {"coarse": {"element_size": COARSE_SIZE},
            "cb10": {"fidelity": "craig_bampton", "modes": 10},
            "cb40": {"fidelity": "craig_bampton", "modes": 40}}
#: The plate of frame_nested: a steel strip x in [0.05, 3.95], y in [0.55, 0.65] (m),
#: meshed at 0.05 m, pinned at the cross members' mid points.
PLATE = {"mesh_file": "resources/meshes/deck_plate.vtk",
         "bounds": (0.05, 3.95, 0.55, 0.65),
         "element_size": 0.05, "points": {"front": (0.05, 0.6), "mid": (2.0, 0.6),
                                          "rear": (3.95, 0.6)}}
RAIL_PORTS = {"front": "port1", "mid": "port2", "rear": "port3"}
CROSS_PORTS = {"left": "port1", "right": "port2", "center": "port3"}
PLATE_PORTS = {"front": "port1", "mid": "port2", "rear": "port3"}
#: y of the cross members' mid points (where frame_nested pins the plate).
CENTER_Y = 0.5 * (frame.RAIL_Y["left"][1] + frame.RAIL_Y["right"][0])


def mesh_file(part: str, element_size: float) -> str:
    """The mesh file of a frame part: its path in the scene."""
    return f"resources/meshes/frame_{part}_{element_size:g}.vtk"


def _rectangle(part: str) -> tuple[float, float, float, float]:
    """x0, x1, y0, y1 (m) of a frame part."""
    kind, side = part.split("_")
    if kind == "rail":
        return (0.0, frame.LENGTH) + frame.RAIL_Y[side]
    return frame.CROSS_X[side] + (frame.RAIL_Y["left"][1], frame.RAIL_Y["right"][0])


def _rectangle_mesh(bounds, element_size: float) -> Callable[[Path], None]:
    """What writes a rectangle x0, x1, y0, y1 (m) meshed at ``element_size`` (m)."""
    return lambda target: rectangle(*bounds, element_size).save(str(target))


def part_mesh(part: str, element_size: float) -> Callable[[Path], None]:
    """What writes the mesh file of a frame part meshed at ``element_size`` (m)."""
    return _rectangle_mesh(_rectangle(part), element_size)


def _edge(x0: float, x1: float, y: float) -> str:
    return f"box {x0!r} {y!r} {x1!r} {y!r}"


def _with_node_counts(values: dict, save: Callable[[Path], None]) -> dict:
    """``values`` plus ``S.nodes`` of every node-set port, counted on the mesh that
    ``save`` writes."""
    with tempfile.TemporaryDirectory() as folder:
        mesh = Path(folder) / Path(values["mesh_file"]).name
        save(mesh)
        spec = BodySpec(mesh_file=str(mesh))
        spec.sets.update({key[:-len(".set")]: value for key, value in values.items()
                          if key.endswith(".set")})
        counts = port_node_counts(spec)
    return {**values, **{f"{port}.nodes": count for port, count in counts.items()}}


def part_parameters(part: str, element_size: float = FRAME["element_size"],
                    center: bool = False) -> dict:
    """ElasticBody parameters of one ladder-frame part (SCENES.md): mesh file, steel,
    clamps, port node sets (``center``: the cross member's mid point as port3), and on
    cross_front the load F_x = 1000 sin(50 pi t) N at (0.05, 0.6) with its probe."""
    x0, x1, y0, y1 = _rectangle(part)
    values = {"mesh_file": mesh_file(part, element_size), "thickness": frame.THICKNESS,
              "youngs_modulus": 210e9, "poisson_ratio": 0.3, "density": 7850.0,
              "mass": "consistent", "fidelity": "full"}
    kind, side = part.split("_")
    if kind == "rail":
        values["clamped"] = f"box 0.0 {y0!r} 0.0 {y1!r}; box {x1!r} {y0!r} {x1!r} {y1!r}"
        edge_y = y1 if side == "left" else y0  # the rail edge facing the cross members
        for cross, (cx0, cx1) in frame.CROSS_X.items():
            values[f"{RAIL_PORTS[cross]}.set"] = _edge(cx0, cx1, edge_y)
    else:
        values[f"{CROSS_PORTS['left']}.set"] = _edge(x0, x1, y0)
        values[f"{CROSS_PORTS['right']}.set"] = _edge(x0, x1, y1)
        if center:
            values[f"{CROSS_PORTS['center']}.set"] = f"point {0.5 * (x0 + x1)!r} {CENTER_Y!r}"
    if part == "cross_front":
        (lx, ly), load = frame.LOAD_POINT, frame.LOAD
        assert load.omega == 2.0 * np.pi * 25.0
        values.update({"load.point": f"{lx!r} {ly!r}", "load.F_x": load.amplitude,
                       "load_frequency": 25.0, "load.probe": 1})  # 50 pi rad/s
    return _with_node_counts(values, part_mesh(part, element_size))


def _frame(scene: SceneWriter, system: str = "", center: bool = False,
           cross_element_size: float = FRAME["element_size"],
           element_size: float = FRAME["element_size"]) -> None:
    """The five parts and six edge joints of frame_split, in system ``system`` (rails
    meshed at ``element_size``, cross members at ``cross_element_size``, m), with the
    parts' meshes."""
    for part in frame.COMPONENTS:
        outputs = ["load.u_x"] if part == "cross_front" else []
        size = cross_element_size if part.startswith("cross") else element_size
        scene.file(mesh_file(part, size), part_mesh(part, size))
        scene.component(part, "ElasticBody", part_parameters(part, size, center=center),
                        outputs=outputs, system=system)
    for a, b in frame.JOINTS:  # a = rail_<side>.<cross>, b = cross_<cross>.<side>
        rail, cross_edge = a.split(".")
        member, side = b.split(".")
        scene.joint(f"{cross_edge}_{side}", f"{rail}.{RAIL_PORTS[cross_edge]}",
                    f"{member}.{CROSS_PORTS[side]}", dofs="x y", system=system)


def frame_split(element_size: float = FRAME["element_size"],
                name: str = "frame_split") -> SceneWriter:
    """SCENES.md frame_split: the ladder frame as five FE FMUs glued node to node (every
    part meshed at ``element_size``, m: finer makes heavier subsystems), with the
    coarse meshes of its fidelity set ``coarse``."""
    scene = SceneWriter(name, "Seed section 2.2.1: a ladder frame split into two "
                        "rails and three cross members, glued node to node on six edges")
    _frame(scene, cross_element_size=element_size, element_size=element_size)
    for part in frame.COMPONENTS:
        scene.file(mesh_file(part, COARSE_SIZE), part_mesh(part, COARSE_SIZE))
    return scene


def frame_nonmatching() -> SceneWriter:
    """SCENES.md frame_nonmatching: frame_split with finer cross members, glued by MLS."""
    scene = SceneWriter("frame_nonmatching", "Seed section 2.2.3: the ladder frame with "
                        "cross members meshed at 0.0125 m and rails at 0.025 m, glued on "
                        "non-matching edges by moving least squares")
    _frame(scene, cross_element_size=NONMATCHING_CROSS_SIZE)
    return scene


def plate_mesh() -> Callable[[Path], None]:
    """What writes the frame_nested plate's mesh file."""
    return _rectangle_mesh(PLATE["bounds"], PLATE["element_size"])


def plate_parameters() -> dict:
    """The frame_nested plate: a user mesh file, three one-node ports, a probe."""
    mid = PLATE["points"]["mid"]
    values = {"mesh_file": PLATE["mesh_file"], "thickness": frame.THICKNESS,
              "mass": "consistent", "load.probe": 1, "load.point": f"{mid[0]!r} {mid[1]!r}"}
    for port, (x, y) in PLATE["points"].items():
        values[f"{PLATE_PORTS[port]}.set"] = f"point {x!r} {y!r}"
    return _with_node_counts(values, plate_mesh())


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
    scene.file(PLATE["mesh_file"], plate_mesh())
    scene.component("plate", "ElasticBody", plate_parameters(), outputs=["load.u_x"])
    for cross in ("front", "mid", "rear"):
        scene.joint(f"plate_{cross}", f"{prefix}cross_{cross}.{CROSS_PORTS['center']}",
                    f"plate.{PLATE_PORTS[cross]}", dofs="x y")
    return scene


def fidelity_values(name: str) -> dict:
    """frame_split's parameter set ``name``: the parameters it changes, per part."""
    change = FIDELITY[name]
    values = {}
    for part in frame.COMPONENTS:
        if "element_size" in change:
            default = part_parameters(part)
            coarse = part_parameters(part, change["element_size"])
            values.update({f"{part}.{k}": v for k, v in coarse.items() if default[k] != v})
        else:
            values.update({f"{part}.{k}": v for k, v in change.items()})
    return values


def write_frame_scenes(root: Path = ROOT) -> None:
    """frame_split (with its fidelity sets), frame_nonmatching, frame_nested,
    frame_nested_flat, each with its meshes."""
    for scene in (frame_split(), frame_nonmatching(), frame_nested(),
                  frame_nested(flat=True)):
        scene.write(root / "ssp" / scene.name, 0.0, FRAME["stop"], step=FRAME["step"],
                    tolerance=FRAME["tolerance"], maxIterations=20, predictor="linear",
                    refreshAfter=10, perturbation=FRAME["perturbation"])
    write_parameter_sets(root / "ssp" / "frame_split",
                         {name: fidelity_values(name) for name in FIDELITY})


if __name__ == "__main__":
    write_frame_scenes()
