"""The topology of a glued problem: which glued subsystem dof feels which joint force.

Joint force entry r (one per glued dof of every joint) acts on the subsystem
dofs named by the incidence matrices C_i (n_i x n_F): +1 on side b, -1 on side a,
moving-least-squares weights on non-matching node sets (section 2.2.3).  The
gluing algorithm needs three products of them, all here: the subsystems' forces
C_i F, the joint-side differences sum_i C_i^T x_i, and the projected flexibility
sum_i C_i^T G_i C_i (eqs. 4.24-4.27), which costs one sparse product over all
subsystems together, so that it grows linearly with their number.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp


class GluingLayout:
    """Incidence, measure weights and labels of the glued dofs.

    ``incidence[i]`` is C_i of the i-th glued subsystem; ``weights`` is n_F x 3
    (w_u, w_v, w_a) and ``measures`` the measure's name per dof; ``labels[r]`` names
    force entry r as ``joint.f_dof`` (the CSV column); ``joint_of[r]`` the joint.
    """

    def __init__(self, incidence, weights, labels, joint_of, measures=None, sizes=None):
        """``incidence``: the C_i as a list of matrices, or (with ``sizes``, each
        C_i's row count) all of them stacked in one matrix, as :func:`~dsim.master.
        planning.assembly.assemble` builds it (one sparse matrix for 10,000
        subsystems rather than 10,000 small ones)."""
        self.labels = list(labels)
        self.size = len(self.labels)
        if sizes is None:
            blocks = [sp.csr_matrix(c) for c in incidence]
            sizes = [c.shape[0] for c in blocks]
            # one stacked C (all glued dofs x n_F): an iteration costs a few sparse products
            incidence = (sp.vstack(blocks).tocsr() if blocks
                         else sp.csr_matrix((0, self.size)))
        sizes = [int(n) for n in sizes]
        self.offsets = np.cumsum(sizes)[:-1] if sizes else np.zeros(0, dtype=int)
        self._bounds = list(zip(np.r_[0, self.offsets].astype(int),
                                np.r_[self.offsets, sum(sizes)].astype(int)))
        self.stacked = sp.csr_matrix(incidence)
        self.stacked_t = self.stacked.T.tocsr()
        self.stacked_abs_t = abs(self.stacked_t)
        self.weights = np.asarray(weights, dtype=float).reshape(-1, 3)
        self.joint_of = list(joint_of)
        #: the measure's name per dof ("displacement", "velocity", ...)
        self.measures = list(measures or ["displacement"] * self.size)

    @property
    def incidence(self) -> list:
        """C_i of each glued subsystem (rows of the stacked matrix)."""
        return [self.stacked[start:stop] for start, stop in self._bounds]

    def differences(self, kinematics, magnitudes: bool = True):
        """Per kind (u, v, a): sum_i C_i^T x_i (= x_b - x_a per joint dof) and the
        matching magnitude sum |C_i|^T |x_i| used by the relative tolerance (None
        unless asked); both 3 x n_F."""
        stacked = np.zeros((self.stacked.shape[0], 3))
        for kind in range(3):
            parts = [values[kind] for values in kinematics]
            if all(x is not None for x in parts):
                if parts:
                    stacked[:, kind] = np.concatenate(parts)
            else:  # a kind some subsystems lack (not read): zero there
                for x, (start, stop) in zip(parts, self._bounds):
                    if x is not None:
                        stacked[start:stop, kind] = x
        differences = (self.stacked_t @ stacked).T
        if not magnitudes:
            return differences, None
        return differences, (self.stacked_abs_t @ np.abs(stacked)).T

    def local_forces(self, forces):
        """Split the joint forces F into each glued subsystem's forces C_i F."""
        local = self.stacked @ forces
        return [local[start:stop] for start, stop in self._bounds]

    def project(self, matrices) -> sp.csr_matrix:
        """sum_i C_i^T M_i C_i (n_F x n_F) of one dense n_i x n_i matrix per glued
        subsystem: a flexibility G_i, or a start sensitivity d a_i / d f_i."""
        return (self.stacked_t @ _block_diagonal(matrices) @ self.stacked).tocsr()


def _block_diagonal(matrices) -> sp.csr_matrix:
    """The block-diagonal sparse matrix of dense square blocks, their non-zero entries
    only (as ``scipy.sparse.block_diag`` of each block's csr_matrix, which builds one
    sparse matrix per block: a thousand subsystems took a second per refresh)."""
    if not len(matrices):
        return sp.csr_matrix((0, 0))
    rows, cols, data, start = [], [], [], 0
    for matrix in matrices:
        block = np.atleast_2d(np.asarray(matrix, dtype=float))
        r, c = np.nonzero(block)
        rows.append(r + start)
        cols.append(c + start)
        data.append(block[r, c])
        start += block.shape[0]
    return sp.csr_matrix((np.concatenate(data), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(start, start))
