"""``solve_lp``'s work bound (``iteration_limit``) and interior solutions (``crossover=False``).

A dual simplex can run for minutes inside one HiGHS call (the min_fuel seed LP of fuzz case 273,
issue 15), where HiGHS's time limit is not looked at: the iteration limit is.  Answers are
compared with ``scipy.optimize.linprog`` on the same LPs.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flexmotion_ros.core.linear_program import LpBackend, LpMethod, LpStatus, solve_lp

from .test_linear_program import random_lp, scipy_reference


@pytest.mark.parametrize("backend", [LpBackend.HIGHSPY, LpBackend.SCIPY])
def test_an_iteration_limit_stops_the_solve_without_a_verdict(backend):
    lp = random_lp(3, 12, 6, 80)
    assert solve_lp(**lp, backend=backend).status is LpStatus.OPTIMAL
    stopped = solve_lp(**lp, iteration_limit=1, presolve=False, backend=backend)
    assert stopped.status is LpStatus.TIME_LIMIT
    # the limit is this call's only: the next call without one solves again
    assert solve_lp(**lp, backend=backend).status is LpStatus.OPTIMAL


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n_eq=st.integers(1, 12), n=st.integers(2, 80))
def test_the_interior_method_without_crossover_finds_linprogs_optimum(seed, n_eq, n):
    lp = random_lp(seed, n_eq, 0, n)
    lp["lower"] = np.maximum(lp["lower"], -1.0)  # boxes on every variable: bounded
    ref = scipy_reference(lp)
    res = solve_lp(**lp, method=LpMethod.IPM, crossover=False, iteration_limit=200, backend=LpBackend.HIGHSPY)
    assert ref.status == 0
    assert res.status is LpStatus.OPTIMAL
    scale = max(1.0, abs(ref.fun))
    assert abs(res.objective - ref.fun) <= 1e-6 * scale
    # its duals are the optimum's: the dual objective of the box LP equals the primal one
    y = res.eq_marginals
    reduced = lp["cost"] - lp["A_eq"].T @ y
    dual = y @ lp["b_eq"] + np.sum(np.where(reduced > 0, reduced * lp["lower"], reduced * lp["upper"]))
    assert abs(dual - ref.fun) <= 1e-6 * scale
