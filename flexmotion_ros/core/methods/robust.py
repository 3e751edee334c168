"""Method ``robust_time_optimal``: zero frequency derivatives of the residual up to ``robust_order``."""

from __future__ import annotations

import time

from ..config import PlannerConfig
from ..model.boundary import MoveProblem
from ..results import PlanResult
from ..sampled.robust import plan_robust_time_optimal_zoh
from ..sampled.zoh import plan_time_optimal_zoh
from ..simulation.prepared import PreparedMove, prepare
from ..time_optimal.robust import MAX_ORDER, plan_robust_time_optimal
from ..time_optimal.solver import plan_time_optimal
from .shaped import options, robustness_info


def plan(config: PlannerConfig, problem: MoveProblem | PreparedMove, rate_hz: float | None) -> PlanResult:
    move = prepare(problem)  # responses built once for every planner below
    problem = move.problem
    o = options(config)
    t0 = time.perf_counter()
    nominal = plan_time_optimal(move)
    profile = plan_robust_time_optimal(problem, o["robust_order"], nominal)
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


METHOD_NAME = "robust_time_optimal"
DESCRIPTION = (
    f"time-optimal with zero frequency derivatives of the residual up to robust_order (0..{MAX_ORDER}, default 1)"
)
