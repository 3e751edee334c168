"""Robust time-optimal moves: zero frequency derivatives of the residual (seed section 2.3.4).

The residual state of mode ``i`` depends on its frequency ``omega_i``;
requiring it and its derivatives ``d^j/domega_i^j`` (``j <= k``) to vanish at
the end flattens the residual vibration around the nominal frequency.  The
derivatives obey a linear system too (:mod:`.robust_response`, the augmented
model in closed form); the robust move is the time-optimal move of that
augmented system to its origin, solved by the core's
:func:`~flexmotion_ros.core.time_optimal.solve_bang_bang` under a work bound
(:data:`WORK_BUDGET`), checked by the matrix-exponential simulation of the
augmented system and certified by Pontryagin's conditions.
"""

from __future__ import annotations

import time

import numpy as np

from ..errors import SolverError
from ..model.boundary import MoveProblem
from ..results import BangBangProfile
from ..simulation.exact import PiecewiseConstant, simulate
from ..tolerances import FINAL_STATE_RTOL
from .certificate import certify
from .rigid_body import rigid_time
from .robust_response import MAX_ORDER, RobustModalResponse, check_order
from .solver import plan_time_optimal, solve_bang_bang

__all__ = ["MAX_ORDER", "WORK_BUDGET", "RobustModalResponse", "check_order", "plan_robust_time_optimal"]


# ------------------------------------------------------------------ planner
#: Bound on the continuous robust solver's switching-function work (points x orders x modes,
#: about 1.2e-8 s CPU each): the 14 slowest plans of fuzz seed 15 cases 0-361 (by CPU) spent at
#: most 8e8 (case 257, 8 modes, 11 s CPU); case 325 (8 modes, moving start) spent 3.8e9 (45 s)
#: and then missed.
WORK_BUDGET = 1e9


def plan_robust_time_optimal(
    problem: MoveProblem, order: int = 1, nominal: BangBangProfile | None = None
) -> BangBangProfile:
    """Time-optimal bang-bang move whose residual has zero frequency derivatives up to ``order``.

    Parameters
    ----------
    problem : MoveProblem
    order : int
        ``k``: ``d^j x_i(T) / domega_i^j = 0`` for every mode ``i`` and ``j <= k``.
    nominal : BangBangProfile, optional
        The plain time-optimal profile (a proved lower bound), if known.

    Returns
    -------
    BangBangProfile
        ``method = "robust_time_optimal"``; ``certificate`` for the augmented system;
        ``extra["augmented_final_state_error_relative"]``.

    Raises
    ------
    SolverError
        If the augmented final state misses the origin (exact simulation), or
        the solver spends :data:`WORK_BUDGET` without finding the move.
    """
    t0 = time.perf_counter()
    k = check_order(order)
    model, um = problem.model, problem.u_max
    system = RobustModalResponse(model, k, problem.include_position)
    xa0 = system.augment(problem.shifted_initial())
    if nominal is None:
        nominal = plan_time_optimal(problem)
    T_low = nominal.duration
    if not np.any(xa0):
        return nominal
    # feasible upper bound: the rigid move shaped by ZV-D^k for every mode (positive shaper)
    T_rigid = rigid_time(model, um, problem.shifted_initial(), problem.include_position)
    T_up = T_rigid + float(np.sum(0.5 * (k + 1) * 2.0 * np.pi / np.asarray(model.omega_d))) if model.n_modes else T_low
    system.horizon = 2.0 * max(T_up, T_low)
    T_init = T_low + 0.5 * (T_up - T_low) * k / (k + 1.0)
    system.work_budget = WORK_BUDGET
    sol = solve_bang_bang(system, xa0, um, T_low * (1.0 - 1e-12), T_init)
    system.work_budget = None
    T = sol.duration
    u = PiecewiseConstant.from_switches(sol.switch_times, sol.levels, T)
    A, B = system.A(), system.B()
    states = simulate((A, B), xa0, u)
    xT = states[-1]
    scale = np.abs(xa0) + np.max(np.abs(states), axis=0)
    scale = np.where(scale > 0.0, scale, 1.0)
    rel = float(np.max(np.abs(xT) / scale))
    if not rel <= FINAL_STATE_RTOL:
        raise SolverError(
            f"robust time-optimal planner missed the target: relative augmented final-state error {rel:.3e}; nothing is returned"
        )
    system.horizon = T
    cert = certify(system, sol.nu, T, um, sol.switch_times, sol.levels, states)
    final_abs = simulate(model, problem.x0, u, times=[T])[0]
    nominal_err = float(np.max(np.abs(system.nominal_part(xT))))
    return BangBangProfile(
        problem=problem,
        switch_times=sol.switch_times,
        levels=sol.levels,
        duration=float(T),
        final_state=final_abs,
        final_state_error=nominal_err,
        final_state_error_relative=float(np.max(np.abs(system.nominal_part(xT)) / system.nominal_part(scale))),
        certificate=cert,
        solve_time_s=time.perf_counter() - t0,
        method="robust_time_optimal",
        extra={
            "robust_order": k,
            "augmented_final_state_error": float(np.max(np.abs(xT))),
            "augmented_final_state_error_relative": rel,
            "time_optimal_duration": float(T_low),
        },
    )
