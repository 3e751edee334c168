"""Planner configuration and the ROS 2 parameter file it lives in.

The same file serves ``flexmotion plan --config FILE`` and the nodes
(``--ros-args --params-file FILE``)::

    /**:
      ros__parameters:
        model:
          b0: 0.5
          c: 0.0
          omega: [1.4142135623730951]
          zeta: [0.0]
          b: [1.0]
        u_max: 1.0
        rate_hz: 1000.0

Nested keys are ROS parameter names with dots (``model.b0``).  The file is
read and written by :mod:`.parameter_file` (rcl's typing rules, without ROS);
:func:`load_config` then refuses unknown names and wrong types
(:func:`~flexmotion_ros.core.parameter_checks.check_parameters`, the check the nodes
run on their start-up parameters too) before building the configuration.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from .errors import ConfigError, GoalError
from .model.boundary import MoveProblem
from .model.measurement import measurement_map
from .model.modal_model import ModalModel, check_positive
from .parameter_checks import check_parameters, check_required_options
from .parameter_file import (
    dump_parameters,
    flatten,
    read_parameter_file,
    read_parameter_sections,
    unflatten,
)
from .parameters import (
    KNOWN_PREFIXES,
    MAX_MOVE_DURATION_S,
    MAX_MOVE_SAMPLES,
    NODE_NAMES,
)
from .shaping.shapers import SHAPERS
from .time_optimal.rigid_body import rigid_time

#: The planning methods, in the order of :data:`~flexmotion_ros.core.methods.METHODS` (which
#: holds their planners and checks that the two lists agree): the default first, then every shaper.
METHOD_NAMES: tuple[str, ...] = (
    "time_optimal",
    *SHAPERS,
    "robust_time_optimal",
    "time_optimal_friction",
    "fixed_time",
    "min_fuel",
    "limited",
    "auto_robust",
)

DEFAULTS: dict[str, Any] = {
    "model.b0": 1.0,
    "model.c": 0.0,
    "model.omega": [],
    "model.zeta": [],
    "model.b": [],
    "u_max": 1.0,
    "rate_hz": 1000.0,
    "method": "time_optimal",
    "limits.position_min": -math.inf,
    "limits.position_max": math.inf,
    "max_move_duration_s": MAX_MOVE_DURATION_S,
    "max_move_samples": MAX_MOVE_SAMPLES,
}


#: Parameters in a shared file that belong to the nodes, the plant, rclpy or
#: the design command, never to a planning method (from the registry,
#: :mod:`flexmotion_ros.core.parameters`).
NOT_OPTION_PREFIXES = ("plant.", *KNOWN_PREFIXES)
NOT_OPTIONS = NODE_NAMES


@dataclass(frozen=True)
class PlannerConfig:
    """Everything a planner needs besides the goal.

    Attributes
    ----------
    model : ModalModel
    u_max : float
        Actuator bound ``|u| <= u_max`` (N or the model's input unit).
    rate_hz : float
        Command rate (Hz).
    method : str
        Profile type (one of :data:`METHOD_NAMES`).
    position_min, position_max : float
        Allowed goal positions (m or rad); infinite means no limit.
    max_move_duration_s : float
        Longest move a goal may ask for (s, > 0): a goal whose rigid-body
        minimum time exceeds it is refused before planning.
    max_move_samples : int
        Most command samples a goal's plan may need at ``rate_hz`` (>= 1):
        a goal whose rigid-body minimum time exceeds it is refused before
        planning (:func:`check_move_samples`, by the nodes and ``flexmotion plan``).
    options : dict
        Method-specific parameters (dotted names), validated by their method.
    """

    model: ModalModel
    u_max: float = 1.0
    rate_hz: float = 1000.0
    method: str = "time_optimal"
    position_min: float = -math.inf
    position_max: float = math.inf
    options: dict = field(default_factory=dict)
    max_move_duration_s: float = MAX_MOVE_DURATION_S
    max_move_samples: int = MAX_MOVE_SAMPLES

    def __post_init__(self) -> None:
        object.__setattr__(self, "u_max", check_positive("u_max", self.u_max))
        object.__setattr__(self, "rate_hz", check_rate_hz(self.rate_hz))
        if self.method not in METHOD_NAMES:
            raise ConfigError("method", f"must be one of {sorted(METHOD_NAMES)}, got {self.method!r}")
        lo, hi = float(self.position_min), float(self.position_max)
        if math.isnan(lo) or math.isnan(hi) or lo >= hi:
            raise ConfigError("limits.position_min/position_max", f"need position_min < position_max, got [{lo}, {hi}]")
        object.__setattr__(self, "position_min", lo)
        object.__setattr__(self, "position_max", hi)
        duration, samples = check_budget_fields(self.max_move_duration_s, self.max_move_samples)
        object.__setattr__(self, "max_move_duration_s", duration)
        object.__setattr__(self, "max_move_samples", samples)
        check_required_options(self.method, self.options)

    def check_goal(self, target: float) -> float:
        """Return ``target`` if finite and inside the position limits, else raise."""
        try:
            t = float(target)
        except (TypeError, ValueError):
            raise GoalError("goal", f"must be a finite position, got {target!r}") from None
        if not math.isfinite(t):
            raise GoalError("goal", f"must be a finite position, got {t}")
        if not self.position_min <= t <= self.position_max:
            raise GoalError("goal", f"{t} is outside the position limits [{self.position_min}, {self.position_max}]")
        return t

    def with_changes(self, **changes: Any) -> PlannerConfig:
        """A validated copy with some fields replaced."""
        return replace(self, **changes)

    def to_parameters(self) -> dict[str, Any]:
        """Flat ROS parameter dictionary (dotted names)."""
        p: dict[str, Any] = {f"model.{k}": v for k, v in self.model.to_dict().items()}
        p.update(
            {
                "u_max": self.u_max,
                "rate_hz": self.rate_hz,
                "method": self.method,
                "limits.position_min": self.position_min,
                "limits.position_max": self.position_max,
                "max_move_duration_s": self.max_move_duration_s,
                "max_move_samples": self.max_move_samples,
            }
        )
        p.update(self.options)
        return p


#: Highest command rate (Hz) a configuration or a plan accepts.
MAX_RATE_HZ = 1e6


def check_rate_hz(value: Any, parameter: str = "rate_hz") -> float:
    """``value`` as a command rate in Hz, the one check of a rate (config and :func:`plan_move`).

    ``plan_move`` validates its ``rate_hz`` here once and passes the float
    down.  The low-level planners users also call directly keep their own
    ``rate_hz > 0`` check (public entry points): ``plan_time_optimal_zoh``,
    ``plan_fixed_time_zoh``, ``plan_min_fuel_zoh``, ``sampled_fuel_curve``,
    ``plan_limited_zoh`` and ``plan_time_optimal_friction_zoh``;
    ``fuel_time_curve`` leaves it to ``plan_min_fuel_zoh``, and the helpers
    only reached through ``plan_move`` (``sample_command``,
    ``plan_robust_time_optimal_zoh``) do not check it.

    Parameters
    ----------
    value : float
        The rate (Hz): finite, ``> 0`` and at most :data:`MAX_RATE_HZ`.
    parameter : str
        The parameter's name for the error.

    Raises
    ------
    ConfigError
        Naming ``parameter`` and the allowed range ``(0, 1e6] Hz``.
    """
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = math.nan
    if not (math.isfinite(x) and 0.0 < x <= MAX_RATE_HZ):
        raise ConfigError(parameter, f"must be in (0, 1e6] Hz (finite, > 0), got {value!r}")
    return x


def check_sampling(model: ModalModel, rate_hz: float) -> None:
    """Refuse a mode at or above the Nyquist frequency ``pi x rate_hz`` (rad/s) of the command.

    A command held for ``1 / rate_hz`` s cannot resolve such a mode: it aliases
    (at ``omega = 2 pi k rate_hz`` it is not controllable at all) and an exact
    plan for it is ill-conditioned (issue 16: 1e5 rad/s at 1 kHz planned for
    36.9 s).  A physical fact, so a parameter set with it is refused when it
    is set, naming the mode and the rate it would need.

    Raises
    ------
    ConfigError
        Naming ``model.omega[i]``, the Nyquist frequency and the rate needed.
    """
    nyquist = math.pi * float(rate_hz)
    for i, w in enumerate(model.omega):
        if w >= nyquist:
            raise ConfigError(
                f"model.omega[{i}]",
                f"{w:g} rad/s is at or above the Nyquist frequency pi x rate_hz = {nyquist:.6g} rad/s of a "
                f"{rate_hz:g} Hz command, which cannot resolve it; raise rate_hz above {w / math.pi:.6g} Hz "
                "or leave the mode out",
            )


def check_move_samples(config: PlannerConfig, problem: MoveProblem, rate_hz: float | None = None) -> int:
    """Refuse, in microseconds, a goal whose plan would need more than ``config.max_move_samples`` samples.

    The count is a lower bound: the rigid body's own minimum time (closed
    form) times the rate, so only goals that certainly exceed the budget
    are refused (issue 16: a goal of 1e6 was a 47-minute move planned in 8.6 s).

    Parameters
    ----------
    config : PlannerConfig
    problem : MoveProblem
    rate_hz : float, optional
        The plan's rate (Hz); None: ``config.rate_hz``.

    Returns
    -------
    int
        The lower bound on the samples.

    Raises
    ------
    GoalError
        Naming ``goal`` and the budget ``max_move_samples``.
    """
    T = rigid_time(problem.model, problem.u_max, problem.shifted_initial(), problem.include_position)
    return check_sample_budget(T, float(rate_hz) if rate_hz else config.rate_hz, config.max_move_samples)


def check_sample_budget(T: float, rate_hz: float, max_move_samples: int) -> int:
    """``ceil(T rate_hz)``, refused (GoalError naming ``goal``) over ``max_move_samples``; one input or several.

    ``T`` (s) is a rigid-body lower bound on the move's duration, so only moves that certainly exceed the
    budget are refused.
    """
    samples = T * rate_hz
    if not samples <= max_move_samples:
        raise GoalError(
            "goal",
            f"the move needs at least {samples:.4g} samples at {rate_hz:g} Hz ({T:.4g} s, rigid-body minimum time), "
            f"over the budget max_move_samples = {max_move_samples}; move less far or raise max_move_samples",
        )
    return math.ceil(samples)


def check_budget_fields(max_move_duration_s: Any, max_move_samples: Any) -> tuple[float, int]:
    """The two move budgets of a configuration, validated: ``(max_move_duration_s, max_move_samples)``.

    Raises
    ------
    ConfigError
        Naming the budget: a duration that is not finite and > 0 s, a sample count that is not an integer >= 1.
    """
    try:
        duration = float(max_move_duration_s)
    except (TypeError, ValueError):
        duration = math.nan
    if not (math.isfinite(duration) and duration > 0.0):
        raise ConfigError("max_move_duration_s", f"must be a finite duration > 0 s, got {max_move_duration_s!r}")
    samples = max_move_samples
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 1:
        raise ConfigError("max_move_samples", f"must be an integer >= 1, got {samples!r}")
    return duration, int(samples)


def config_from_parameters(params: Mapping[str, Any]) -> PlannerConfig:
    """Build and validate a :class:`PlannerConfig` from flat ROS parameters.

    Missing (or unset: ``None``) names take :data:`DEFAULTS`; the names of
    the nodes, the plant, rclpy and the design command are dropped
    (:data:`NOT_OPTIONS`, :data:`NOT_OPTION_PREFIXES`); the other names are
    kept in ``options`` for the methods to validate.  This is the Python
    entry point and does not judge names or types: a parameter set from a
    file, ``--option`` or a node goes through
    :func:`~flexmotion_ros.core.parameter_checks.check_parameters` first
    (:func:`load_config` and the nodes do), which refuses unknown names and
    wrong ROS types.
    """
    p = dict(DEFAULTS)
    p.update({k: v for k, v in params.items() if v is not None})
    model = ModalModel(
        b0=p["model.b0"],
        c=p["model.c"],
        omega=tuple(p["model.omega"] or ()),
        zeta=tuple(p["model.zeta"] or ()),
        b=tuple(p["model.b"] or ()),
    )
    options = {
        k: v
        for k, v in p.items()
        if k not in DEFAULTS
        and k not in NOT_OPTIONS
        and not k.startswith(NOT_OPTION_PREFIXES)
        and not (isinstance(v, (list, tuple)) and not v)  # an empty list is unset, as in rcl
    }
    check_sampling(model, check_rate_hz(p["rate_hz"]))
    measurement_map(p, model.n_modes)  # measurement.* fit the model: the nodes give the same verdict
    return PlannerConfig(
        model=model,
        u_max=p["u_max"],
        rate_hz=p["rate_hz"],
        method=str(p["method"]),
        position_min=p["limits.position_min"],
        position_max=p["limits.position_max"],
        options=options,
        max_move_duration_s=p["max_move_duration_s"],
        max_move_samples=p["max_move_samples"],
    )


def load_config(path: str | Path, node_name: str | None = "flexmotion_planner") -> PlannerConfig:
    """Read, check (names and ROS types) and validate a planner configuration from a ROS 2 parameter file."""
    params = read_parameter_file(path, node_name)
    check_parameters(params)
    return config_from_parameters(params)


def write_config(path: str | Path, config: PlannerConfig, header: str = "") -> None:
    """Write ``config`` as a ROS 2 parameter file (finite limits only, the move budgets if not the defaults)."""
    params = config.to_parameters()
    for key in ("limits.position_min", "limits.position_max"):
        if not math.isfinite(params[key]):
            del params[key]
    if params["max_move_duration_s"] == MAX_MOVE_DURATION_S:
        del params["max_move_duration_s"]
    if params["max_move_samples"] == MAX_MOVE_SAMPLES:
        del params["max_move_samples"]
    Path(path).write_text(dump_parameters(params, header))


#: Re-exported: the parameter file's reader and writer live in :mod:`.parameter_file`.
__all__ = [
    "DEFAULTS",
    "MAX_RATE_HZ",
    "METHOD_NAMES",
    "NOT_OPTIONS",
    "NOT_OPTION_PREFIXES",
    "PlannerConfig",
    "check_move_samples",
    "check_budget_fields",
    "check_rate_hz",
    "check_sample_budget",
    "check_sampling",
    "config_from_parameters",
    "dump_parameters",
    "flatten",
    "load_config",
    "read_parameter_file",
    "read_parameter_sections",
    "unflatten",
    "write_config",
]
