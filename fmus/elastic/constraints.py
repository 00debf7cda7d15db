"""Linear constraints as a transformation u = T q (master-slave elimination).

Full nodal displacements ``u`` (m) are written in generalized coordinates ``q``:
- clamped nodes have no column (u = 0);
- nodes of a rigid set follow a reference point with translation and small rotation,
  u = u0 + theta x r (2-D: theta = rz), r being the node's offset from the reference point;
- tied nodes (hanging nodes of a non-conforming mesh) are fixed linear combinations of
  other nodes;
- every other dof is its own column.
Columns are ordered: independent nodal dofs by full index, then each rigid set's
reference dofs (x y rz in 2-D, x y z rx ry rz in 3-D).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

ROTATIONS = {2: ("rz",), 3: ("rx", "ry", "rz")}
TRANSLATIONS = {2: ("x", "y"), 3: ("x", "y", "z")}


@dataclass
class Transformation:
    """u_full = matrix @ q. ``rigid_columns[name]`` are q indices of a rigid set's dofs."""

    matrix: sp.csr_matrix
    rigid_columns: dict[str, np.ndarray] = field(default_factory=dict)
    rigid_points: dict[str, np.ndarray] = field(default_factory=dict)


def rigid_rows(offset: np.ndarray) -> np.ndarray:
    """d u / d (translation, rotation) of a point at ``offset`` (m) from the reference.

    Shape (dim, dim + nrot): identity for translations, theta x r for small rotations.
    """
    dim = offset.size
    if dim == 2:
        rx, ry = offset
        return np.array([[1.0, 0.0, -ry], [0.0, 1.0, rx]])
    rx, ry, rz = offset
    cross = np.array([[0.0, rz, -ry], [-rz, 0.0, rx], [ry, -rx, 0.0]])  # theta x r
    return np.hstack([np.eye(3), cross])


def build_transformation(nodal_dofs: np.ndarray, points: np.ndarray,
                         clamped: np.ndarray,
                         rigid: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
                         ties: dict[int, tuple[np.ndarray, np.ndarray]] | None = None,
                         ) -> Transformation:
    """Build T for ``nodal_dofs`` (dim, nnodes) and node ``points`` (dim, nnodes).

    ``clamped``: node indices with u = 0. ``rigid``: name -> (node indices, reference
    point). ``ties``: slave node -> (master nodes, weights), u_slave = sum w u_master.
    Raises ValueError when a node is constrained twice.
    """
    rigid = rigid or {}
    ties = ties or {}
    dim, nnodes = nodal_dofs.shape
    nfull = nodal_dofs.size
    owner = np.full(nnodes, "", dtype=object)  # which constraint took each node
    for node in clamped:
        owner[node] = "clamped"
    for name, (nodes, _) in rigid.items():
        taken = nodes[owner[nodes] != ""]
        if taken.size:
            raise ValueError(f"rigid node set {name!r}: node {taken[0]} is already "
                             f"{owner[taken[0]] or 'constrained'}")
        owner[nodes] = f"rigid set {name!r}"
    for slave in ties:
        if owner[slave] != "":
            raise ValueError(f"tied node {slave} is already {owner[slave]}")
        owner[slave] = "tied"

    independent = np.sort(nodal_dofs[:, owner == ""].ravel())
    column_of = np.full(nfull, -1)
    column_of[independent] = np.arange(independent.size)
    ncols = independent.size
    rows, cols, vals = [independent], [np.arange(independent.size)], [np.ones(independent.size)]

    transformation = Transformation(matrix=None)
    nref = dim + len(ROTATIONS[dim])
    for name, (nodes, point) in rigid.items():
        point = np.asarray(point, dtype=float)
        columns = ncols + np.arange(nref)
        ncols += nref
        transformation.rigid_columns[name] = columns
        transformation.rigid_points[name] = point
        for node in nodes:
            block = rigid_rows(points[:, node] - point)
            r, c = np.nonzero(block)
            rows.append(nodal_dofs[r, node])
            cols.append(columns[c])
            vals.append(block[r, c])
    partial = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                            shape=(nfull, ncols))
    if ties:  # a slave dof's row is the weighted sum of its masters' rows
        combine = sp.lil_matrix((nfull, nfull))
        for slave, (masters, weights) in ties.items():
            if np.any(owner[np.asarray(masters)] == "tied"):
                raise ValueError(f"tied node {slave}: a master node is itself tied")
            for c in range(dim):
                combine[nodal_dofs[c, slave], nodal_dofs[c, masters]] = np.asarray(weights)
        partial = partial + combine.tocsr() @ partial
    transformation.matrix = partial.tocsr()
    return transformation
