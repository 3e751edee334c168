"""Method ``robust_time_optimal``: zero frequency derivatives of the residual up to ``robust_order``."""

from __future__ import annotations

import time

from ..config import PlannerConfig
from ..model.boundary import MoveProblem
from ..results import PlanResult
from ..sampled.robust import plan_robust_time_optimal_zoh
from ..sampled.zoh import plan_time_optimal_zoh
from ..time_optimal.robust import MAX_ORDER, plan_robust_time_optimal
from ..time_optimal.solver import plan_time_optimal
from .shaped import options, robustness_info


def plan(config: PlannerConfig, problem: MoveProblem, rate_hz: float | None) -> PlanResult:
    o = options(config)
    t0 = time.perf_counter()
    nominal = plan_time_optimal(problem)
    profile = plan_robust_time_optimal(problem, o["robust_order"], nominal)
    plan_time = time.perf_counter() - t0
    sampled = None
    if rate_hz:
        if profile.duration == 0.0 or profile is nominal:
            sampled = plan_time_optimal_zoh(problem, rate_hz, nominal)
        else:
            sampled = plan_robust_time_optimal_zoh(problem, profile, o["robust_order"], rate_hz)
    info = {"plan_time_s": plan_time, "robust_order": o["robust_order"], **profile.extra}
    info.update(robustness_info(profile.input(), problem, nominal.duration, o["robustness.tolerance"]))
    return PlanResult("robust_time_optimal", problem, profile, sampled, info)


METHOD_NAME = "robust_time_optimal"
DESCRIPTION = (
    f"time-optimal with zero frequency derivatives of the residual up to robust_order (0..{MAX_ORDER}, default 1)"
)
