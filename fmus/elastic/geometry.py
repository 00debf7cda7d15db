"""Meshes and node sets for elastic bodies.

Geometry comes either from parameters (:func:`rectangle`, :func:`box`) or from a mesh
file (:func:`load_mesh`, anything scikit-fem's ``Mesh.load`` reads through meshio).
Node sets select mesh nodes by index, by a predicate on coordinates, by an
axis-aligned box (:func:`in_box`) or by the name of a boundary stored in the mesh file.
Lengths are in m.
"""
from __future__ import annotations

import contextlib
import io
from pathlib import Path
from typing import Callable, Sequence, Union

import numpy as np
from skfem import (ElementHex1, ElementHexS2, ElementQuad1, ElementQuad2, ElementTetP1,
                   ElementTetP2, ElementTriP1, ElementTriP2, Mesh, MeshHex, MeshQuad, MeshTri)

#: A node set: node indices, a predicate ``f(x) -> bool mask`` on coordinates of shape
#: ``(dim, nnodes)``, or the name of a boundary (facet set) stored in the mesh.
NodeSetSpec = Union[Sequence[int], np.ndarray, Callable[[np.ndarray], np.ndarray], str]

#: Linear (first order) meshes the core supports and their scalar element per order:
#: 1 the linear element, 2 a quadratic one on the same mesh (mid-side nodes added:
#: 9-node quads, 6-node triangles, 20-node serendipity hexahedra, 10-node tetrahedra).
ELEMENTS = {
    "MeshQuad1": {1: ElementQuad1, 2: ElementQuad2},
    "MeshTri1": {1: ElementTriP1, 2: ElementTriP2},
    "MeshHex1": {1: ElementHex1, 2: ElementHexS2},
    "MeshTet1": {1: ElementTetP1, 2: ElementTetP2},
}


def _divisions(low: float, high: float, element_size: float) -> int:
    """Number of equal elements of about ``element_size`` over ``[low, high]``."""
    if not high > low:
        raise ValueError(f"empty interval [{low}, {high}]")
    if not element_size > 0:
        raise ValueError(f"element size must be positive, got {element_size}")
    return max(1, int(round((high - low) / element_size)))


def rectangle(x0: float, x1: float, y0: float, y1: float, element_size: float,
              kind: str = "quad") -> Mesh:
    """A structured mesh of the rectangle ``[x0, x1] x [y0, y1]`` (m).

    ``kind`` is ``"quad"`` (bilinear quadrilaterals) or ``"tri"`` (linear triangles).
    The number of elements per side is the side length over ``element_size``, rounded.
    """
    xs = np.linspace(x0, x1, _divisions(x0, x1, element_size) + 1)
    ys = np.linspace(y0, y1, _divisions(y0, y1, element_size) + 1)
    if kind == "quad":
        return MeshQuad.init_tensor(xs, ys)
    if kind == "tri":
        return MeshTri.init_tensor(xs, ys)
    raise ValueError(f"unknown 2-D element kind {kind!r} (use 'quad' or 'tri')")


def box(x0: float, x1: float, y0: float, y1: float, z0: float, z1: float,
        element_size: float) -> Mesh:
    """A structured trilinear hexahedral mesh of ``[x0,x1] x [y0,y1] x [z0,z1]`` (m)."""
    return MeshHex.init_tensor(
        np.linspace(x0, x1, _divisions(x0, x1, element_size) + 1),
        np.linspace(y0, y1, _divisions(y0, y1, element_size) + 1),
        np.linspace(z0, z1, _divisions(z0, z1, element_size) + 1),
    )


def load_mesh(path: Union[str, Path]) -> Mesh:
    """Read a mesh file with scikit-fem / meshio; any failure is one ValueError naming the file."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"mesh file {path}: no such file")
    chatter = io.StringIO()  # meshio prints its complaints; keep them for the message
    try:
        with contextlib.redirect_stdout(chatter), contextlib.redirect_stderr(chatter):
            mesh = Mesh.load(str(path))
    except (Exception, SystemExit) as error:  # meshio calls sys.exit() on some bad files
        reason = " ".join(chatter.getvalue().split()) or str(error) or type(error).__name__
        raise ValueError(f"mesh file {path}: cannot be read as a mesh ({reason})") from None
    check_mesh(mesh, str(path))
    return mesh


def check_mesh(mesh: Mesh, source: str = "mesh") -> None:
    """Raise ValueError unless ``mesh`` is a non-empty linear tri/quad/tet/hex mesh."""
    if type(mesh).__name__ not in ELEMENTS:
        raise ValueError(f"{source}: unsupported mesh type {type(mesh).__name__} "
                         f"(supported: {', '.join(ELEMENTS)})")
    if mesh.nelements == 0 or not np.all(np.isfinite(mesh.p)):
        raise ValueError(f"{source}: mesh has no elements or non-finite coordinates")


def in_box(low: Sequence[float], high: Sequence[float], tolerance: float = 1e-9):
    """Predicate selecting nodes with ``low - tol <= x <= high + tol`` in every direction."""
    lo = np.asarray(low, dtype=float)[:, None] - tolerance
    hi = np.asarray(high, dtype=float)[:, None] + tolerance

    def select(x: np.ndarray) -> np.ndarray:
        return np.all((x >= lo) & (x <= hi), axis=0)
    return select


def sort_along(points: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """``nodes`` ordered by their coordinates (x first, then y, then z).

    Coordinates are rounded to 1e-9 of the mesh extent first, so two meshes sharing an
    edge list the same physical nodes in the same order despite round-off.
    """
    extent = float(np.ptp(points, axis=1).max()) or 1.0
    keys = np.round(points[:, nodes] / (1e-9 * extent)).astype(np.int64)
    order = np.lexsort(keys[::-1])  # lexsort's primary key is the last row
    return nodes[order]


def resolve_node_set(mesh: Mesh, name: str, spec: NodeSetSpec, points=None,
                     facet_nodes=None) -> np.ndarray:
    """Node indices of node set ``name`` (sorted along the set); ValueError if empty.

    ``points`` (dim, nnodes) are the nodes to choose from (default the mesh vertices;
    a quadratic body passes its mid-side nodes too) and ``facet_nodes(facets)`` the
    nodes on some facets (for a boundary name; default the facets' vertices).
    """
    points = mesh.p if points is None else points
    if isinstance(spec, str):
        if not mesh.boundaries or spec not in mesh.boundaries:
            known = sorted(mesh.boundaries or {})
            raise ValueError(f"node set {name!r}: the mesh has no boundary {spec!r} "
                             f"(boundaries: {known})")
        facets = mesh.boundaries[spec]
        nodes = (np.unique(mesh.facets[:, facets]) if facet_nodes is None
                 else np.unique(facet_nodes(facets)))
    elif callable(spec):
        mask = np.asarray(spec(points), dtype=bool)
        nodes = np.flatnonzero(mask)
    else:
        nodes = np.unique(np.asarray(spec, dtype=np.int64))
        count = points.shape[1]
        if nodes.size and (nodes[0] < 0 or nodes[-1] >= count):
            raise ValueError(f"node set {name!r}: node index out of range 0..{count - 1}")
    if nodes.size == 0:
        raise ValueError(f"node set {name!r} is empty: it selects no node of the mesh")
    return sort_along(points, nodes)


def nearest_node(points: np.ndarray, point: Sequence[float]) -> int:
    """Index of the node (column of ``points``, shape (dim, nnodes)) nearest ``point`` (m)."""
    point = np.asarray(point, dtype=float)
    if point.shape != (points.shape[0],):
        raise ValueError(f"point {point.tolist()} must have {points.shape[0]} coordinates")
    return int(np.argmin(np.sum((points - point[:, None]) ** 2, axis=0)))


def merge_meshes(meshes: Sequence[Mesh], tolerance: float = 1e-9) -> Mesh:
    """One mesh of the given same-type meshes, nodes closer than ``tolerance`` (m) merged.

    Used to mesh an assembly as one body that shares nodes on the interfaces.
    """
    kind = type(meshes[0])
    if any(type(m) is not kind for m in meshes):
        raise ValueError("merge_meshes: all meshes must have the same type")
    points = np.hstack([m.p for m in meshes])
    offsets = np.cumsum([0] + [m.nvertices for m in meshes[:-1]])
    elements = np.hstack([m.t + off for m, off in zip(meshes, offsets)])
    keys = np.round(points / tolerance).astype(np.int64)
    _, first, inverse = np.unique(keys.T, axis=0, return_index=True, return_inverse=True)
    return kind(np.ascontiguousarray(points[:, first]),
                np.ascontiguousarray(inverse.reshape(-1)[elements]))
