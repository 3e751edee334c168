"""Minimum fuel with per-input weights at a fixed rate (seed eq. 2.38 with ``C = [c_1 ... c_m]``).

For a given move time ``K dt`` the zero-order-hold sequence minimising
``sum_i c_i int |u_i| dt = sum_i c_i dt sum_k |u_ik|`` subject to an exact
arrival at rest and ``|u_ik| <= u_max_i`` is a linear program (``u = u+ - u-``).
Its optimality is certified by weak duality, evaluated here and not by the
LP solver: for any ``nu``::

    fuel >= nu^T w - sum_{i,k} u_max_i max(0, |nu^T g_ik| - c_i dt)

(the Lagrangian minimised over the box), with ``nu`` the LP's equality
multipliers.  The optimum is bang-off-bang per input (eq. 2.38's form).  The
sequence is corrected to an exact arrival (least-norm, samples with slack)
and checked by exact simulation.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..errors import InputError, SolverError
from ..linear_program import LpStatus, solve_lp
from ..model.modal_model import check_positive
from ..sampled.zoh import correct_exactly
from ..tolerances import HIGHS_OPTIONS, LP_GAP_RTOL
from .dual import multi_state_scale
from .parse import check_bounds
from .problem import MultiMoveProblem
from .response import MultiResponse
from .results import MultiSampledProfile
from .sampled_lp import finish_samples


def fuel_dual_bound(G: np.ndarray, w: np.ndarray, nu: np.ndarray, cost: np.ndarray, u_max_rows: np.ndarray) -> float:
    """Weak-duality lower bound on the fuel (see the module notes); rows of ``G`` per (input, sample)."""
    return float(nu @ w) - float(u_max_rows @ np.maximum(0.0, np.abs(G @ nu) - cost))


def plan_multi_min_fuel_zoh(
    problem: MultiMoveProblem, move_time: float, rate_hz: float, fuel_weights=None
) -> MultiSampledProfile:
    """The least weighted fuel ``sum_i c_i int |u_i|`` arriving at rest in ``round(move_time rate_hz)`` samples.

    Raises
    ------
    InputError
        ``move_time`` too short for the bounds at this rate (names the parameter), bad weights.
    SolverError
        The LP failed or the exact check missed.
    """
    t0 = time.perf_counter()
    T = check_positive("move_time", move_time, "s")
    dt = 1.0 / check_positive("rate_hz", rate_hz, "Hz")
    m = problem.model.m
    c = np.ones(m) if fuel_weights is None else check_bounds(fuel_weights, m, "fuel_weights")
    K = max(1, round(T / dt))
    resp = MultiResponse(problem)
    x0 = problem.shifted_initial()
    U = problem.u_max
    s = multi_state_scale(resp, x0, U, K * dt)
    gam = resp.input_integral(np.array([dt]))[0]
    tau = dt * np.arange(K)
    G = np.concatenate([resp.expm_x_many(tau, gam[:, i]) / s for i in range(m)])  # (m K, n), samples to go
    w = -resp.expm_x(K * dt, x0) / s
    rows_U = np.repeat(U, K)
    cost = np.repeat(c * dt, K)
    # variables: u+ (mK), u- (mK), each in [0, U]
    res = solve_lp(
        cost=np.concatenate([cost, cost]),
        A_eq=np.hstack([G.T, -G.T]),
        b_eq=w,
        lower=0.0,
        upper=np.concatenate([rows_U, rows_U]),
        **HIGHS_OPTIONS,
    )
    if res.status is LpStatus.INFEASIBLE:
        raise InputError(
            "move_time",
            f"{K} samples at {1 / dt:g} Hz ({K * dt:.6g} s) cannot reach rest within u_max; "
            "it must be at least the time-optimal move time",
        )
    if res.status is not LpStatus.OPTIMAL:
        raise SolverError(f"min_fuel: the linear program failed ({res.message})")
    u = res.x[: m * K] - res.x[m * K :]
    nu = np.asarray(res.eq_marginals, float)
    fixed = correct_exactly(G * rows_U[:, None], w, u / rows_U, 1.0)
    if fixed is None:
        raise SolverError("min_fuel: no exact correction of the LP sequence; nothing is returned")
    u = fixed * rows_U
    fuel = float(cost @ np.abs(u))
    bound = fuel_dual_bound(G, w, nu, cost, rows_U)
    gap = (fuel - bound) / max(abs(fuel), 1e-300)
    cmds = np.clip(u.reshape(m, K)[:, ::-1].T, -U, U)
    extra = {
        "fuel": fuel,
        "fuel_lower_bound": bound,
        "fuel_gap_relative": gap,
        "fuel_weights": [float(v) for v in c],
        "fuel_certified": bool(gap <= LP_GAP_RTOL or math.isclose(fuel, bound, rel_tol=LP_GAP_RTOL)),
    }
    return finish_samples(problem, cmds, dt, False, 0, "", math.nan, None, t0, extra, method="min_fuel")
