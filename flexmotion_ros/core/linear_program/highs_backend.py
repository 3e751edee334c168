"""The direct HiGHS backend of :func:`~flexmotion_ros.core.linear_program.solve_lp` (``highspy``).

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
from functools import partial

import numpy as np
from scipy import sparse

from .answers import CHECK_TOL, DEFAULT_FEASIBILITY_TOL, NO_ITERATION_LIMIT, LpBackend, LpBasis, LpSolution, LpStatus

try:  # an optional accelerator: without it, linprog solves the same LP
    import highspy
except ImportError:  # pragma: no cover - exercised only on installs without highspy
    highspy = None
if highspy is not None and not hasattr(highspy, "_Highs"):  # pragma: no cover - a highspy without its core class
    highspy = None

#: Whether ``highspy`` (with its core class) is installed.
AVAILABLE = highspy is not None


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


def solve_highspy(
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
    *,
    crossover=True,
    iteration_limit=None,
    start_basis=None,
    start_point=None,
    want_basis=False,
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
    iterations = (
        NO_ITERATION_LIMIT if iteration_limit is None else max(0, min(int(iteration_limit), NO_ITERATION_LIMIT))
    )
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
    if start_basis is not None and start_basis.col_status.size == n and start_basis.row_status.size == row_lo.size:
        _set_basis(h, start_basis)
    elif start_point is not None and np.size(start_point) == n:
        # HiGHS turns a point without a basis into a starting basis in run() (its basisForSolution)
        start = highspy.HighsSolution()
        start.col_value = np.asarray(start_point, dtype=float).tolist()
        start.value_valid = True
        h.setSolution(start)
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
    raw_basis = h.getBasis() if want_basis else None  # a copy: read into arrays only if asked for
    iterations = int(h.getInfo().simplex_iteration_count)
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
        iterations=iterations,
        basis_reader=None if raw_basis is None else partial(_basis_arrays, raw_basis),
    )


def _set_basis(h, basis: LpBasis) -> None:
    """Start HiGHS's simplex from ``basis`` (the model is passed; a basis it rejects is only not used)."""
    status = [highspy.HighsBasisStatus(i) for i in range(5)]  # a table: 20 x faster than one call per entry
    b = highspy.HighsBasis()
    b.col_status = [status[x] for x in np.asarray(basis.col_status).tolist()]
    b.row_status = [status[x] for x in np.asarray(basis.row_status).tolist()]
    b.valid = True
    h.setBasis(b)


def _basis_arrays(b) -> LpBasis | None:
    """A ``highspy.HighsBasis`` as arrays (each of its list attributes is converted anew on every access: once)."""
    if not b.valid:
        return None
    cols, rows = b.col_status, b.row_status
    return LpBasis(
        col_status=np.array([x.value for x in cols], dtype=np.int8).reshape(len(cols)),
        row_status=np.array([x.value for x in rows], dtype=np.int8).reshape(len(rows)),
    )


__all__ = ["AVAILABLE", "solve_highspy"]
