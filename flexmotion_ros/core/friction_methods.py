"""Planner methods ``time_optimal_friction`` and ``fixed_time`` (registered on import).

Options are ROS parameters next to ``method`` in the parameter file
(``config.options``)::

    method: time_optimal_friction
    coulomb_force: 0.2     # N, in [0, u_max): friction on the rigid body
    arrival_time: 5.0      # s, >= T*: used by method fixed_time

See ``config/friction_example.yaml``.
"""

from __future__ import annotations

from .boundary import MoveProblem
from .config import PlannerConfig
from .errors import FlexmotionError
from .fixed_time import plan_fixed_time, plan_fixed_time_zoh
from .friction_time_optimal import check_coulomb_force, plan_time_optimal_friction
from .friction_zoh import plan_friction_zoh
from .planning import PlanResult, register_method


def _option(config: PlannerConfig, name: str, method: str, allowed: str):
    if name not in config.options:
        raise FlexmotionError(name, f"required by method {method}: set '{name}' ({allowed}) in the parameter file")
    return config.options[name]


def _plan_friction(config: PlannerConfig, problem: MoveProblem, rate_hz: float | None) -> PlanResult:
    raw = _option(config, "coulomb_force", "time_optimal_friction", f"N, in [0, u_max) = [0, {problem.u_max:g})")
    F = check_coulomb_force(raw, problem.u_max)
    continuous = plan_time_optimal_friction(problem, F)
    sampled = plan_friction_zoh(problem, F, rate_hz, continuous) if rate_hz else None
    info = {
        "coulomb_force": F,
        "frictionless_duration": continuous.frictionless_duration,
        "added_time_s": continuous.duration - continuous.frictionless_duration,
        "optimality": continuous.certificate.claim,
    }
    if sampled is not None:
        info["sampled_extra_samples"] = int(sampled.extra.get("extra_samples", 0))
    return PlanResult("time_optimal_friction", problem, continuous, sampled, info)


def _plan_fixed_time(config: PlannerConfig, problem: MoveProblem, rate_hz: float | None) -> PlanResult:
    raw = _option(config, "arrival_time", "fixed_time", "s, >= the time-optimal move time T*")
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


register_method(
    "time_optimal_friction",
    "bang-bang under Coulomb friction on the rigid body (option coulomb_force, N); exact ZOH at rate_hz",
    _plan_friction,
)
register_method(
    "fixed_time",
    "arrive at rest at arrival_time (s, >= T*) with the least peak force; exact ZOH at rate_hz",
    _plan_fixed_time,
)
