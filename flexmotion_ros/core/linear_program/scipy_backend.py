"""The ``scipy.optimize.linprog`` backend of :func:`~flexmotion_ros.core.linear_program.solve_lp`.

The same solver family (scipy's bundled HiGHS), only slower per call; what runs when ``highspy``
is absent, and the tests' independent reference.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.optimize import linprog

from .answers import LpBackend, LpMethod, LpSolution, LpStatus

_SCIPY_STATUS = {0: LpStatus.OPTIMAL, 1: LpStatus.TIME_LIMIT, 2: LpStatus.INFEASIBLE, 3: LpStatus.UNBOUNDED}
_SCIPY_METHOD = {LpMethod.CHOOSE: "highs", LpMethod.DUAL_SIMPLEX: "highs-ds", LpMethod.IPM: "highs-ipm"}


def solve_scipy(
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
) -> LpSolution:
    options = {"presolve": bool(presolve)}  # linprog always crosses over: ``crossover`` has no effect here
    if iteration_limit is not None:
        options["maxiter"] = max(0, int(iteration_limit))
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


__all__ = ["solve_scipy"]
