"""Planner methods ``min_fuel`` and ``limited`` for the nodes and ``flexmotion plan``.

``min_fuel``
    Bang-off-bang minimum-fuel move (seed eq. 2.38) arriving at rest after
    ``move_time`` seconds.  Parameters (dotted ROS names):

    * ``move_time`` (s, ``>= T*``); absent: ``1.2 T*`` (:data:`DEFAULT_MOVE_TIME_FACTOR`):
      the fuel falls steeply just above ``T*`` (on the Wie-Bernstein benchmark 20 % more
      time saves 65 % of the fuel), far less beyond;
    * ``fuel_curve.longest_time`` (s, ``>= T*``), optional: also report the
      fuel/time trade-off curve from ``T*`` to that time (``info["fuel_curve"]``);
    * ``fuel_curve.points`` (integer ``>= 2``, default 9).

``limited``
    Fewest zero-order-hold samples that reach rest exactly while every limit
    holds at and between the samples.  Parameters:

    * ``limits.velocity_max`` (m/s, ``> 0``): rigid-body velocity;
    * ``limits.deflection_max`` (list, one per mode, ``> 0``; ``.inf``: no limit);
    * ``limits.slew_rate`` (N/s, ``> 0``): ``|u_k - u_{k-1}| <= slew_rate / rate_hz``,
      from and to 0 at the ends;
    * ``limits.report_each`` (bool, default false): also plan with each limit
      alone and report the time each one costs (``info["added_time_by_limit_s"]``).

Both plan at the node's rate: without ``rate_hz`` (``flexmotion plan`` without
``--rate``) they use ``config.rate_hz`` and say so in ``info["rate_source"]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .boundary import MoveProblem
from .config import ConfigError, PlannerConfig
from .errors import SolverError
from .fuel_curve import fuel_time_curve, sampled_fuel_curve
from .fuel_lp import plan_min_fuel_zoh
from .limit_checks import Limits
from .limits import plan_limited
from .min_fuel import FuelProfile, plan_min_fuel
from .planning import PlanResult, register_method
from .profile import SampledProfile
from .simulation import PiecewiseConstant
from .time_optimal import plan_time_optimal
from .zoh import plan_zoh

#: ``move_time`` when the parameter is absent, relative to the time-optimal ``T*``.
DEFAULT_MOVE_TIME_FACTOR = 1.2
LIMIT_OPTIONS = ("limits.velocity_max", "limits.deflection_max", "limits.slew_rate", "limits.report_each")


@dataclass
class SampledInput:
    """A zero-order-hold sequence seen as the continuous-time input it is.

    For methods whose result is only sampled: the summary then has the same
    keys as a continuous profile (switch times = instants where the held
    level changes).
    """

    sampled: SampledProfile
    method: str
    certified: bool
    message: str

    @property
    def duration(self) -> float:
        return self.sampled.duration

    def input(self) -> PiecewiseConstant:
        return self.sampled.input()

    def to_dict(self) -> dict:
        u = self.sampled.commands
        tol = 1e-12 * (float(np.max(np.abs(u))) if u.size else 0.0)  # ignore rounding-level changes
        change = np.flatnonzero(np.abs(np.diff(u)) > tol) + 1 if u.size else np.empty(0, int)
        starts = np.concatenate([[0], change]).astype(int) if u.size else np.empty(0, int)
        return {
            "method": self.method,
            "duration": float(self.duration),
            "switch_times": [float(k * self.sampled.dt) for k in change],
            "levels": [float(u[k]) for k in starts],
            "final_state": [float(v) for v in self.sampled.states[-1]],
            "final_state_error": float(self.sampled.final_state_error),
            "final_state_error_relative": float(self.sampled.final_state_error_relative),
            "certified": bool(self.certified),
            "certificate": {"passed": bool(self.certified), "message": self.message},
            "solve_time_s": float(self.sampled.solve_time_s),
        }


def _rate(config: PlannerConfig, rate_hz: float | None) -> tuple[float, str]:
    if rate_hz:
        return float(rate_hz), "request"
    return config.rate_hz, "config.rate_hz (no rate given: the node's rate)"


def _float_option(options: dict, name: str, unit: str, low: float, low_text: str) -> float | None:
    if name not in options or options[name] is None:
        return None
    value = options[name]
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ConfigError(name, f"must be a number {low_text}{unit}, got {value!r}") from None
    if not math.isfinite(x) or x < low:
        raise ConfigError(name, f"must be a finite number {low_text}{unit}, got {x}")
    return x


# ------------------------------------------------------------------ min_fuel
def _plan_min_fuel(config: PlannerConfig, problem: MoveProblem, rate_hz: float | None) -> PlanResult:
    opts = config.options
    to = plan_time_optimal(problem)
    T_star = to.duration
    T = _float_option(opts, "move_time", " s", T_star * (1.0 - 1e-12), f">= the time-optimal {T_star:.9g}")
    move_time = T if T is not None else DEFAULT_MOVE_TIME_FACTOR * T_star
    longest = _float_option(opts, "fuel_curve.longest_time", " s", T_star * (1.0 - 1e-12), f">= the time-optimal {T_star:.9g}")
    points = opts.get("fuel_curve.points", 9)
    if isinstance(points, bool) or not isinstance(points, (int, float)) or points != int(points) or not 2 <= points <= 1000:
        raise ConfigError("fuel_curve.points", f"must be an integer in [2, 1000], got {points!r}")
    rate, source = _rate(config, rate_hz)
    info: dict = {
        "move_time": move_time,
        "move_time_source": "move_time" if T is not None else f"default {DEFAULT_MOVE_TIME_FACTOR} * T*",
        "time_optimal_duration": T_star,
        "fuel_time_optimal": problem.u_max * T_star,
        "rate_source": source,
    }
    continuous: FuelProfile | None
    try:
        continuous = plan_min_fuel(problem, move_time, to)
        nu = None if continuous.extra.get("time_optimal") else continuous.costate
    except SolverError as exc:
        # e.g. a singular arc (|B^T lambda| = 1 on an interval): the LP optimum stays exact
        continuous, nu = None, None
        info["continuous_note"] = f"no continuous bang-off-bang profile: {exc}"
    sampled = plan_min_fuel_zoh(problem, rate, move_time, to, nu_guess=nu, continuous=continuous)
    info["sampled_fuel"] = sampled.extra["fuel"]
    info["sampled_fuel_lower_bound"] = sampled.extra["fuel_lower_bound"]
    if continuous is not None:
        info["fuel"] = continuous.fuel
        info["fuel_lower_bound"] = continuous.fuel_lower_bound
    fuel = continuous.fuel if continuous is not None else sampled.extra["fuel"]
    info["fuel_saving_percent"] = 100.0 * (1.0 - fuel / (problem.u_max * T_star)) if T_star > 0 else 0.0
    if longest is not None:
        try:
            info["fuel_curve"] = fuel_time_curve(problem, longest, int(points), None, to).to_dict()
        except SolverError as exc:
            curve = sampled_fuel_curve(problem, rate, longest, int(points), to).to_dict()
            info["fuel_curve"] = {**curve, "note": f"sampled curve only: {exc}"}
    cont = continuous if continuous is not None else SampledInput(sampled, "min_fuel", True, "sampled LP optimum (duality gap closed)")
    return PlanResult("min_fuel", problem, cont, sampled, info)


# ------------------------------------------------------------------- limited
def limits_from_options(config: PlannerConfig) -> tuple[Limits, bool]:
    """The :class:`Limits` in ``config.options`` (validated) and ``limits.report_each``."""
    opts = config.options
    unknown = sorted(k for k in opts if k.startswith("limits.") and k not in LIMIT_OPTIONS)
    if unknown:
        raise ConfigError(unknown[0], f"unknown limit; known: {', '.join(LIMIT_OPTIONS)}")
    q = opts.get("limits.deflection_max")
    if q is not None and not isinstance(q, (list, tuple)):
        q = [q] if config.model.n_modes == 1 else q
        if not isinstance(q, list):
            raise ConfigError("limits.deflection_max", f"must be a list with one value > 0 per mode ({config.model.n_modes})")
    each = opts.get("limits.report_each", False)
    if not isinstance(each, bool):
        raise ConfigError("limits.report_each", f"must be true or false, got {each!r}")
    lim = Limits(opts.get("limits.velocity_max"), tuple(q) if q is not None else None, opts.get("limits.slew_rate"))
    return lim.validated(config.model), each


def _plan_limited(config: PlannerConfig, problem: MoveProblem, rate_hz: float | None) -> PlanResult:
    limits, each = limits_from_options(config)
    rate, source = _rate(config, rate_hz)
    unlimited = plan_zoh(problem, rate)
    result = plan_limited(problem, rate, limits, unlimited)
    info: dict = {"rate_source": source, "unlimited_duration": unlimited.duration, **result.to_dict()}
    if each and len(limits.active) > 1:
        by = {}
        for name in limits.active:
            by[name] = plan_limited(problem, rate, limits.only(name), unlimited).added_time_s
        info["added_time_by_limit_s"] = by
    elif limits.active:
        info["added_time_by_limit_s"] = {limits.active[0]: result.added_time_s} if len(limits.active) == 1 else {}
    message = "fewest samples proved (relaxation infeasible below)" if result.minimal else (
        f"not proved fewest: no sequence below {result.lower_bound_samples} samples"
    )
    cont = SampledInput(result.sampled, "limited", result.minimal, message)
    return PlanResult("limited", problem, cont, result.sampled, info)


register_method("min_fuel", "minimum fuel (bang-off-bang) for a given move_time; fuel/time curve", _plan_min_fuel)
register_method("limited", "fewest samples under velocity, deflection and slew-rate limits (LP)", _plan_limited)
