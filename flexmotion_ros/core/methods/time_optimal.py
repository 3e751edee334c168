"""Method ``time_optimal`` (the default): the certified bang-bang optimum and its exact ZOH sequence."""

from __future__ import annotations

from ..config import PlannerConfig
from ..model.boundary import MoveProblem
from ..results import PlanResult
from ..sampled.zoh import plan_time_optimal_zoh
from ..simulation.prepared import PreparedMove, prepare
from ..time_optimal.solver import plan_time_optimal


def plan(config: PlannerConfig, problem: MoveProblem | PreparedMove, rate_hz: float | None) -> PlanResult:
    move = prepare(problem)  # responses built once for every planner below
    problem = move.problem
    continuous = plan_time_optimal(move)
    sampled = plan_time_optimal_zoh(move.with_continuous(continuous), rate_hz, continuous) if rate_hz else None
    return PlanResult(method="time_optimal", problem=problem, continuous=continuous, sampled=sampled)


METHOD_NAME = "time_optimal"
DESCRIPTION = "certified time-optimal bang-bang (zero-order hold at rate_hz)"
