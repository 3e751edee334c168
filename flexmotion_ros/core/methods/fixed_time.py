"""Method ``fixed_time``: arrive at rest at ``arrival_time`` (s, ``>= T*``) with the least peak force.

Option (a ROS parameter next to ``method``)::

    method: fixed_time
    arrival_time: 5.0      # s, >= T*
"""

from __future__ import annotations

from ..config import PlannerConfig
from ..errors import SolverError
from ..model.boundary import MoveProblem
from ..results import PlanResult
from ..sampled.fixed_time import plan_fixed_time_lp, plan_fixed_time_zoh
from ..simulation.prepared import PreparedMove, prepare
from ..time_optimal.fixed_time import plan_fixed_time
from ..time_optimal.solver import plan_time_optimal
from .common import SampledInput, required_option


def plan(config: PlannerConfig, problem: MoveProblem | PreparedMove, rate_hz: float | None) -> PlanResult:
    move = prepare(problem)  # responses built once for every planner below
    problem = move.problem
    raw = required_option(config, "arrival_time", "fixed_time")  # its unit and range: the registry's
    try:
        move = move.with_continuous(plan_time_optimal(move))  # T*, solved once for both planners
        continuous = plan_fixed_time(move, raw)
    except SolverError as exc:
        if not rate_hz:
            raise
        # no continuous move (the time-optimal planner refused the model): the sampled
        # least-peak move at the requested sample from the LP alone, checked exactly as always
        sampled = plan_fixed_time_lp(move, raw, rate_hz)
        note = f"no continuous fixed-time move ({exc}); sampled least-peak LP at the requested sample"
        return PlanResult(
            method="fixed_time",
            problem=problem,
            continuous=SampledInput(sampled, "fixed_time", False, note),
            sampled=sampled,
            info={
                "arrival_time": float(sampled.duration),
                "continuous_note": note,
                "requested_samples": int(sampled.extra["requested_samples"]),
                "peak_command": float(sampled.extra["peak_command"]),
            },
        )
    sampled = plan_fixed_time_zoh(move, continuous.duration, rate_hz, continuous) if rate_hz else None
    info = {
        "arrival_time": float(continuous.duration),
        "bound_used": continuous.extra["bound_used"],
        "time_optimal_duration": continuous.extra["time_optimal_duration"],
        "added_time_s": continuous.duration - continuous.extra["time_optimal_duration"],
    }
    if sampled is not None:
        info["requested_samples"] = int(sampled.extra.get("requested_samples", sampled.samples))
        info["peak_command"] = float(sampled.extra.get("peak_command", 0.0))
    return PlanResult(method="fixed_time", problem=problem, continuous=continuous, sampled=sampled, info=info)


METHOD_NAME = "fixed_time"
DESCRIPTION = "arrive at rest at arrival_time (s, >= T*) with the least peak force; exact ZOH at rate_hz"
