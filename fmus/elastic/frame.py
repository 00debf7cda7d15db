"""The planar ladder frame of SCENES.md (frame_split, frame_nonmatching; seed section 2.2).

Plane stress steel, thickness 0.01 m. Rails x in [0, 4], y in [0, 0.1] (``rail_left``)
and y in [1.1, 1.2] (``rail_right``); cross members y in [0.1, 1.1] at x in [0, 0.1]
(``cross_front``), [1.95, 2.05] (``cross_mid``), [3.9, 4.0] (``cross_rear``). The rail
ends (edges x = 0 and x = 4 of both rails) are clamped. Load F_x = 1000 sin(50 pi t) N
at (0.05, 0.6), where ``cross_front`` has the probe ``load``. Bilinear quads, consistent
mass, no damping, Newmark average acceleration, H = 1e-4 s, 0 to 0.2 s.

Ports: each rail has ``front``, ``mid``, ``rear`` (its edge facing the cross members),
each cross member ``left`` (edge y = 0.1, on rail_left) and ``right`` (edge y = 1.1, on
rail_right). :data:`JOINTS` pairs them: ``("rail_left.front", "cross_front.left")`` ...
"""
from __future__ import annotations

import time as clock
from dataclasses import dataclass
from typing import Optional

import numpy as np

from .assembly import STEEL
from .core import ElasticBody, PointLoad
from .geometry import in_box, merge_meshes, rectangle

LENGTH, RAIL_WIDTH, WIDTH = 4.0, 0.1, 1.2
THICKNESS = 0.01
CROSS_X = {"front": (0.0, 0.1), "mid": (1.95, 2.05), "rear": (3.9, 4.0)}
RAIL_Y = {"left": (0.0, 0.1), "right": (1.1, 1.2)}
LOAD_POINT = (0.05, 0.6)
LOAD = PointLoad(LOAD_POINT, "x", amplitude=1000.0, omega=50.0 * np.pi)
STEP_SIZE, STOP_TIME = 1e-4, 0.2
ELEMENT_SIZE = 0.025
COMPONENTS = ("rail_left", "rail_right", "cross_front", "cross_mid", "cross_rear")
#: The six glued edges as (a, b) = ("component.port", "component.port").
JOINTS = tuple((f"rail_{side}.{cross}", f"cross_{cross}.{side}")
               for cross in CROSS_X for side in RAIL_Y)


def _rail_sets(side: str) -> dict:
    """Clamped ends and the three interface edges of rail ``side``."""
    y0, y1 = RAIL_Y[side]
    edge_y = y1 if side == "left" else y0  # the rail edge facing the cross members
    sets = {"clamped": lambda x: (np.isclose(x[0], 0.0) | np.isclose(x[0], LENGTH))}
    for cross, (x0, x1) in CROSS_X.items():
        sets[cross] = in_box((x0, edge_y), (x1, edge_y))
    return sets


def _cross_sets(cross: str) -> dict:
    x0, x1 = CROSS_X[cross]
    y_left, y_right = RAIL_Y["left"][1], RAIL_Y["right"][0]
    return {"left": in_box((x0, y_left), (x1, y_left)),
            "right": in_box((x0, y_right), (x1, y_right))}


def rail(side: str, element_size: float = ELEMENT_SIZE, *, mass: str = "consistent",
         modes: Optional[int] = None) -> ElasticBody:
    """Rail ``side`` ('left': y in [0, 0.1], 'right': y in [1.1, 1.2]), ends clamped."""
    y0, y1 = RAIL_Y[side]
    return ElasticBody(rectangle(0.0, LENGTH, y0, y1, element_size), STEEL,
                       thickness=THICKNESS, mass=mass, node_sets=_rail_sets(side),
                       clamped=["clamped"], ports=list(CROSS_X), modes=modes,
                       name=f"rail_{side}")


def cross_member(cross: str, element_size: float = ELEMENT_SIZE, *, mass: str = "consistent",
                 modes: Optional[int] = None) -> ElasticBody:
    """Cross member ``cross`` ('front', 'mid', 'rear'); the front one carries the load."""
    x0, x1 = CROSS_X[cross]
    front = cross == "front"
    return ElasticBody(rectangle(x0, x1, RAIL_Y["left"][1], RAIL_Y["right"][0], element_size),
                       STEEL, thickness=THICKNESS, mass=mass, node_sets=_cross_sets(cross),
                       ports=["left", "right"], loads=[LOAD] if front else [],
                       probes={"load": LOAD_POINT} if front else {}, modes=modes,
                       name=f"cross_{cross}")


def rail_left(element_size: float = ELEMENT_SIZE, **options) -> ElasticBody:
    return rail("left", element_size, **options)


def rail_right(element_size: float = ELEMENT_SIZE, **options) -> ElasticBody:
    return rail("right", element_size, **options)


def cross_front(element_size: float = ELEMENT_SIZE, **options) -> ElasticBody:
    return cross_member("front", element_size, **options)


def cross_mid(element_size: float = ELEMENT_SIZE, **options) -> ElasticBody:
    return cross_member("mid", element_size, **options)


def cross_rear(element_size: float = ELEMENT_SIZE, **options) -> ElasticBody:
    return cross_member("rear", element_size, **options)


def frame_parts(rail_element_size: float = ELEMENT_SIZE,
                cross_element_size: Optional[float] = None, **options) -> dict[str, ElasticBody]:
    """The five part bodies by component name (frame_nonmatching: cross size 0.0125)."""
    cross_size = cross_element_size or rail_element_size
    return {"rail_left": rail_left(rail_element_size, **options),
            "rail_right": rail_right(rail_element_size, **options),
            "cross_front": cross_front(cross_size, **options),
            "cross_mid": cross_mid(cross_size, **options),
            "cross_rear": cross_rear(cross_size, **options)}


def frame_body(element_size: float = ELEMENT_SIZE, cross_element_size: Optional[float] = None,
               *, mass: str = "consistent") -> ElasticBody:
    """The whole frame meshed as one body (nodes shared on the interfaces).

    With a finer ``cross_element_size`` the cross members' extra edge nodes are hanging
    nodes tied linearly to the rail edge (a conforming reference for frame_nonmatching).
    """
    cross_size = cross_element_size or element_size
    meshes = [rectangle(0.0, LENGTH, y0, y1, element_size) for y0, y1 in RAIL_Y.values()]
    meshes += [rectangle(x0, x1, RAIL_Y["left"][1], RAIL_Y["right"][0], cross_size)
               for x0, x1 in CROSS_X.values()]
    mesh = merge_meshes(meshes, tolerance=1e-6 * min(element_size, cross_size))
    rail_nodes = np.unique(mesh.t[:, :meshes[0].nelements + meshes[1].nelements])

    def rail_ends(x):  # x = 0 and x = 4 on the rails only, not the cross members' edges
        on_rail = (x[1] <= RAIL_Y["left"][1] + 1e-9) | (x[1] >= RAIL_Y["right"][0] - 1e-9)
        return on_rail & (np.isclose(x[0], 0.0) | np.isclose(x[0], LENGTH))
    return ElasticBody(mesh, STEEL, thickness=THICKNESS, mass=mass,
                       node_sets={"clamped": rail_ends}, clamped=["clamped"],
                       loads=[LOAD], probes={"load": LOAD_POINT},
                       ties=_hanging_node_ties(mesh.p, rail_nodes), name="frame")


def _hanging_node_ties(points: np.ndarray, rail_nodes: np.ndarray) -> dict:
    """Cross-member nodes on a rail edge that are not rail nodes: linear interpolation
    between the two rail nodes around them on that edge."""
    ties = {}
    for edge_y in (RAIL_Y["left"][1], RAIL_Y["right"][0]):
        on_edge = np.flatnonzero(np.isclose(points[1], edge_y))
        masters = np.intersect1d(on_edge, rail_nodes)
        masters = masters[np.argsort(points[0, masters])]
        for node in np.setdiff1d(on_edge, rail_nodes):
            x = points[0, node]
            right = int(np.searchsorted(points[0, masters], x))
            a, b = masters[right - 1], masters[right]
            weight = (x - points[0, a]) / (points[0, b] - points[0, a])
            ties[int(node)] = ([a, b], [1.0 - weight, weight])
    return ties


@dataclass(frozen=True)
class FrameResult:
    """Time (s) and load-point x displacement (m), one row per step including t = 0."""

    time: np.ndarray
    load_u_x: np.ndarray
    wall_time: float


def simulate(body: ElasticBody, output: str, step_size: float, stop_time: float,
             start_time: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Run ``body`` alone from rest and record ``output`` at every step (t = start + n h)."""
    steps = int(round((stop_time - start_time) / step_size))
    times = start_time + step_size * np.arange(steps + 1)
    values = np.empty(steps + 1)
    body.initialize(start_time)
    values[0] = body.outputs()[output]
    for n in range(steps):
        body.step(times[n], step_size)
        values[n + 1] = body.outputs()[output]
    return times, values


def monolithic_frame(element_size: float = ELEMENT_SIZE, step_size: float = STEP_SIZE,
                     stop_time: float = STOP_TIME, *, cross_element_size: Optional[float] = None,
                     mass: str = "consistent") -> FrameResult:
    """The frame reference: one body, same Newmark rule and step, load-point u_x (m).

    ``element_size`` is the rails' (and by default the cross members') element size.
    """
    start = clock.perf_counter()
    body = frame_body(element_size, cross_element_size, mass=mass)
    times, values = simulate(body, "load.u_x", step_size, stop_time)
    return FrameResult(times, values, clock.perf_counter() - start)
