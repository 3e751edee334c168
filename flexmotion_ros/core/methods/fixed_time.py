"""Method ``fixed_time``: arrive at rest at ``arrival_time`` (s, ``>= T*``) with the least peak force.

Option (a ROS parameter next to ``method``)::

    method: fixed_time
    arrival_time: 5.0      # s, >= T*
"""

from __future__ import annotations

from ..config import PlannerConfig
from ..model.boundary import MoveProblem
from ..results import PlanResult
from ..sampled.fixed_time import plan_fixed_time_zoh
from ..time_optimal.fixed_time import plan_fixed_time
from .common import required_option


def plan(config: PlannerConfig, problem: MoveProblem, rate_hz: float | None) -> PlanResult:
    raw = required_option(config, "arrival_time", "fixed_time", "s, >= the time-optimal move time T*")
    continuous = plan_fixed_time(problem, raw)
    sampled = plan_fixed_time_zoh(problem, continuous.duration, rate_hz, continuous) if rate_hz else None
    info = {
        "arrival_time": float(continuous.duration),
        "bound_used": continuous.extra["bound_used"],
        "time_optimal_duration": continuous.extra["time_optimal_duration"],
        "added_time_s": continuous.duration - continuous.extra["time_optimal_duration"],
    }
    if sampled is not None:
        info["requested_samples"] = int(sampled.extra.get("requested_samples", sampled.samples))
        info["peak_command"] = float(sampled.extra.get("peak_command", 0.0))
    return PlanResult("fixed_time", problem, continuous, sampled, info)


METHOD_NAME = "fixed_time"
DESCRIPTION = "arrive at rest at arrival_time (s, >= T*) with the least peak force; exact ZOH at rate_hz"
