"""Linear programs through HiGHS with a small call overhead: :func:`solve_lp`.

The planners' linear programs are small and many (a replan solves a few
``n x K`` peak LPs, ``n`` states, ``K`` free samples).  ``scipy.optimize.linprog``
spends most of such a call validating and converting its input; the HiGHS
solve itself is the smaller part.  :func:`solve_lp` hands the same problem to
the same solver (HiGHS, through its official ``highspy`` bindings) directly:
the constraint matrix as compressed columns built from a dense array without
``scipy.sparse``, one solver object per thread, and the answer in the
conventions of ``linprog`` (row duals with ``linprog``'s ``marginals`` sign:
the derivative of the optimal objective with respect to the right-hand side).

Without ``highspy`` (e.g. an install from distribution packages, which carry
scipy but not highspy) every call goes to ``linprog``: the same LP, the same
solver family, only slower.  ``test/core/test_linear_program.py`` checks both
backends against ``linprog`` on random LPs (values, duals, infeasible and
unbounded problems).

Modules: ``answers`` (statuses, methods, backends, :class:`LpSolution`, :class:`LpBasis`),
``highs_backend`` (the direct ``highspy`` solve), ``scipy_backend`` (``linprog``).
"""

from __future__ import annotations

import numpy as np

from . import highs_backend
from .answers import (
    BASIC,
    CHECK_TOL,
    DEFAULT_FEASIBILITY_TOL,
    NO_ITERATION_LIMIT,
    LpBackend,
    LpBasis,
    LpMethod,
    LpSolution,
    LpStatus,
)
from .scipy_backend import solve_scipy

#: The backend :func:`solve_lp` uses unless told otherwise (a module global: benches switch it).
DEFAULT_BACKEND = LpBackend.HIGHSPY if highs_backend.AVAILABLE else LpBackend.SCIPY


def solve_lp(
    *,
    cost,
    A_ub=None,
    b_ub=None,
    A_eq=None,
    b_eq=None,
    lower=0.0,
    upper=np.inf,
    method: LpMethod = LpMethod.CHOOSE,
    presolve: bool = True,
    time_limit_s: float | None = None,
    primal_feasibility_tolerance: float | None = None,
    dual_feasibility_tolerance: float | None = None,
    backend: LpBackend | None = None,
    crossover: bool = True,
    iteration_limit: int | None = None,
    start_basis: LpBasis | None = None,
    start_point: np.ndarray | None = None,
    return_basis: bool = False,
) -> LpSolution:
    """``min cost^T x  s.t.  A_ub x <= b_ub,  A_eq x = b_eq,  lower <= x <= upper`` by HiGHS.

    Parameters
    ----------
    cost : array_like, shape (n,)
    A_ub, A_eq : ndarray or scipy sparse matrix, shape (m, n), optional
        Dense arrays are handed over without ``scipy.sparse`` (explicit zeros dropped).
    b_ub, b_eq : array_like, optional
    lower, upper : float or array_like
        Variable bounds (``-inf`` / ``inf``: none); default ``x >= 0`` as ``linprog``.
    method : LpMethod
        ``CHOOSE`` (``linprog(method="highs")``), ``DUAL_SIMPLEX`` (``"highs-ds"``), ``IPM``.
    presolve : bool
        HiGHS's presolve; if it leaves no verdict (``OTHER``), the LP is asked
        once more without it.
    time_limit_s : float, optional
        Wall-time limit (s); reaching it gives ``TIME_LIMIT``.
    primal_feasibility_tolerance, dual_feasibility_tolerance : float, optional
        HiGHS's tolerances (``linprog``'s options of the same names); default
        :data:`DEFAULT_FEASIBILITY_TOL`, HiGHS's own.
    backend : LpBackend, optional
        Default :data:`DEFAULT_BACKEND` (``HIGHSPY`` when installed).
    crossover : bool
        After ``IPM``, HiGHS's crossover to a basic solution (``highspy`` only: ``linprog``
        always crosses over).  Without it the point and duals are the interior method's,
        optimal to its tolerances but not a vertex.
    iteration_limit : int, optional
        A work budget: simplex (and interior-point) iterations; reaching it gives ``TIME_LIMIT``.
        Unlike ``time_limit_s`` it does not depend on the machine's load (the same LP, the same answer).
    start_basis : LpBasis, optional
        Start the simplex from this basis (e.g. the optimum of the same LP before rows were added,
        their slacks basic): a warm start, same verdicts.  Ignored by the ``SCIPY`` backend, and when
        its sizes do not match the LP.
    start_point : ndarray, shape (n,), optional
        Start the simplex from a basis HiGHS builds around this point (``setSolution``; e.g. the optimum of
        an LP with the same columns and another objective): a warm start, same verdicts.  Used only
        without ``start_basis``; ignored by the ``SCIPY`` backend and when its size does not match.
    return_basis : bool
        Return the optimal basis in :attr:`LpSolution.basis` (``HIGHSPY`` backend).

    Returns
    -------
    LpSolution
        ``x``, ``objective`` and the row duals when ``OPTIMAL``; an
        ``OPTIMAL`` point that violates a constraint by more than
        :data:`CHECK_TOL` comes back ``OTHER``, as ``linprog`` reports it (status 4).
    """
    c = np.asarray(cost, dtype=float).ravel()
    n = c.size
    lo = np.broadcast_to(np.asarray(lower, dtype=float), (n,)).astype(float)
    hi = np.broadcast_to(np.asarray(upper, dtype=float), (n,)).astype(float)
    b_ub = None if b_ub is None else np.asarray(b_ub, dtype=float).ravel()
    b_eq = None if b_eq is None else np.asarray(b_eq, dtype=float).ravel()
    if (A_ub is None) != (b_ub is None) or (A_eq is None) != (b_eq is None):
        raise ValueError("solve_lp: A_ub and b_ub (A_eq and b_eq) come together")
    which = backend if backend is not None else DEFAULT_BACKEND
    if which is LpBackend.HIGHSPY and not highs_backend.AVAILABLE:
        raise ValueError("solve_lp: backend highspy requested but highspy is not installed (pip install highspy)")
    solve = highs_backend.solve_highspy if which is LpBackend.HIGHSPY else solve_scipy
    tolerances = (primal_feasibility_tolerance, dual_feasibility_tolerance)
    work = {"crossover": crossover, "iteration_limit": iteration_limit}
    if which is LpBackend.HIGHSPY:
        work.update(start_basis=start_basis, start_point=start_point, want_basis=return_basis)
    res = solve(c, A_ub, b_ub, A_eq, b_eq, lo, hi, method, presolve, time_limit_s, tolerances, **work)
    if res.status is LpStatus.OTHER and presolve and which is LpBackend.HIGHSPY:
        # HiGHS 1.16's presolve can blow a badly scaled LP up (a friction LP: presolved entries of 7e58,
        # "Not Set") that its solver alone solves, and that scipy's bundled HiGHS solved with presolve:
        # no verdict with presolve asks once without it
        work["start_basis"] = work["start_point"] = None
        again = solve(c, A_ub, b_ub, A_eq, b_eq, lo, hi, method, False, time_limit_s, tolerances, **work)
        if again.status is not LpStatus.OTHER:
            return again
    return res


__all__ = [
    "BASIC",
    "CHECK_TOL",
    "DEFAULT_BACKEND",
    "DEFAULT_FEASIBILITY_TOL",
    "LpBackend",
    "LpBasis",
    "LpMethod",
    "LpSolution",
    "LpStatus",
    "NO_ITERATION_LIMIT",
    "solve_lp",
]
