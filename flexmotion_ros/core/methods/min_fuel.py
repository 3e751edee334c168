"""Planner methods ``min_fuel`` and

It plans at the node's rate: without ``rate_hz`` it uses ``config.rate_hz`` and says so in
``info["rate_source"]``.
"""

from __future__ import annotations

from ..config import PlannerConfig
from ..errors import ConfigError, SolverError
from ..fuel.curve import fuel_time_curve, sampled_fuel_curve
from ..fuel.lp import plan_min_fuel_zoh
from ..fuel.min_fuel import BangOffBangMissed, FuelProfile, plan_min_fuel
from ..model.boundary import MoveProblem
from ..results import PlanResult
from ..sampled.zoh import plan_time_optimal_zoh
from ..simulation.prepared import PreparedMove, prepare
from ..time_optimal.solver import plan_time_optimal
from .common import SampledInput, float_option, planning_rate

#: ``move_time`` when the parameter is absent, relative to the time-optimal ``T*``.
DEFAULT_MOVE_TIME_FACTOR = 1.2


# ------------------------------------------------------------------ min_fuel
def plan(config: PlannerConfig, problem: MoveProblem | PreparedMove, rate_hz: float | None) -> PlanResult:
    move = prepare(problem)  # responses built once for every planner below
    problem = move.problem
    opts = config.options
    to = plan_time_optimal(move)
    T_star = to.duration
    T = float_option(opts, "move_time", " s", T_star * (1.0 - 1e-12), f">= the time-optimal {T_star:.9g}")
    move_time = T if T is not None else DEFAULT_MOVE_TIME_FACTOR * T_star
    longest = float_option(
        opts, "fuel_curve.longest_time", " s", T_star * (1.0 - 1e-12), f">= the time-optimal {T_star:.9g}"
    )
    points = opts.get("fuel_curve.points", 9)
    if (
        isinstance(points, bool)
        or not isinstance(points, (int, float))
        or points != int(points)
        or not 2 <= points <= 1000
    ):
        raise ConfigError("fuel_curve.points", f"must be an integer in [2, 1000], got {points!r}")
    rate, source = planning_rate(config, rate_hz)
    info: dict = {
        "move_time": move_time,
        "move_time_source": "move_time" if T is not None else f"default {DEFAULT_MOVE_TIME_FACTOR} * T*",
        "time_optimal_duration": T_star,
        "fuel_time_optimal": problem.u_max * T_star,
        "rate_source": source,
    }
    continuous: FuelProfile | None
    try:
        continuous = plan_min_fuel(move, move_time, to)
        nu = None if continuous.extra.get("time_optimal") else continuous.costate
    except BangOffBangMissed as exc:
        # e.g. a singular arc (|B^T lambda| = 1 on an interval): the LP optimum stays exact, and
        # the best dual iterate guesses its saturated samples (windowed LPs, not one over every sample)
        continuous, nu = None, exc.costate
        info["continuous_note"] = f"no continuous bang-off-bang profile: {exc}"
    except SolverError as exc:
        continuous, nu = None, None
        info["continuous_note"] = f"no continuous bang-off-bang profile: {exc}"
    sampled = plan_min_fuel_zoh(
        move,
        rate,
        move_time,
        to,
        nu_guess=nu,
        continuous=continuous,
        fewest_samples=lambda: plan_time_optimal_zoh(move.with_continuous(to), rate).samples,
    )
    info["sampled_fuel"] = sampled.extra["fuel"]
    info["sampled_fuel_lower_bound"] = sampled.extra["fuel_lower_bound"]
    if continuous is not None:
        info["fuel"] = continuous.fuel
        info["fuel_lower_bound"] = continuous.fuel_lower_bound
    fuel = continuous.fuel if continuous is not None else sampled.extra["fuel"]
    info["fuel_saving_percent"] = 100.0 * (1.0 - fuel / (problem.u_max * T_star)) if T_star > 0 else 0.0
    if longest is not None:
        try:
            info["fuel_curve"] = fuel_time_curve(move, longest, int(points), None, to).to_dict()
        except SolverError as exc:
            curve = sampled_fuel_curve(move, rate, longest, int(points), to).to_dict()
            info["fuel_curve"] = {**curve, "note": f"sampled curve only: {exc}"}
    if continuous is not None:
        cont = continuous
    elif sampled.extra.get("fuel_gap_closed", True):
        cont = SampledInput(sampled, "min_fuel", True, "sampled LP optimum (duality gap closed)")
    else:  # the LP's work bound: the best window, exact and within the bound, optimality not proved
        gap = sampled.extra["fuel"] - sampled.extra["fuel_lower_bound"]
        cont = SampledInput(
            sampled,
            "min_fuel",
            False,
            f"best window of the sampled fuel LP within its work bound; fuel within {gap:.3g} N s of the optimum",
        )
    return PlanResult(method="min_fuel", problem=problem, continuous=cont, sampled=sampled, info=info)


METHOD_NAME = "min_fuel"
DESCRIPTION = "minimum fuel (bang-off-bang) for a given move_time; fuel/time curve"
