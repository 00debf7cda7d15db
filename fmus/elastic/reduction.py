"""Reductions of an elastic body: Craig-Bampton, the rigid body, and their error.

Craig-Bampton: the boundary (interface) coordinates stay physical; the interior is
described by the static constraint modes (interior response to a unit boundary
displacement) plus the lowest ``modes`` fixed-interface normal modes (mass normalized).
Rigid: the body's rigid-body motions alone (small rotations), the lowest fidelity.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
from scipy.sparse.linalg import eigsh, splu


def generalized_eigen(stiffness, mass, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Lowest ``count`` eigenpairs of K x = w^2 M x: (w^2 in (rad/s)^2, M-normalized vectors).

    Dense ``eigh`` for small systems, shift-invert Lanczos otherwise. The shift is slightly
    negative so that floating (singular K) systems work too.
    """
    n = stiffness.shape[0]
    count = min(count, n)
    if n <= 400 or count >= n - 1:
        k = stiffness.toarray() if sp.issparse(stiffness) else np.asarray(stiffness)
        m = mass.toarray() if sp.issparse(mass) else np.asarray(mass)
        values, vectors = la.eigh(k, m, subset_by_index=(0, count - 1))
        return values, vectors
    ratio = np.mean(stiffness.diagonal()) / np.mean(mass.diagonal())
    values, vectors = eigsh(sp.csc_matrix(stiffness), k=count, M=sp.csc_matrix(mass),
                            sigma=-1e-6 * ratio, which="LM")
    order = np.argsort(values)
    return values[order], vectors[:, order]


def craig_bampton_basis(stiffness: sp.spmatrix, mass: sp.spmatrix, boundary: np.ndarray,
                        modes: int) -> np.ndarray:
    """Reduction basis Psi with q = Psi [q_boundary; eta] (dense, shape (n, nb + modes)).

    ``boundary`` are the kept coordinate indices; the rows of Psi at ``boundary`` are the
    identity, so the interface stays physical. Needs a non-singular interior stiffness
    (the boundary and the clamps must stop every rigid-body motion of the interior).
    """
    if modes < 0:
        raise ValueError(f"number of Craig-Bampton modes must be >= 0, got {modes}")
    stiffness, mass = sp.csr_matrix(stiffness), sp.csr_matrix(mass)
    n = stiffness.shape[0]
    boundary = np.asarray(boundary)
    interior = np.setdiff1d(np.arange(n), boundary)
    if modes > interior.size:
        raise ValueError(f"{modes} Craig-Bampton modes asked, the interior has only "
                         f"{interior.size} coordinates")
    k_ii = stiffness[interior][:, interior].tocsc()
    k_ib = stiffness[interior][:, boundary].toarray()
    basis = np.zeros((n, boundary.size + modes))
    basis[boundary, np.arange(boundary.size)] = 1.0
    if interior.size:
        basis[np.ix_(interior, np.arange(boundary.size))] = -splu(k_ii).solve(k_ib)
    if modes:
        _, vectors = generalized_eigen(k_ii, mass[interior][:, interior], modes)
        basis[np.ix_(interior, boundary.size + np.arange(modes))] = vectors
    return basis


def rigid_body_basis(transformation: sp.spmatrix, points: np.ndarray, node_dofs: np.ndarray,
                     name: str = "body") -> np.ndarray:
    """Generalized coordinates of the rigid-body motions, shape (n, 3) in 2-D (x, y, rz),
    (n, 6) in 3-D: q with ``transformation @ q`` the motion of every node (``points``,
    (dim, nnodes), m; ``node_dofs`` their dofs), rotations about the nodes' centroid.
    ValueError if the constraints (clamps) stop a rigid-body motion."""
    dim = points.shape[0]
    d = points - points.mean(axis=1, keepdims=True)
    zero, one = np.zeros(d.shape[1]), np.ones(d.shape[1])
    if dim == 2:  # columns x, y, rz; rows u_x, u_y
        rows = [[one, zero, -d[1]], [zero, one, d[0]]]
    else:  # columns x, y, z, rx, ry, rz: u = t + theta x r
        rows = [[one, zero, zero, zero, d[2], -d[1]],
                [zero, one, zero, -d[2], zero, d[0]],
                [zero, zero, one, d[1], -d[0], zero]]
    T = sp.csr_matrix(transformation)
    motion = np.zeros((T.shape[0], len(rows[0])))
    for c in range(dim):
        motion[node_dofs[c]] = np.column_stack(rows[c])
    # T has full column rank: the least-squares q is exact when the motion is admissible
    basis = splu(sp.csc_matrix(T.T @ T)).solve(np.asarray(T.T @ motion))
    if np.linalg.norm(T @ basis - motion) > 1e-9 * np.linalg.norm(motion):
        raise ValueError(f"{name}: a rigid body cannot have clamped nodes")
    return basis


@dataclass(frozen=True)
class ReductionError:
    """Relative errors of a reduced model against the full one.

    ``response``: max over time of |y_reduced - y_full| / max |y_full|, y being the
    interface displacements and probe outputs; ``frequency``: largest relative error of
    the lowest ``len(frequencies_full)`` natural frequencies; frequencies in Hz.
    """

    modes: int
    response: float
    frequency: float
    frequencies_full: np.ndarray
    frequencies_reduced: np.ndarray


def craig_bampton_error(build: Callable[[Optional[int]], "object"], modes: int,
                        step_size: float, steps: int,
                        interface_forces: Optional[Callable[[float], np.ndarray]] = None,
                        frequencies: int = 4) -> ReductionError:
    """Compare ``build(modes)`` (reduced) with ``build(None)`` (full) from rest.

    Both bodies are stepped ``steps`` times with ``step_size`` (s), their own loads and
    ``interface_forces(t)`` (N, default zero) held over each step.
    """
    bodies = [build(None), build(modes)]
    histories = []
    for body in bodies:
        reference = body.interface_kinematics()[0]
        body.initialize(0.0)
        rows = []
        for n in range(steps):
            time = n * step_size
            if interface_forces is not None:
                body.set_interface_forces(interface_forces(time + step_size))
            body.step(time, step_size)
            outputs = np.array(list(body.outputs().values()))
            rows.append(np.concatenate([body.interface_kinematics()[0] - reference, outputs]))
        histories.append(np.array(rows))
    full, reduced = histories
    scale = np.max(np.abs(full))
    response = float(np.max(np.abs(reduced - full)) / scale) if scale > 0 else np.nan
    f_full = bodies[0].natural_frequencies(frequencies)
    f_reduced = bodies[1].natural_frequencies(frequencies)
    count = min(f_full.size, f_reduced.size)
    elastic = f_full[:count] > 1e-6 * f_full[:count].max()  # skip rigid-body (zero) modes
    error = np.abs(f_reduced[:count] - f_full[:count])[elastic] / f_full[:count][elastic]
    return ReductionError(modes, response, float(np.max(error)), f_full, f_reduced)
