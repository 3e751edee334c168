"""Method ``robust_time_optimal``: zero frequency derivatives of the residual up to ``robust_order``."""

from __future__ import annotations

import time

from ..config import PlannerConfig
from ..errors import SolverError
from ..model.boundary import MoveProblem
from ..results import PlanResult
from ..sampled.robust import plan_robust_time_optimal_zoh
from ..sampled.zoh import plan_time_optimal_zoh
from ..simulation.prepared import PreparedMove, prepare
from ..time_optimal.rigid_body import rigid_time
from ..time_optimal.robust import MAX_ORDER, plan_robust_time_optimal
from ..time_optimal.solver import plan_time_optimal
from .common import SampledInput
from .shaped import options, robustness_info


def plan(config: PlannerConfig, problem: MoveProblem | PreparedMove, rate_hz: float | None) -> PlanResult:
    move = prepare(problem)  # responses built once for every planner below
    problem = move.problem
    o = options(config)
    t0 = time.perf_counter()
    nominal = None
    try:
        nominal = plan_time_optimal(move)
        profile = plan_robust_time_optimal(problem, o["robust_order"], nominal)
    except SolverError as exc:
        if not rate_hz:
            raise
        # no continuous robust move (its solver, or the nominal one, found none): the
        # sampled robust move from the linear programs alone, checked exactly as always
        return _sampled_only(move.with_continuous(nominal), o, rate_hz, exc, t0)
    plan_time = time.perf_counter() - t0
    sampled = None
    if rate_hz:
        if profile.duration == 0.0 or profile is nominal:
            sampled = plan_time_optimal_zoh(move, rate_hz, nominal)
        else:
            sampled = plan_robust_time_optimal_zoh(move, profile, o["robust_order"], rate_hz)
    info = {"plan_time_s": plan_time, "robust_order": o["robust_order"], **profile.extra}
    info.update(robustness_info(profile.input(), problem, nominal.duration, o["robustness.tolerance"]))
    return PlanResult(method="robust_time_optimal", problem=problem, continuous=profile, sampled=sampled, info=info)


def _sampled_only(move: PreparedMove, o: dict, rate_hz: float, exc: SolverError, t0: float) -> PlanResult:
    """The sampled robust move without a continuous one (the continuous solver's refusal ``exc``)."""
    problem = move.problem
    if move.continuous is not None:
        lower, T_nominal = move.continuous.duration, move.continuous.duration
    else:  # the rigid body's minimum time: also a proved lower bound
        lower = rigid_time(problem.model, problem.u_max, move.x0, problem.include_position)
        T_nominal = lower
    sampled = plan_robust_time_optimal_zoh(move, None, o["robust_order"], rate_hz, lower)
    note = f"no continuous robust move ({exc}); sampled robust move from the linear programs"
    cont = SampledInput(sampled, "robust_time_optimal", bool(sampled.minimal), note)
    info = {"plan_time_s": time.perf_counter() - t0, "robust_order": o["robust_order"], "continuous_note": note}
    info.update(robustness_info(sampled.input(), problem, T_nominal, o["robustness.tolerance"]))
    return PlanResult(method="robust_time_optimal", problem=problem, continuous=cont, sampled=sampled, info=info)


METHOD_NAME = "robust_time_optimal"
DESCRIPTION = (
    f"time-optimal with zero frequency derivatives of the residual up to robust_order (0..{MAX_ORDER}, default 1)"
)
