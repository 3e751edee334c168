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

Why the core class ``highspy._Highs`` and not the public ``highspy.Highs``:
the public wrapper registers Python callbacks at construction, and HiGHS
prints its two-line banner to stdout when a callback is set while output is
on -- before any option can turn it off (the ``flexmotion`` command line
must print nothing but its answer).  Its wrapper also keeps class-level
locks for its threaded solve, which we do not use.  The core class is the
one ``scipy``'s own HiGHS wrapper uses; output is switched off before any
model is passed, so HiGHS never writes.
"""

from __future__ import annotations

import os
import threading
from dataclasses import dataclass
from enum import Enum

import numpy as np
from scipy import sparse
from scipy.optimize import linprog

try:  # an optional accelerator: without it, linprog solves the same LP
    import highspy
except ImportError:  # pragma: no cover - exercised only on installs without highspy
    highspy = None
if highspy is not None and not hasattr(highspy, "_Highs"):  # pragma: no cover - a highspy without its core class
    highspy = None

#: HiGHS's default primal and dual feasibility tolerances (what ``linprog`` leaves them at unless told).
DEFAULT_FEASIBILITY_TOL = 1e-7
#: HiGHS's own iteration limit (none): what ``iteration_limit=None`` sets.
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


#: The backend :func:`solve_lp` uses unless told otherwise.
DEFAULT_BACKEND = LpBackend.HIGHSPY if highspy is not None else LpBackend.SCIPY


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


def _csc_parts(A) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(start, index, value)`` of ``A`` in compressed columns, explicit zeros dropped (as ``csc_array(A)``)."""
    if sparse.issparse(A):
        C = sparse.csc_array(A)
        C.eliminate_zeros()
        C.sort_indices()
        return C.indptr.astype(np.int32), C.indices.astype(np.int32), np.asarray(C.data, dtype=float)
    At = np.asarray(A, dtype=float).T  # rows of At: the columns of A, in order
    mask = At != 0.0
    if mask.size and mask.all():  # the planners' dense rows: no index arithmetic
        cols, rows = At.shape
        start = np.arange(0, (cols + 1) * rows, rows, dtype=np.int32)
        return start, np.tile(np.arange(rows, dtype=np.int32), cols), At.ravel()
    start = np.zeros(At.shape[0] + 1, dtype=np.int32)
    np.cumsum(np.count_nonzero(mask, axis=1), out=start[1:])
    return start, np.nonzero(mask)[1].astype(np.int32), At[mask]


def _stack_rows(A_ub, A_eq, n: int):
    """``[A_ub; A_eq]`` (dense if both are, else sparse), or an empty ``(0, n)`` array."""
    blocks = [A for A in (A_ub, A_eq) if A is not None]
    if not blocks:
        return np.zeros((0, n))
    if len(blocks) == 1:
        return blocks[0]
    if any(sparse.issparse(A) for A in blocks):
        return sparse.vstack(blocks, format="csc")
    return np.vstack(blocks)


_local = threading.local()


def _reset_after_fork() -> None:
    """A forked child starts with no solver objects of its parent's threads."""
    global _local
    _local = threading.local()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_reset_after_fork)


def _solver():
    """This thread's HiGHS object (created silent on first use; never shared between threads)."""
    h = getattr(_local, "highs", None)
    if h is None:
        h = highspy._Highs()
        h.setOptionValue("output_flag", False)  # before any model: HiGHS prints nothing, not even its banner
        h.setOptionValue("log_to_console", False)
        h.setOptionValue("simplex_strategy", 1)  # dual simplex, as linprog always asks
        # one thread: the serial dual simplex still synchronises with HiGHS's worker pool in places, and on a
        # busy machine that costs more than it saves (an 8 x 1000 peak LP: 7.1 ms with the default, 0.39 ms
        # with one thread, interleaved on a loaded 2-core machine); no worker threads also means nothing a
        # forked planning child could inherit half-alive
        h.setOptionValue("threads", 1)
        _local.highs = h
    return h


_STATUS = {}
if highspy is not None:
    _M = highspy.HighsModelStatus
    _STATUS = {
        _M.kOptimal: LpStatus.OPTIMAL,
        _M.kInfeasible: LpStatus.INFEASIBLE,
        _M.kModelError: LpStatus.INFEASIBLE,  # inconsistent bounds (linprog: status 2)
        _M.kUnbounded: LpStatus.UNBOUNDED,
        _M.kTimeLimit: LpStatus.TIME_LIMIT,
        _M.kIterationLimit: LpStatus.TIME_LIMIT,
    }


def _infinite_to_highs(a: np.ndarray) -> np.ndarray:
    """``+-inf`` as HiGHS's infinity (itself ``inf`` in recent versions: nothing to do)."""
    if np.isinf(highspy.kHighsInf):
        return a
    inf = np.isinf(a)
    if inf.any():
        a = a.copy()
        a[inf] = np.sign(a[inf]) * highspy.kHighsInf
    return a


def _solve_highspy(
    c,
    A_ub,
    b_ub,
    A_eq,
    b_eq,
    lower,
    upper,
    method,
    presolve,
    time_limit_s,
    tolerances,
    crossover=True,
    iteration_limit=None,
) -> LpSolution:
    n = c.size
    m_ub = 0 if b_ub is None else b_ub.size
    A = _stack_rows(A_ub, A_eq, n)
    start, index, value = _csc_parts(A)
    row_lo = np.concatenate([np.full(m_ub, -np.inf), b_eq if b_eq is not None else np.zeros(0)])
    row_hi = np.concatenate([b_ub if b_ub is not None else np.zeros(0), b_eq if b_eq is not None else np.zeros(0)])
    h = _solver()
    primal, dual = (DEFAULT_FEASIBILITY_TOL if tol is None else float(tol) for tol in tolerances)
    # HiGHS compares time_limit with the object's run clock, which adds up over every run of the object
    # (measured: a 0.05 s limit refused every solve after 0.05 s of solves in total): the limit of this
    # solve is the clock now plus its own share
    limit = h.getRunTime() + float(time_limit_s) if time_limit_s is not None else np.inf
    iterations = NO_ITERATION_LIMIT if iteration_limit is None else int(iteration_limit)
    options = (method.value, "on" if presolve else "off", limit, primal, dual, "on" if crossover else "off", iterations)
    if options != getattr(_local, "options", None):  # set only what changed since this thread's last call
        h.setOptionValue("solver", options[0])
        h.setOptionValue("presolve", options[1])
        h.setOptionValue("time_limit", options[2])
        h.setOptionValue("primal_feasibility_tolerance", primal)
        h.setOptionValue("dual_feasibility_tolerance", dual)
        h.setOptionValue("run_crossover", options[5])
        h.setOptionValue("simplex_iteration_limit", iterations)
        h.setOptionValue("ipm_iteration_limit", iterations)
        _local.options = options
    passed = h.passModel(
        n,
        row_lo.size,
        value.size,
        1,  # column-wise matrix
        1,  # minimise
        0.0,
        c,
        _infinite_to_highs(lower),
        _infinite_to_highs(upper),
        _infinite_to_highs(row_lo),
        _infinite_to_highs(row_hi),
        start,
        index,
        value,
        np.zeros(n, dtype=np.int32),  # every column continuous
    )
    if passed == highspy.HighsStatus.kError:
        # HiGHS refuses a model it cannot hold, e.g. a row whose bound lies past its infinity (1e20) on the
        # wrong side; linprog reported such a model error as infeasible (status 2), and so does this
        h.clearModel()
        return LpSolution(
            status=LpStatus.INFEASIBLE,
            x=None,
            objective=None,
            eq_marginals=None,
            ub_marginals=None,
            message="HiGHS refused the model (a bound past its infinity, 1e20): read as infeasible, as linprog",
            backend=LpBackend.HIGHSPY,
        )
    h.run()
    model_status = h.getModelStatus()
    status = _STATUS.get(model_status, LpStatus.OTHER)
    message = h.modelStatusToString(model_status)
    if status is not LpStatus.OPTIMAL:
        h.clearSolver()  # the next model starts afresh, as a new object would
        return LpSolution(
            status=status,
            x=None,
            objective=None,
            eq_marginals=None,
            ub_marginals=None,
            message=message,
            backend=LpBackend.HIGHSPY,
        )
    sol = h.getSolution()
    x = np.array(sol.col_value)
    row_value = np.array(sol.row_value)
    row_dual = np.array(sol.row_dual)
    objective = float(h.getObjectiveValue())
    h.clearSolver()
    # linprog's check of an "optimal" point (its status 4 otherwise): bounds, inequality slack, equality residual
    ok = (
        np.all(np.isfinite(x))
        and np.all(x >= lower - CHECK_TOL)
        and np.all(x <= upper + CHECK_TOL)
        and np.all(row_hi[:m_ub] - row_value[:m_ub] >= -CHECK_TOL)
        and np.all(np.abs(row_hi[m_ub:] - row_value[m_ub:]) <= CHECK_TOL)
    )
    if not ok:
        return LpSolution(
            status=LpStatus.OTHER,
            x=None,
            objective=None,
            eq_marginals=None,
            ub_marginals=None,
            message=f"{message}, but the point violates the constraints by more than {CHECK_TOL:.1e}",
            backend=LpBackend.HIGHSPY,
        )
    return LpSolution(
        status=LpStatus.OPTIMAL,
        x=x,
        objective=objective,
        eq_marginals=row_dual[m_ub:],
        ub_marginals=row_dual[:m_ub],
        message=message,
        backend=LpBackend.HIGHSPY,
    )


_SCIPY_STATUS = {0: LpStatus.OPTIMAL, 1: LpStatus.TIME_LIMIT, 2: LpStatus.INFEASIBLE, 3: LpStatus.UNBOUNDED}
_SCIPY_METHOD = {LpMethod.CHOOSE: "highs", LpMethod.DUAL_SIMPLEX: "highs-ds", LpMethod.IPM: "highs-ipm"}


def _solve_scipy(
    c,
    A_ub,
    b_ub,
    A_eq,
    b_eq,
    lower,
    upper,
    method,
    presolve,
    time_limit_s,
    tolerances,
    crossover=True,
    iteration_limit=None,
) -> LpSolution:
    options = {"presolve": bool(presolve)}  # linprog always crosses over: ``crossover`` has no effect here
    if iteration_limit is not None:
        options["maxiter"] = int(iteration_limit)
    if time_limit_s is not None:
        options["time_limit"] = float(time_limit_s)
    for name, tol in zip(("primal_feasibility_tolerance", "dual_feasibility_tolerance"), tolerances):
        if tol is not None:
            options[name] = float(tol)
    # dense rows as CSC: linprog converts a dense matrix itself, slower than HiGHS solves a full-horizon LP
    res = linprog(
        c,
        A_ub=A_ub if A_ub is None or sparse.issparse(A_ub) else sparse.csc_matrix(A_ub),
        b_ub=b_ub,
        A_eq=A_eq if A_eq is None or sparse.issparse(A_eq) else sparse.csc_matrix(A_eq),
        b_eq=b_eq,
        bounds=np.column_stack([lower, upper]),
        method=_SCIPY_METHOD[method],
        options=options,
    )
    status = _SCIPY_STATUS.get(res.status, LpStatus.OTHER)
    optimal = status is LpStatus.OPTIMAL
    return LpSolution(
        status=status,
        x=np.asarray(res.x, dtype=float) if optimal else None,
        objective=float(res.fun) if optimal else None,
        eq_marginals=np.asarray(res.eqlin.marginals, dtype=float) if optimal and b_eq is not None else None,
        ub_marginals=np.asarray(res.ineqlin.marginals, dtype=float) if optimal and b_ub is not None else None,
        message=str(res.message),
        backend=LpBackend.SCIPY,
    )


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
        Most simplex (and interior-point) iterations: a work bound HiGHS honours inside a
        solve, where the time limit may not be; reaching it gives ``TIME_LIMIT``.

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
    if which is LpBackend.HIGHSPY and highspy is None:
        raise ValueError("solve_lp: backend highspy requested but highspy is not installed (pip install highspy)")
    solve = _solve_highspy if which is LpBackend.HIGHSPY else _solve_scipy
    tolerances = (primal_feasibility_tolerance, dual_feasibility_tolerance)
    work = {"crossover": crossover, "iteration_limit": iteration_limit}
    res = solve(c, A_ub, b_ub, A_eq, b_eq, lo, hi, method, presolve, time_limit_s, tolerances, **work)
    if res.status is LpStatus.OTHER and presolve and which is LpBackend.HIGHSPY:
        # HiGHS 1.16's presolve can blow a badly scaled LP up (a friction LP: presolved entries of 7e58,
        # "Not Set") that its solver alone solves, and that scipy's bundled HiGHS solved with presolve:
        # no verdict with presolve asks once without it
        again = solve(c, A_ub, b_ub, A_eq, b_eq, lo, hi, method, False, time_limit_s, tolerances, **work)
        if again.status is not LpStatus.OTHER:
            return again
    return res


__all__ = [
    "CHECK_TOL",
    "DEFAULT_BACKEND",
    "DEFAULT_FEASIBILITY_TOL",
    "LpBackend",
    "LpMethod",
    "LpSolution",
    "LpStatus",
    "NO_ITERATION_LIMIT",
    "solve_lp",
]
