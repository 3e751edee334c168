"""Warm starts of the limited planner's LPs (:mod:`.lp`): a round's basis carried to the next, and start points.

A row round is the same LP with rows added: :class:`WarmStart` carries its optimal basis, each old row
by what it limits (:func:`row_keys`), the new rows basic.  An LP over the same columns as a solved one
(a reference after its scaled probe) starts from that solution's point (:func:`start_point`); an LP in
other windows or at another count from a point built from a solution's commands
(:func:`point_from_commands`).  HiGHS builds its starting basis around a point; a warm start gives the
cold solve's verdict and optimum (a warm solve without a verdict is followed by the cold one).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse.linalg import spsolve

from ..linear_program import BASIC, LpBasis, LpSolution
from .segments import Assembled, LPSolution, Segments


@dataclass(frozen=True, kw_only=True)
class WarmStart:
    """One round of a limit LP: its rows and its answer, whose optimal basis starts the next round.

    Both are kept as they are and read only when a next round asks (:meth:`carried`): most rounds are
    the last of their LP.

    Attributes
    ----------
    rows : Assembled
        The round's LP (its row keys, :func:`row_keys`, in HiGHS's order: inequalities, then equalities).
    solution : LpSolution
        Its answer (``return_basis``).
    """

    rows: Assembled
    solution: LpSolution

    def carried(self, a: Assembled) -> LpBasis | None:
        """The basis for the same LP with rows added (``a``): old rows keep their status, new rows
        are basic (their slacks), so the number of basic variables stays the number of rows.  None
        when the LP is not this one with rows added (other columns, a row gone, keys not unique)."""
        b = self.solution.basis
        old_keys, keys = row_keys(self.rows), row_keys(a)
        m = old_keys.shape[0]
        if b is None or b.col_status.size != a.cost.size or b.row_status.size != m:
            return None
        # every key numbered (equal rows of the stacked keys, equal numbers), without a Python loop over rows
        _, ids = np.unique(np.vstack([old_keys, keys]), axis=0, return_inverse=True)
        ids = ids.ravel()
        old, new = ids[:m], ids[m:]
        if np.unique(old).size != m or np.unique(new).size != new.size or not np.isin(old, new).all():
            return None
        status = np.full(int(ids.max(initial=-1)) + 1, BASIC, dtype=np.int8)
        status[old] = b.row_status
        return LpBasis(col_status=b.col_status, row_status=status[new])


def same_columns(sol: LPSolution, K: int, seg: Segments) -> bool:
    """Whether ``sol`` was solved over the first columns of an LP at ``K`` in ``seg`` (the same knots and runs)."""
    s = sol.segments
    return (
        sol.x is not None
        and sol.K == K
        and np.array_equal(s.start, seg.start)
        and np.array_equal(s.end, seg.end)
        and np.array_equal(s.slope, seg.slope)
    )


def start_point(a: Assembled, x: np.ndarray) -> np.ndarray | None:
    """A point of the assembled LP from ``x``, the values of its first columns (another mode's optimum).

    Columns past ``x`` are the total-variation ones (``+-step - tau <= 0``): each set to the smallest value
    its rows allow.  Then every column is clipped to its bounds (``t`` fixed, ``|v| <= 1``): the point may
    miss a row (e.g. a mid-interval one); HiGHS repairs it from the basis it builds around the point.
    """
    n, m = a.cost.size, x.size
    if m > n:
        return None
    out = np.zeros(n)
    out[:m] = x
    if m < n and a.A_ub is not None:
        A = sparse.csc_array(a.A_ub)
        need = A[:, :m] @ x - a.b_ub  # each row's value before its tau term
        extra = A[:, m:]
        for j in range(n - m):
            lo, hi = extra.indptr[j], extra.indptr[j + 1]
            coef = extra.data[lo:hi]
            rows = extra.indices[lo:hi]
            neg = coef < 0.0
            if neg.any():
                out[m + j] = max(0.0, float(np.max(need[rows[neg]] / -coef[neg])))
    return np.clip(out, a.lower, a.upper)


def resampled(v: np.ndarray, K: int) -> np.ndarray:
    """``v`` stretched to ``K`` samples by normalised time (nearest sample)."""
    j = np.minimum(np.rint(np.arange(K) * (v.size / K)).astype(int), v.size - 1)
    return v[j]


def point_from_commands(a: Assembled, seg: Segments, v: np.ndarray, slew: float | None) -> np.ndarray | None:
    """A point of the assembled LP near the commands ``v`` (normalised, ``K`` samples): free samples as
    they are, each run's level its mean (a ramp's: its first sample), the chain states from the chain
    equalities, ``t`` at its bound, the total-variation columns from their rows.  None if the chain
    system is singular."""
    n = a.cost.size
    x = np.zeros(n)
    F = a.free
    x[a.uvar[F]] = v[F]
    for r in range(seg.start.size):
        p, q = seg.start[r], seg.end[r]
        x[a.lvar[r]] = v[p] if (slew is not None and seg.slope[r]) else float(np.mean(v[p:q]))
    x = np.clip(x, a.lower, a.upper)
    x[: a.n_t] = a.lower[: a.n_t] if np.all(np.isfinite(a.lower[: a.n_t])) else x[: a.n_t]
    chain = np.zeros(n, bool)
    chain[a.n_t + F.size + seg.start.size : n - a.n_tv] = True
    fixed = a.lower == a.upper
    x[fixed] = a.lower[fixed]
    unknown = chain & ~fixed
    if unknown.any() and a.A_eq is not None:
        E = sparse.csc_array(a.A_eq)
        Eu = E[:, np.flatnonzero(unknown)]
        rows = np.flatnonzero(np.diff(sparse.csr_array(Eu).indptr) > 0)
        Eu = sparse.csc_array(sparse.csr_array(Eu)[rows])
        rhs = a.b_eq[rows] - sparse.csr_array(E[:, np.flatnonzero(~unknown)])[rows] @ x[~unknown]
        if Eu.shape[0] != Eu.shape[1]:
            return None
        try:
            xu = spsolve(Eu, rhs)
        except RuntimeError:
            return None
        if not np.all(np.isfinite(xu)):
            return None
        x[unknown] = xu
    return start_point(a, x[: n - a.n_tv])


def row_keys(a: Assembled) -> np.ndarray:
    """A key per row of the assembled LP that is the same for the same row in another round: shape (rows, 6).

    Limit rows by what they limit (class 0, kind, sample, index, sign, offset); the other inequalities
    (class 1) and the equalities (class 2) by their position among their own kind (the same for the same
    ``K``, segments and mode).
    """
    meta = a.meta
    other = meta[:, 0] == -1  # the command rows (kind -2) have their sample and sign
    n_eq = a.b_eq.size if a.b_eq is not None else 0
    keys = np.zeros((meta.shape[0] + n_eq, 6))
    ub = keys[: meta.shape[0]]
    ub[:, 0] = other
    ub[:, 1:4] = np.trunc(meta[:, :3])
    ub[:, 4] = meta[:, 3]
    ub[:, 5] = a.s
    ub[other, 1:] = 0.0
    ub[other, 2] = np.arange(np.count_nonzero(other))
    keys[meta.shape[0] :, 0] = 2.0
    keys[meta.shape[0] :, 2] = np.arange(n_eq)
    return keys + 0.0  # -0.0 as 0.0
