"""Moving-least-squares transfer between non-matching interface node sets
(seed section 2.2.3).

``T = transfer_matrix(dependent, independent)`` gives, for every dependent node
p, weights T[p, k] over the independent nodes such that a field sampled on the
independent nodes is carried to p as ``sum_k T[p, k] u_k``: compatibility reads
``u_dependent = T u_independent`` and, by virtual work, the forces F on the
dependent nodes reach the independent nodes as ``T^T F``.

Each row is a local linear least-squares fit (basis 1, s in the interface's own
coordinates) weighted by a cubic spline of support ``support`` times the
independent nodes' spacing (default 1: on an edge, the piecewise linear
interpolant, the same tie a conforming mesh transition makes).  Because the basis holds constants and linear
functions, every row sums to one and reproduces the node coordinates exactly;
so the total force and the total moment carried across are conserved exactly.

Written here because no maintained package offers MLS shape functions for a
handful of points; the fit is a few lines of numpy per node.
"""
from __future__ import annotations

import numpy as np


def _interface_coordinates(points: np.ndarray, tolerance: float = 1e-9) -> np.ndarray:
    """Coordinates of points in the interface's own principal directions,
    dropping directions in which the interface has no extent (an edge in 2-D
    is one-dimensional, a face in 3-D two-dimensional)."""
    centred = points - points.mean(axis=0)
    _, singular, directions = np.linalg.svd(centred, full_matrices=False)
    keep = singular > tolerance * max(singular.max(initial=0.0), 1e-300)
    return centred @ directions[keep].T


def _spline(r: np.ndarray) -> np.ndarray:
    """Cubic spline weight of normalised distance r (1 at 0, 0 from r = 1 on)."""
    r = np.abs(r)
    return np.where(r <= 0.5, 2 / 3 - 4 * r ** 2 + 4 * r ** 3,
                    np.where(r < 1.0, 4 / 3 - 4 * r + 4 * r ** 2 - 4 / 3 * r ** 3, 0.0))


def transfer_matrix(dependent: np.ndarray, independent: np.ndarray,
                    support: float = 1.0) -> np.ndarray:
    """MLS weights T (n_dependent x n_independent) from node coordinates (m).

    ``support`` is the radius of influence in units of the independent nodes'
    mean nearest-neighbour spacing.  At 1 an edge's transfer is the piecewise
    linear interpolant (each point sees the two nodes around it); larger values
    smooth over more nodes.  A node that sees fewer nodes than the basis has
    terms widens its own radius until it sees enough.
    """
    dependent = np.atleast_2d(np.asarray(dependent, float))
    independent = np.atleast_2d(np.asarray(independent, float))
    local = _interface_coordinates(np.vstack((independent, dependent)))
    s_ind, s_dep = local[: len(independent)], local[len(independent):]
    gaps = np.linalg.norm(s_ind[:, None] - s_ind[None], axis=2)
    np.fill_diagonal(gaps, np.inf)
    spacing = float(np.mean(gaps.min(axis=1))) if len(independent) > 1 else 1.0
    radius = support * spacing
    basis_ind = np.hstack((np.ones((len(s_ind), 1)), s_ind))
    terms = basis_ind.shape[1]
    rows = []
    for point in s_dep:
        distances = np.linalg.norm(s_ind - point, axis=1)
        nearest = int(np.argmin(distances))
        reach = radius
        while True:
            weights = _spline(distances / reach)
            weights[weights < 1e-12 * weights.max(initial=0.0)] = 0.0  # round-off at the rim
            if np.count_nonzero(weights) >= terms or distances[nearest] <= 1e-9 * reach:
                break
            if reach > 2.0 * distances.max():
                raise ValueError(f"MLS: {len(s_ind)} nodes cannot determine a fit of "
                                 f"{terms} terms at {point}")
            reach *= 1.25  # this node sees too few: widen its own support only
        if np.count_nonzero(weights) < terms:
            # on top of an independent node that alone is in reach: take its value,
            # which is the linear interpolant there
            row = np.zeros(len(s_ind))
            row[nearest] = 1.0
            rows.append(row)
            continue
        moment = basis_ind.T @ (weights[:, None] * basis_ind)
        rows.append(np.linalg.solve(moment, np.r_[1.0, point]) @ (basis_ind.T * weights))
    return np.array(rows)
