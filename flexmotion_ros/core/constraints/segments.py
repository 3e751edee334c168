"""What the limited planner's linear programs are over and what they return: :class:`Segments`, :class:`LPSolution`.

:class:`Assembled` is one such LP as HiGHS's input (built by :mod:`.assembly`, read by :mod:`.lp` and
:mod:`.warm`).

The ``K`` commands of a limit LP (:mod:`.lp`) are free variables or share a
*level* over a run (:class:`Segments`: constant, or a ramp at the slew limit);
:class:`LPSolution` is one solve's commands, scale ``t`` and the dual values
the weak-duality bound of :mod:`.dual` needs, with its limit rows identified
by kind (:data:`STATE`, :data:`CUT`, :data:`SLEW`), sample and index.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Row kinds in :class:`LPSolution`.
STATE, CUT, SLEW = 0, 1, 2
#: Row kind of the command rows ``+-v_m <= t`` (negative: not a limit row, no place in the dual bound).
COMMAND = -2


@dataclass(frozen=True, kw_only=True)
class Lazy:
    """Which rows of a scaled LP are included (the others are checked after the solve).

    The masks grow in place as left-out rows are found violated (:meth:`.lp.LimitLP.solve`).

    Attributes
    ----------
    state : list of numpy.ndarray
        Per block, shape ``(K + 1, 2)``: include the ``+`` / ``-`` limit row at sample ``k`` (at knots).
    command : numpy.ndarray
        Shape ``(K, 2)``: include ``+v_m <= t`` / ``-v_m <= t`` (free samples).
    """

    state: list
    command: np.ndarray


@dataclass
class Segments:
    """Parametrisation of ``K`` commands: runs ``[start, end)`` sharing a level; the rest free.

    ``slope`` per run: 0 (constant level) or ``+-1`` (slew ramp: ``+-t`` slew
    steps per sample on top of the level).  Runs never touch the first or
    last sample.
    """

    K: int
    start: np.ndarray
    end: np.ndarray
    slope: np.ndarray

    @classmethod
    def all_free(cls, K: int) -> Segments:
        e = np.zeros(0, dtype=int)
        return cls(K, e, e.copy(), np.zeros(0))

    @classmethod
    def from_runs(cls, K: int, runs: list[tuple[int, int, float]]) -> Segments:
        runs = sorted((int(a), int(b), float(s)) for a, b, s in runs if 1 <= a < b <= K - 1)
        return cls(
            K, np.array([r[0] for r in runs], int), np.array([r[1] for r in runs], int), np.array([r[2] for r in runs])
        )

    def run_of(self) -> np.ndarray:
        """Run index of every sample, -1 for free samples."""
        out = np.full(self.K, -1)
        for r, (a, b) in enumerate(zip(self.start, self.end)):
            out[a:b] = r
        return out

    @property
    def n_free(self) -> int:
        return int(self.K - np.sum(self.end - self.start))


@dataclass
class LPSolution:
    """One solve: commands, scale and the dual values the weak-duality bound needs."""

    K: int
    u: np.ndarray  # commands (N), forward order
    t: float
    nu: np.ndarray  # multipliers of the (scaled) arrival rows
    rows: np.ndarray  # included limit rows: (kind, k, index, sign), shape (R, 4)
    s: np.ndarray  # offset within the interval of cut rows (s)
    lam: np.ndarray  # their multipliers (>= 0)
    segments: Segments
    levels: np.ndarray
    #: The LP's column values (None for a lifted solution): a start point for another LP over the same
    #: columns (:meth:`.lp.LimitLP.solve`'s ``start``).
    x: np.ndarray | None = None


@dataclass(frozen=True, kw_only=True)
class Assembled:
    """One assembled limit LP (HiGHS's input) and where its answer sits.

    Attributes
    ----------
    cost, A_ub, b_ub, A_eq, b_eq, lower, upper
        The LP ``min cost x`` s.t. ``A_ub x <= b_ub``, ``A_eq x = b_eq``, ``lower <= x <= upper``.
    free : numpy.ndarray
        Indices of the free samples.
    uvar : numpy.ndarray
        Column of each sample's command (``-1`` inside runs).
    lvar : numpy.ndarray
        Column of each run's level.
    n_arrival : int
        The arrival rows (the first equalities).
    row_scale : numpy.ndarray
        Scale of each arrival row (its multipliers are scaled back by it).
    meta, s : numpy.ndarray
        Kind, sample, index and sign of every inequality row (``-1`` kind: not a limit row), and the
        offset of cut rows within their interval (s).
    """

    cost: np.ndarray
    A_ub: object
    b_ub: np.ndarray
    A_eq: object
    b_eq: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    free: np.ndarray
    uvar: np.ndarray
    lvar: np.ndarray
    n_arrival: int
    row_scale: np.ndarray
    meta: np.ndarray
    s: np.ndarray
    #: The ``t`` columns (one per knot, first) and the total-variation columns (last).
    n_t: int = 0
    n_tv: int = 0
