"""Method ``time_optimal`` (the default): the certified bang-bang optimum and its exact ZOH sequence."""

from __future__ import annotations

from ..config import PlannerConfig
from ..model.boundary import MoveProblem
from ..results import PlanResult
from ..sampled.zoh import plan_time_optimal_zoh
from ..time_optimal.solver import plan_time_optimal


def plan(config: PlannerConfig, problem: MoveProblem, rate_hz: float | None) -> PlanResult:
    continuous = plan_time_optimal(problem)
    sampled = plan_time_optimal_zoh(problem, rate_hz, continuous) if rate_hz else None
    return PlanResult("time_optimal", problem, continuous, sampled)


METHOD_NAME = "time_optimal"
DESCRIPTION = "certified time-optimal bang-bang (zero-order hold at rate_hz)"
