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
reads and writes that format without ROS, typing every value by rcl's own
rules (:func:`~flexmotion_ros.core.parameters.rcl_scalar`: ``1`` is an
integer, ``1.0`` a double) so that ``flexmotion plan`` and the nodes see the
same types; :func:`load_config` then refuses unknown names and wrong types
(:func:`~flexmotion_ros.core.parameters.check_parameters`, the check the nodes
run on their start-up parameters too) before building the configuration.
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
from .parameters import (
    KNOWN_PREFIXES,
    MAX_MOVE_DURATION_S,
    NODE_NAMES,
    check_parameters,
    check_required_options,
    rcl_scalar,
    ros_type,
)
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
    "max_move_duration_s": MAX_MOVE_DURATION_S,
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
        budget = self.max_move_duration_s
        try:
            budget = float(budget)
        except (TypeError, ValueError):
            budget = math.nan
        if not (math.isfinite(budget) and budget > 0.0):
            raise ConfigError(
                "max_move_duration_s", f"must be a finite duration > 0 s, got {self.max_move_duration_s!r}"
            )
        object.__setattr__(self, "max_move_duration_s", budget)
        check_required_options(self.method, self.options)

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
                "max_move_duration_s": self.max_move_duration_s,
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

    Missing (or unset: ``None``) names take :data:`DEFAULTS`; the names of
    the nodes, the plant, rclpy and the design command are dropped
    (:data:`NOT_OPTIONS`, :data:`NOT_OPTION_PREFIXES`); the other names are
    kept in ``options`` for the methods to validate.  This is the Python
    entry point and does not judge names or types: a parameter set from a
    file, ``--option`` or a node goes through
    :func:`~flexmotion_ros.core.parameters.check_parameters` first
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
    return PlannerConfig(
        model=model,
        u_max=p["u_max"],
        rate_hz=p["rate_hz"],
        method=str(p["method"]),
        position_min=p["limits.position_min"],
        position_max=p["limits.position_max"],
        options=options,
        max_move_duration_s=p["max_move_duration_s"],
    )


def _yaml_error(path: Path, exc: yaml.YAMLError, parameter: str) -> ConfigError:
    mark = getattr(exc, "problem_mark", None)
    where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    return ConfigError(parameter, f"{path} is not valid YAML{where}: {problem}")


def _typed_tree(node: yaml.Node, name: str, path: Path, parameter: str) -> Any:
    """A composed YAML node as rcl reads it: mappings nest, scalars and sequences are typed."""
    line = node.start_mark.line + 1
    if isinstance(node, yaml.MappingNode):
        out: dict[str, Any] = {}
        for key, value in node.value:
            if not isinstance(key, yaml.ScalarNode):
                raise ConfigError(parameter, f"{path}: a key must be a name (line {key.start_mark.line + 1})")
            out[key.value] = _typed_tree(value, f"{name}.{key.value}" if name else key.value, path, parameter)
        return out if out else None  # 'x: {}' declares x with no value in rcl
    if isinstance(node, yaml.SequenceNode):
        items: list[Any] = []
        stack = list(node.value)
        while stack:  # rcl flattens nested sequences
            item = stack.pop(0)
            if isinstance(item, yaml.SequenceNode):
                stack[:0] = list(item.value)
                continue
            if not isinstance(item, yaml.ScalarNode):
                raise ConfigError(name, f"{path}: a list holds values only (line {item.start_mark.line + 1})")
            items.append(_scalar(item, name, path))
        try:
            ros_type(items)
        except TypeError:
            kinds = ", ".join(dict.fromkeys(str(ros_type(v).value) for v in items))
            raise ConfigError(
                name,
                f"{path} line {line}: list items must all have one type (ROS arrays are homogeneous; "
                f"write doubles as 2.0, not 2), got {kinds}",
            ) from None
        return items
    return _scalar(node, name, path)


def _scalar(node: yaml.Node, name: str, path: Path) -> Any:
    quoted = node.style in ("'", '"')
    if not quoted and node.value == "":
        raise ConfigError(name, f"{path}: no value at line {node.start_mark.line + 1}")
    return rcl_scalar(node.value, quoted)


def read_parameter_sections(path: str | Path, parameter: str = "config") -> dict[str, dict[str, Any]]:
    """Every section of a ROS 2 parameter file: ``{node name: flat typed ros__parameters}``.

    Values are typed by rcl's rules (:func:`~flexmotion_ros.core.parameters.rcl_scalar`);
    a value rcl refuses (no value, a mixed list), a YAML syntax error or an
    unreadable file raises :class:`ConfigError` naming ``parameter``, the
    file and, for syntax errors, the line and column.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise ConfigError(parameter, f"file not found: {path}") from None
    except IsADirectoryError:
        raise ConfigError(parameter, f"{path} is a directory, not a parameter file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(parameter, f"cannot read {path}: {getattr(exc, 'strerror', None) or exc}") from None
    try:
        root = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.YAMLError as exc:
        raise _yaml_error(path, exc, parameter) from None
    if not isinstance(root, yaml.MappingNode):
        raise ConfigError(parameter, f"{path}: expected a mapping of node names to ros__parameters")
    sections: dict[str, dict[str, Any]] = {}
    for key, value in root.value:
        if not isinstance(key, yaml.ScalarNode) or not isinstance(value, yaml.MappingNode):
            raise ConfigError(parameter, f"{path}: expected a mapping of node names to ros__parameters")
        for sub_key, sub in value.value:
            if isinstance(sub_key, yaml.ScalarNode) and sub_key.value == "ros__parameters":
                if not isinstance(sub, yaml.MappingNode):
                    raise ConfigError(
                        parameter,
                        f"{path}: 'ros__parameters' of '{key.value}' must be a mapping of parameter names to values "
                        f"(line {sub.start_mark.line + 1})",
                    )
                tree = _typed_tree(sub, "", path, parameter)
                sections.setdefault(key.value, {}).update(flatten(tree or {}))
    return sections


def read_parameter_file(path: str | Path, node_name: str | None = None, parameter: str = "config") -> dict[str, Any]:
    """Flat parameters from a ROS 2 parameter YAML file, typed by rcl's rules.

    Takes the ``ros__parameters`` of ``/**`` (wildcard) and, if given, of
    ``node_name`` (which override the wildcard), as ROS does.
    """
    path = Path(path)
    data = read_parameter_sections(path, parameter)
    params: dict[str, Any] = {}
    keys = ["/**", "**"]
    if node_name:
        bare = node_name.lstrip("/")
        keys += [bare, "/" + bare]  # ROS matches 'node' and '/node' alike
    found = False
    for key in keys:
        if key in data:
            params.update(data[key])
            found = True
    if not found:
        raise ConfigError(parameter, f"{path}: no '/**: ros__parameters:' section")
    return params


def load_config(path: str | Path, node_name: str | None = "flexmotion_planner") -> PlannerConfig:
    """Read, check (names and ROS types) and validate a planner configuration from a ROS 2 parameter file."""
    params = read_parameter_file(path, node_name)
    check_parameters(params)
    return config_from_parameters(params)


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
    """Write ``config`` as a ROS 2 parameter file (finite limits only, the move budget if not the default)."""
    params = config.to_parameters()
    for key in ("limits.position_min", "limits.position_max"):
        if not math.isfinite(params[key]):
            del params[key]
    if params["max_move_duration_s"] == MAX_MOVE_DURATION_S:
        del params["max_move_duration_s"]
    Path(path).write_text(dump_parameters(params, header))
