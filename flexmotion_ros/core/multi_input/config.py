"""The multi-input planner configuration: one validated object, built from the flat ROS parameters.

The parameter file of a multi-input machine is the single-input one with
``model.inputs`` (that is what makes it multi-input), flat row-major
matrices and one bound per input (:mod:`.parse`)::

    /**:
      ros__parameters:
        model:
          inputs: [trolley, bridge]          # m actuated joints
          rigid_bodies: [x, y]               # k rigid-body coordinates
          b0: [0.004, 0.0, 0.0, 0.0018]      # k x m, row-major (1/kg)
          c: [0.0, 0.0]
          omega: [1.85, 2.48]                # rad/s
          zeta: [0.0, 0.0]
          b: [0.0, -0.0006, -0.0025, 0.0]    # N x m, row-major
        u_max: [300.0, 500.0]                # N, one per input
        rate_hz: 1000.0
        sync: time                           # time | none | phase

:class:`MultiPlannerConfig` is what :class:`~flexmotion_ros.core.config.PlannerConfig`
is for one input: everything a planner needs besides the goal, validated once
(the model's controllability, the bounds, ``sync``, the method, the rate and
the Nyquist check, the move budgets).  The move budgets are refused up front
from a closed-form lower bound (:func:`rigid_lower_bound`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..config import (
    DEFAULTS,
    NOT_OPTION_PREFIXES,
    NOT_OPTIONS,
    check_budget_fields,
    check_rate_hz,
    check_sample_budget,
    check_sampling,
)
from ..errors import ConfigError, GoalError
from ..model.modal_model import ModalModel
from ..parameter_checks import check_required_options
from ..parameters import MAX_MOVE_DURATION_S, MAX_MOVE_SAMPLES
from ..time_optimal.rigid_body import rigid_time
from .methods import check_multi_method
from .model import MultiModel
from .parse import PARAMETER_NAMES, multi_setup_from_parameters
from .problem import MultiMoveProblem, check_bounds


@dataclass(frozen=True)
class MultiPlannerConfig:
    """Everything a multi-input planner needs besides the goal (validated).

    Attributes
    ----------
    model : MultiModel
        ``k`` rigid bodies, ``N`` modes, ``m`` inputs (controllable).
    u_max : tuple of float
        One bound per input (N or the input's unit), each > 0.
    rate_hz : float
        Command rate (Hz).
    method : str
        One of :data:`~flexmotion_ros.core.multi_input.methods.MULTI_METHODS`.
    sync : str
        ``time`` (default), ``none`` or ``phase``.
    fuel_weights : tuple of float
        ``c_i`` of eq. 2.38, one per input (``min_fuel``; default all 1).
    position_min, position_max : float
        Allowed goal positions of every rigid body (m or rad); infinite: no limit.
    options : dict
        Method options (dotted names).
    max_move_duration_s : float
        Longest move a goal may ask for (s).
    max_move_samples : int
        Most command samples a goal's plan may need at ``rate_hz``.
    """

    model: MultiModel
    u_max: tuple
    rate_hz: float = 1000.0
    method: str = "time_optimal"
    sync: str = "time"
    fuel_weights: tuple | None = None
    position_min: float = -math.inf
    position_max: float = math.inf
    options: dict = field(default_factory=dict)
    max_move_duration_s: float = MAX_MOVE_DURATION_S
    max_move_samples: int = MAX_MOVE_SAMPLES

    def __post_init__(self) -> None:
        # tuples, not arrays: a configuration compares with == (the node's against the command line's)
        object.__setattr__(self, "u_max", tuple(float(v) for v in check_bounds(self.u_max, self.model.m)))
        weights = np.ones(self.model.m) if self.fuel_weights is None else self.fuel_weights
        object.__setattr__(
            self, "fuel_weights", tuple(float(v) for v in check_bounds(weights, self.model.m, "fuel_weights"))
        )
        object.__setattr__(self, "rate_hz", check_rate_hz(self.rate_hz))
        check_multi_method(self.method)
        check_sampling(self.model, self.rate_hz)  # the Nyquist check reads only omega
        lo, hi = float(self.position_min), float(self.position_max)
        if math.isnan(lo) or math.isnan(hi) or lo >= hi:
            raise ConfigError("limits.position_min/position_max", f"need position_min < position_max, got [{lo}, {hi}]")
        object.__setattr__(self, "position_min", lo)
        object.__setattr__(self, "position_max", hi)
        duration, samples = check_budget_fields(self.max_move_duration_s, self.max_move_samples)
        object.__setattr__(self, "max_move_duration_s", duration)
        object.__setattr__(self, "max_move_samples", samples)
        check_required_options(self.method, self.options)

    # ------------------------------------------------------------------ sizes
    @property
    def m(self) -> int:
        """Number of inputs."""
        return self.model.m

    @property
    def k(self) -> int:
        """Number of rigid bodies."""
        return self.model.k

    def check_goal(self, targets) -> np.ndarray:
        """One target per rigid body (m or rad), finite and inside the limits; NaN: keep (filled in later).

        Raises
        ------
        GoalError
            Naming ``goal`` (wrong count) or ``goal[j]`` and the rigid body.
        """
        try:
            t = np.asarray(targets, dtype=float).ravel()
        except (TypeError, ValueError):
            raise GoalError("goal", f"must be one finite position per rigid body, got {targets!r}") from None
        names = self.model.rigid_bodies
        if t.size != self.k:
            raise GoalError(
                "goal", f"needs one target per rigid body {list(names)} ({self.k}), got {t.size}: {t.tolist()}"
            )
        for j, v in enumerate(t):
            if math.isnan(v):
                continue
            if not math.isfinite(v):
                raise GoalError(f"goal[{j}]", f"must be a finite position ({names[j]}), got {v}")
            if not self.position_min <= v <= self.position_max:
                raise GoalError(
                    f"goal[{j}]",
                    f"{v} ({names[j]}) is outside the position limits [{self.position_min}, {self.position_max}]",
                )
        return t

    def with_changes(self, **changes: Any) -> MultiPlannerConfig:
        """A validated copy with some fields replaced."""
        return replace(self, **changes)

    def to_parameters(self) -> dict[str, Any]:
        """Flat ROS parameter dictionary (dotted names)."""
        p: dict[str, Any] = {f"model.{k}": v for k, v in self.model.to_dict().items()}
        p["model.mode_names"] = list(self.model.mode_names)
        p.update(
            {
                "u_max": [float(v) for v in self.u_max],
                "rate_hz": self.rate_hz,
                "method": self.method,
                "sync": self.sync,
                "limits.position_min": self.position_min,
                "limits.position_max": self.position_max,
                "max_move_duration_s": self.max_move_duration_s,
                "max_move_samples": self.max_move_samples,
            }
        )
        if self.fuel_weights is not None and np.any(np.asarray(self.fuel_weights) != 1.0):
            p["fuel_weights"] = [float(v) for v in self.fuel_weights]
        p.update(self.options)
        return p


def _set(value: Any) -> bool:
    """rcl's notion of a value being given: not None, not an empty list."""
    return value is not None and not (isinstance(value, (list, tuple)) and not value)


def multi_config_from_parameters(params: Mapping[str, Any]) -> MultiPlannerConfig:
    """Build and validate a :class:`MultiPlannerConfig` from flat ROS parameters (``model.inputs`` given).

    Unset names (None, ``[]``) take the defaults; the names of the nodes,
    the plant, rclpy and the design command are dropped; the others are the
    method options.  As :func:`~flexmotion_ros.core.config.config_from_parameters`,
    names and ROS types are judged before, by
    :func:`~flexmotion_ros.core.parameter_checks.check_parameters`.

    Raises
    ------
    ModelError, ConfigError
        Naming the parameter (sizes, controllability naming the mode and the inputs, bounds, ``sync``, method).
    """
    p = {k: v for k, v in params.items() if _set(v)}
    defaults = {k: v for k, v in DEFAULTS.items() if k not in ("model.b0", "model.c", "u_max")}
    merged = {**defaults, **p}
    if "u_max" not in p:
        merged["u_max"] = DEFAULTS["u_max"]
    setup = multi_setup_from_parameters({k: v for k, v in merged.items() if k in PARAMETER_NAMES})
    multi_names = set(PARAMETER_NAMES)
    options = {
        k: v
        for k, v in merged.items()
        if k not in DEFAULTS and k not in multi_names and k not in NOT_OPTIONS and not k.startswith(NOT_OPTION_PREFIXES)
    }
    return MultiPlannerConfig(
        model=setup.model,
        u_max=setup.u_max,
        rate_hz=merged["rate_hz"],
        method=str(merged["method"]),
        sync=setup.sync,
        fuel_weights=setup.fuel_weights,
        position_min=merged["limits.position_min"],
        position_max=merged["limits.position_max"],
        options=options,
        max_move_duration_s=merged["max_move_duration_s"],
        max_move_samples=merged["max_move_samples"],
    )


def rigid_lower_bound(problem: MultiMoveProblem) -> float:
    """A closed-form lower bound (s) on any move of ``problem``: the slowest rigid body on its own.

    Rigid body ``j`` accelerates at most ``sum_i |b0[j, i]| u_max[i]`` whatever
    the inputs do, so the time-optimal move of a single rigid body with that
    bound (and its viscous term ``c_j``) from its own start to its own target
    (or to rest, if free) is a lower bound for the whole machine.
    """
    model = problem.model
    B0 = model.B0
    shift = problem.x0 - problem.target_state()
    T = 0.0
    for j in range(model.k):
        gain = float(np.abs(B0[j]) @ np.asarray(problem.u_max, float))
        body = ModalModel(b0=gain, c=model.c[j])
        x0 = shift[2 * j : 2 * j + 2]
        has_position = problem.targets[j] is not None
        T = max(T, rigid_time(body, 1.0, x0 if has_position else x0[1:], has_position))
    return T


def check_multi_move_budget(config: MultiPlannerConfig, problem: MultiMoveProblem, rate_hz: float | None = None) -> int:
    """Refuse, in microseconds, a goal over ``max_move_duration_s`` or ``max_move_samples`` (lower bound).

    Returns
    -------
    int
        The lower bound on the samples at the rate (Hz; None: ``config.rate_hz``).

    Raises
    ------
    GoalError
        Naming ``goal`` and the budget.
    """
    T = rigid_lower_bound(problem)
    if not T <= config.max_move_duration_s:
        raise GoalError(
            "goal",
            f"the move needs at least {T:.4g} s (rigid-body minimum time), over the budget max_move_duration_s = "
            f"{config.max_move_duration_s:g} s; move less far or raise max_move_duration_s",
        )
    return check_sample_budget(T, float(rate_hz) if rate_hz else config.rate_hz, config.max_move_samples)


__all__ = [
    "MultiPlannerConfig",
    "check_multi_move_budget",
    "multi_config_from_parameters",
    "rigid_lower_bound",
]
