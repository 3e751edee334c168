"""What several methods share: required and numeric options, the move budget, the planning rate, sampled-only results."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config import PlannerConfig
from ..errors import ConfigError, GoalError, ModelError
from ..model.boundary import MoveProblem
from ..parameters import option
from ..results import SampledProfile
from ..simulation.exact import PiecewiseConstant
from ..time_optimal.rigid_body import rigid_time
from ..tolerances import MAX_SAMPLES


def required_option(config: PlannerConfig, name: str, method: str, allowed: str | None = None):
    """``config.options[name]``, or :class:`ConfigError` saying ``method`` needs it (``allowed``: the registry's)."""
    if config.options.get(name) is None:
        allowed = allowed or option(name).allowed
        raise ConfigError(name, f"required by method {method}: set '{name}' ({allowed}) in the parameter file")
    return config.options[name]


#: Largest ``|c| T`` (viscous relaxations of the rigid body within a move)
#: planned: the final velocity's rounding grows like ``eps |c| T`` (measured:
#: 3.5e-9 relative at ``|c| T = 2.3e8``, 1e-10 at ``7e7``).
MAX_VISCOUS_SPAN = 3e7


def check_plannable(config: PlannerConfig, rate_hz: float | None = None) -> float:
    """Refuse, before any goal, a configuration no sampled plan can serve; return the rate checked (Hz).

    For a node to call when parameters are set (and :func:`plan_move` calls
    it whenever a rate is given).  Costs microseconds.  Refused:

    * a mode at or above the Nyquist frequency of the command rate
      (``omega_d dt >= pi``): commands held for ``dt`` cannot steer it (at
      ``omega_d dt = k pi`` the sampled mode is not even controllable, and
      above it the rate aliases it onto a slower one).

    Parameters
    ----------
    config : PlannerConfig
        The validated configuration (model, ``u_max``, ``rate_hz``, budget).
    rate_hz : float, optional
        The command rate (Hz); default ``config.rate_hz``.

    Raises
    ------
    ConfigError
        Naming ``rate_hz``, the mode and the smallest rate that serves it.
    """
    rate = float(rate_hz) if rate_hz else config.rate_hz
    wd = np.asarray(config.model.omega_d, dtype=float)
    if wd.size:
        i = int(np.argmax(wd))
        if wd[i] / rate >= math.pi:
            raise ConfigError(
                "rate_hz",
                f"mode {i + 1} at {wd[i]:.6g} rad/s is at or above the Nyquist frequency pi rate_hz = "
                f"{math.pi * rate:.6g} rad/s of {rate:g} Hz (omega dt = {wd[i] / rate:.4g} >= pi): commands held "
                f"for 1/rate_hz cannot steer it; set rate_hz above {wd[i] / math.pi:.6g} Hz (better 10x that)",
            )
    return rate


def check_move_budget(config: PlannerConfig, problem: MoveProblem, rate_hz: float | None = None) -> float:
    """Refuse a move longer than the budget before planning it; return its lower bound (s).

    The bound is the rigid body's own minimum time (closed form, a lower bound
    for the whole machine), so the check costs microseconds and refuses only
    moves that certainly exceed a budget (e.g. ``--goal 1e300``):

    * ``config.max_move_duration_s`` (s);
    * ``|c| T`` at most :data:`MAX_VISCOUS_SPAN` (a viscous term this stiff
      cannot be brought to rest in double precision);
    * with ``rate_hz``: :data:`~flexmotion_ros.core.tolerances.MAX_SAMPLES`
      commands (every sampled planner's horizon) and :func:`check_plannable`.

    Raises
    ------
    GoalError
        Naming ``goal`` and the budget ``max_move_duration_s`` or the sample budget.
    ConfigError
        From :func:`check_plannable` (a mode above the Nyquist frequency).
    """
    T = rigid_time(problem.model, problem.u_max, problem.shifted_initial(), problem.include_position)
    if not T <= config.max_move_duration_s:
        raise GoalError(
            "goal",
            f"the move needs at least {T:.4g} s (rigid-body minimum time), over the budget max_move_duration_s = "
            f"{config.max_move_duration_s:g} s; move less far or raise max_move_duration_s",
        )
    stiff = abs(problem.model.c) * T
    if stiff > MAX_VISCOUS_SPAN:
        raise ModelError(
            "model.c",
            f"the rigid body's velocity relaxes in 1/|c| = {1.0 / abs(problem.model.c):.3g} s, {stiff:.3g} times "
            f"within the move's {T:.4g} s (over {MAX_VISCOUS_SPAN:.0e}): double precision cannot bring it exactly "
            "to rest (error ~1e-16 |c| T); use a smaller |c| or a shorter move",
        )
    if rate_hz:
        rate = check_plannable(config, rate_hz)
        if T * rate > MAX_SAMPLES:
            raise GoalError(
                "goal",
                f"the move needs at least {T:.4g} s (rigid-body minimum time): over {MAX_SAMPLES:.0e} samples at "
                f"{rate:g} Hz, the sample budget; move less far or lower rate_hz",
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
