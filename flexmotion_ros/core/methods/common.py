"""What several methods share: required and numeric options, the move budget, the planning rate, sampled-only results."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config import PlannerConfig
from ..errors import ConfigError, GoalError
from ..model.boundary import MoveProblem
from ..parameters import option
from ..results import SampledProfile
from ..simulation.exact import PiecewiseConstant
from ..time_optimal.rigid_body import rigid_time


def required_option(config: PlannerConfig, name: str, method: str, allowed: str | None = None):
    """``config.options[name]``, or :class:`ConfigError` saying ``method`` needs it (``allowed``: the registry's)."""
    if config.options.get(name) is None:
        allowed = allowed or option(name).allowed
        raise ConfigError(name, f"required by method {method}: set '{name}' ({allowed}) in the parameter file")
    return config.options[name]


def check_move_budget(config: PlannerConfig, problem: MoveProblem) -> float:
    """Refuse a move longer than ``config.max_move_duration_s`` before planning it; return its lower bound (s).

    The bound is the rigid body's own minimum time (closed form, a lower bound
    for the whole machine), so the check costs microseconds and refuses only
    moves that certainly exceed the budget (e.g. ``--goal 1e300``).

    Raises
    ------
    GoalError
        Naming ``goal`` and the budget ``max_move_duration_s``.
    """
    T = rigid_time(problem.model, problem.u_max, problem.shifted_initial(), problem.include_position)
    if not T <= config.max_move_duration_s:
        raise GoalError(
            "goal",
            f"the move needs at least {T:.4g} s (rigid-body minimum time), over the budget max_move_duration_s = "
            f"{config.max_move_duration_s:g} s; move less far or raise max_move_duration_s",
        )
    return T


def float_option(options: dict, name: str, unit: str, low: float, low_text: str) -> float | None:
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


def planning_rate(config: PlannerConfig, rate_hz: float | None) -> tuple[float, str]:
    if rate_hz:
        return float(rate_hz), "request"
    return config.rate_hz, "config.rate_hz (no rate given: the node's rate)"


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
