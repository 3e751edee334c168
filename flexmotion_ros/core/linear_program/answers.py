"""The vocabulary of :func:`~flexmotion_ros.core.linear_program.solve_lp`: statuses, methods, backends, answers, bases.

Kept apart from the two backends so each can build an :class:`LpSolution` without importing the other.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from enum import Enum
from functools import cached_property

import numpy as np

#: HiGHS's default primal and dual feasibility tolerances (what ``linprog`` leaves them at unless told).
DEFAULT_FEASIBILITY_TOL = 1e-7
#: HiGHS's own iteration limit (``kHighsIInf``, none): what ``iteration_limit=None`` sets.
NO_ITERATION_LIMIT = 2_147_483_647
#: linprog's post-solve feasibility check, reproduced for the direct backend: ``sqrt(1e-9) * 10``.
CHECK_TOL = 10.0 * 1e-9**0.5


class LpStatus(Enum):
    """What the solver proved (values: what diagnostics show)."""

    OPTIMAL = "optimal"
    INFEASIBLE = "infeasible"
    UNBOUNDED = "unbounded"
    TIME_LIMIT = "time_limit"  # time or iteration limit reached
    OTHER = "other"  # numerical difficulty, solver or model error: nothing proved


class LpMethod(Enum):
    """The HiGHS algorithm (``linprog``'s ``highs``, ``highs-ds``, ``highs-ipm``)."""

    CHOOSE = "choose"
    DUAL_SIMPLEX = "simplex"
    IPM = "ipm"


class LpBackend(Enum):
    """Who solves: HiGHS directly (``highspy``), or through ``scipy.optimize.linprog``."""

    HIGHSPY = "highspy"
    SCIPY = "scipy"


@dataclass(frozen=True, kw_only=True)
class LpSolution:
    """The answer of :func:`solve_lp` for ``min c^T x  s.t.  A_ub x <= b_ub,  A_eq x = b_eq,  lower <= x <= upper``.

    Attributes
    ----------
    status : LpStatus
    x : ndarray or None
        The optimal point (OPTIMAL only).
    objective : float or None
        ``c^T x`` (OPTIMAL only).
    eq_marginals, ub_marginals : ndarray or None
        Row duals: the derivative of the optimal objective with respect to
        each ``b_eq`` / ``b_ub`` entry (``linprog``'s ``eqlin.marginals`` and
        ``ineqlin.marginals``; OPTIMAL only).
    message : str
        The solver's words, for diagnostics.
    backend : LpBackend
        Who solved it.
    """

    status: LpStatus
    x: np.ndarray | None
    objective: float | None
    eq_marginals: np.ndarray | None
    ub_marginals: np.ndarray | None
    message: str
    backend: LpBackend
    #: HiGHS's simplex iteration count (OPTIMAL on the highspy backend only; 0 from an optimal start basis).
    iterations: int | None = None
    #: Reads the optimal basis when first asked for (:attr:`basis`): turning HiGHS's statuses into arrays
    #: costs about 0.5 us per row and column, and most bases are never used (the bench's 1 kHz all-three
    #: move: 14 read, 2 used, 0.08 s CPU).
    basis_reader: Callable[[], LpBasis | None] | None = field(default=None, repr=False, compare=False)

    @cached_property
    def basis(self) -> LpBasis | None:
        """The optimal basis (OPTIMAL with ``return_basis`` on the highspy backend only)."""
        return self.basis_reader() if self.basis_reader is not None else None


@dataclass(frozen=True, kw_only=True)
class LpBasis:
    """A simplex basis of one LP: HiGHS's status of every column and of every row.

    Attributes
    ----------
    col_status : ndarray of int, shape (n,)
    row_status : ndarray of int, shape (m,)
        The ``A_ub`` rows, then the ``A_eq`` rows.  Values are HiGHS's ``HighsBasisStatus``:
        0 at the lower bound, 1 basic (:data:`BASIC`), 2 at the upper bound, 3 zero, 4 nonbasic.
    """

    col_status: np.ndarray
    row_status: np.ndarray


#: ``LpBasis`` status of a basic column or row (a new row's slack starts basic: the basis stays a basis).
BASIC = 1
