"""Sparse constraint rows assembled from triplets, for the linear programs of the limited planner.

Rows are added one at a time or in blocks of equal length; each row keeps a
right-hand side, optional metadata ``(kind, k, index, sign)`` (which limit
it is, so that dual values can be mapped back) and a stamp ``s``: in the
primal LPs the time offset (s) of a cut row within its sample interval, in
the dual of :mod:`.limit_dual` a position in time (samples) that orders the
rows for a banded factorisation.  Single entries can be added to existing rows
(the dual's columns are built row by row in :mod:`.limit_dual`).
"""

from __future__ import annotations

import numpy as np
from scipy import sparse

#: Metadata of rows added without any.
NO_META = (-1.0, 0.0, 0.0, 0.0)


class SparseRows:
    """Rows of a sparse matrix with right-hand sides, metadata and time offsets."""

    def __init__(self) -> None:
        self.r: list[np.ndarray] = []
        self.c: list[np.ndarray] = []
        self.v: list[np.ndarray] = []
        self.b: list[np.ndarray] = []
        self.meta: list[np.ndarray] = []
        self.s: list[np.ndarray] = []
        self.n = 0

    def add(self, cols, vals, rhs: float = 0.0, meta=None, s: float = 0.0) -> None:
        """One row: ``sum vals * x[cols]`` against ``rhs``."""
        cols = np.asarray(cols, int)
        self.r.append(np.full(cols.size, self.n))
        self.c.append(cols)
        self.v.append(np.asarray(vals, float))
        self.b.append(np.array([rhs], float))
        self.meta.append(np.array([meta if meta is not None else NO_META], float))
        self.s.append(np.array([s], float))
        self.n += 1

    def add_many(self, cols, vals, rhs=None, meta=None, s=0.0) -> None:
        """Rows with the same number of terms: ``cols``, ``vals`` of shape ``(rows, terms)``.

        ``rhs`` per row or shared (default 0); ``meta = (kind, k, index, sign)``
        with ``k`` per row or shared; ``s`` per row or shared.
        """
        cols = np.asarray(cols)
        m = cols.shape[0]
        if m == 0:
            return
        self.r.append(np.repeat(self.n + np.arange(m), cols.shape[1]))
        self.c.append(cols.ravel().astype(int))
        self.v.append(np.asarray(vals, float).ravel())
        self.b.append(np.broadcast_to(np.asarray(0.0 if rhs is None else rhs, float), (m,)).copy())
        if meta is None:
            md = np.tile(NO_META, (m, 1))
        else:
            kind, k, idx, sgn = meta
            md = np.column_stack(
                [np.full(m, kind), np.broadcast_to(np.asarray(k, float), (m,)), np.full(m, idx), np.full(m, sgn)]
            )
        self.meta.append(md)
        self.s.append(np.broadcast_to(np.asarray(s, float), (m,)).copy())
        self.n += m

    def entry(self, row: int, col: int, val: float) -> None:
        """One more term in an existing row."""
        self.r.append(np.array([row]))
        self.c.append(np.array([col]))
        self.v.append(np.array([val], float))

    def matrix(self, ncols: int) -> sparse.csr_matrix:
        """The rows as a CSR matrix with ``ncols`` columns."""
        if not self.v:
            return sparse.csr_matrix((self.n, ncols))
        return sparse.csr_matrix(
            (np.concatenate(self.v), (np.concatenate(self.r), np.concatenate(self.c))), shape=(self.n, ncols)
        )

    def system(self, ncols: int) -> tuple[sparse.csr_matrix | None, np.ndarray | None]:
        """``(matrix, rhs)`` for ``scipy.optimize.linprog``, ``(None, None)`` without rows."""
        return (self.matrix(ncols), self.rhs()) if self.n else (None, None)

    def rhs(self) -> np.ndarray:
        return np.concatenate(self.b) if self.b else np.zeros(0)

    def meta_array(self) -> np.ndarray:
        return np.concatenate(self.meta) if self.meta else np.zeros((0, 4))

    def s_array(self) -> np.ndarray:
        return np.concatenate(self.s) if self.s else np.zeros(0)
