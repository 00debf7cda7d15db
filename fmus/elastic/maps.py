"""The interface map B of a body (interface dofs x generalized coordinates), applied
the cheap way when it allows: a body glued at its own mesh nodes has a B that only
picks coordinates (a row of zeros where a glued node is clamped), so B q is an
indexing and B^T F a scatter-add; a Craig-Bampton or rigid-port body has a real
sparse B.  (A scipy sparse product costs several microseconds of Python dispatch
however small it is, and a glued step makes four.)"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp


class InterfaceMap:
    """y = B x and x = B^T y for a sparse ``matrix`` B (SI units follow x and y)."""

    def __init__(self, matrix):
        self.matrix = sp.csr_matrix(matrix)
        self.matrix.eliminate_zeros()
        self.transpose = self.matrix.T.tocsr()
        self.rows, self.columns = self.matrix.shape
        counts = np.diff(self.matrix.indptr)
        picks = self.rows > 0 and bool(np.all(counts <= 1) and np.all(self.matrix.data == 1.0))
        #: the rows that pick a coordinate and the coordinate each picks, when B only
        #: picks coordinates (None otherwise)
        self.picking = np.flatnonzero(counts) if picks else None
        self.picked = self.matrix.indices.copy() if picks else None
        self._every_row = picks and len(self.picking) == self.rows

    def apply(self, x: np.ndarray) -> np.ndarray:
        """B x (x: one vector, or one column per vector)."""
        if self.picked is None:
            return self.matrix @ x
        if self._every_row:
            return x[self.picked]
        y = np.zeros((self.rows,) + x.shape[1:])
        y[self.picking] = x[self.picked]
        return y

    def apply_transpose(self, y: np.ndarray) -> np.ndarray:
        """B^T y (y: one vector): forces on the interface dofs to generalized forces."""
        if self.picked is None:
            return self.transpose @ y
        return np.bincount(self.picked, weights=y[self.picking], minlength=self.columns)
