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

Nested keys are ROS parameter names with dots (``model.b0``).  This module
reads and writes that format without ROS; the nodes map their declared
parameters through :func:`config_from_parameters` too, so both validate alike.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import yaml

from .errors import ConfigError
from .model.modal_model import ModalModel, check_positive
from .shaping.shapers import SHAPERS

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
}


#: Parameters in a shared file that belong to the nodes, the plant, rclpy or
#: the design command, never to a planning method.
NOT_OPTION_PREFIXES = ("plant.", "design.", "qos_overrides.")
NOT_OPTIONS = frozenset(
    {
        "lockstep",
        "command_timeout",
        "publish_rate_hz",
        "publish_hold_when_idle",
        "stream_priority",
        "initial_position",
        "replan_lead_s",
        "max_trajectory_points",
        "frame_id",
        "diagnostics_period_s",
        "use_sim_time",
        "start_type_description_service",
    }
)


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

    def check_goal(self, target: float) -> float:
        """Return ``target`` if finite and inside the position limits, else raise."""
        from .errors import GoalError

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


def flatten(tree: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """``{"model": {"b0": 1}}`` -> ``{"model.b0": 1}``."""
    out: dict[str, Any] = {}
    for key, value in tree.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            out.update(flatten(value, name + "."))
        else:
            out[name] = value
    return out


def unflatten(params: Mapping[str, Any]) -> dict[str, Any]:
    """Inverse of :func:`flatten`."""
    tree: dict[str, Any] = {}
    for name, value in params.items():
        node = tree
        parts = name.split(".")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = value
    return tree


def config_from_parameters(params: Mapping[str, Any]) -> PlannerConfig:
    """Build and validate a :class:`PlannerConfig` from flat ROS parameters.

    Missing names take :data:`DEFAULTS`; other names are kept in ``options``
    for the methods to validate, except those of the nodes, the plant and the
    design command (:data:`NOT_OPTIONS`, :data:`NOT_OPTION_PREFIXES`).
    """
    p = dict(DEFAULTS)
    p.update(params)
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
        if k not in DEFAULTS and k not in NOT_OPTIONS and not k.startswith(NOT_OPTION_PREFIXES)
    }
    return PlannerConfig(
        model=model,
        u_max=p["u_max"],
        rate_hz=p["rate_hz"],
        method=str(p["method"]),
        position_min=p["limits.position_min"],
        position_max=p["limits.position_max"],
        options=options,
    )


def read_parameter_file(path: str | Path, node_name: str | None = None) -> dict[str, Any]:
    """Flat parameters from a ROS 2 parameter YAML file.

    Takes the ``ros__parameters`` of ``/**`` (wildcard) and, if given, of
    ``node_name`` (which override the wildcard), as ROS does.
    """
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except FileNotFoundError:
        raise ConfigError("config", f"file not found: {path}") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ConfigError("config", f"{path} is not valid YAML{where}: {problem}") from None
    if not isinstance(data, Mapping):
        raise ConfigError("config", f"{path}: expected a mapping of node names to ros__parameters")
    params: dict[str, Any] = {}
    keys = ["/**", "**"]
    if node_name:
        bare = node_name.lstrip("/")
        keys += [bare, "/" + bare]  # ROS matches 'node' and '/node' alike
    found = False
    for key in keys:
        section = data.get(key)
        if isinstance(section, Mapping) and isinstance(section.get("ros__parameters"), Mapping):
            params.update(flatten(section["ros__parameters"]))
            found = True
    if not found:
        raise ConfigError("config", f"{path}: no '/**: ros__parameters:' section")
    return params


def load_config(path: str | Path, node_name: str | None = "flexmotion_planner") -> PlannerConfig:
    """Read and validate a planner configuration from a ROS 2 parameter file."""
    return config_from_parameters(read_parameter_file(path, node_name))


class _Dumper(yaml.SafeDumper):
    pass


def _float_repr(dumper: yaml.SafeDumper, value: float):
    # ROS parameter files need doubles to look like doubles: 2.0, not 2
    if math.isinf(value):
        text = ".inf" if value > 0 else "-.inf"
    elif math.isnan(value):
        text = ".nan"
    else:
        text = repr(float(value))
        if "e" in text and "." not in text.split("e")[0]:
            mant, exp = text.split("e")
            text = f"{mant}.0e{exp}"
    return dumper.represent_scalar("tag:yaml.org,2002:float", text)


_Dumper.add_representer(float, _float_repr)


def dump_parameters(params: Mapping[str, Any], header: str = "") -> str:
    """A ROS 2 parameter file (``/**: ros__parameters:``) for flat parameters."""
    clean = {
        k: (float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) and k not in _INT_PARAMS else v)
        for k, v in params.items()
    }
    clean = {k: ([float(x) for x in v] if isinstance(v, (list, tuple)) else v) for k, v in clean.items()}
    body = yaml.dump(
        {"/**": {"ros__parameters": unflatten(clean)}}, Dumper=_Dumper, sort_keys=False, default_flow_style=None
    )
    return (header + body) if header else body


#: Parameters that are integers, not doubles.
_INT_PARAMS = {"robust_order", "design.force_on", "fuel_curve.points"}


def write_config(path: str | Path, config: PlannerConfig, header: str = "") -> None:
    """Write ``config`` as a ROS 2 parameter file (finite limits only)."""
    params = config.to_parameters()
    for key in ("limits.position_min", "limits.position_max"):
        if not math.isfinite(params[key]):
            del params[key]
    Path(path).write_text(dump_parameters(params, header))
