"""The one registry of parameter names, and ROS 2's typing rules without ROS.

Every name a parameter file, ``flexmotion ... --option`` or a node may carry is
listed here once, with its ROS type, unit and allowed values:

* :data:`CONFIG_PARAMETERS`: the planner configuration
  (:class:`~flexmotion_ros.core.config.PlannerConfig`);
* :data:`METHOD_OPTIONS`: the planning methods' options, each with the methods
  that read it and those that require it (the method modules read their
  descriptions and requirements from here: the configuration checks them
  without importing the planners);
* :data:`PLANNER_NODE_PARAMETERS`, :data:`PLANT_NODE_PARAMETERS`: parameters
  of the nodes only (``flexmotion plan`` ignores them but knows them);
* :data:`ROS_PARAMETERS`, :data:`KNOWN_PREFIXES`: what rclpy adds itself, and
  the namespaces validated by their own owner (``design.*`` by ``flexmotion
  design``, ``qos_overrides.*`` by rclpy).

**Adding a node parameter**: add its ``Spec`` in
:mod:`flexmotion_ros.nodes.parameters` *and* one :class:`ParameterInfo` line to
:data:`PLANNER_NODE_PARAMETERS` or :data:`PLANT_NODE_PARAMETERS` below
(``test/ros/test_parameters.py`` checks that both lists agree).  A name not
listed is refused by ``flexmotion plan`` and by the nodes alike, with the
closest known name.

Types follow ``rcl_yaml_param_parser`` (what ``--params-file`` does):
:func:`rcl_scalar` types one YAML scalar as rcl does (an integer literal is
an INTEGER, ``1.0`` a DOUBLE, ``yes`` a BOOL, a quoted value a STRING, ...).
The verdict on an integer where a double is declared is **refuse**, in the
command line and the nodes alike: rclpy refuses it at declaration and at
``ros2 param set``, so accepting it in a file would only move the refusal to
run time.  The error names the key and says to write ``2.0``.
"""

from __future__ import annotations

import difflib
import enum
import math
import re
import sys
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from .errors import ConfigError
from .shaping.shapers import SHAPERS


class ParameterType(enum.Enum):
    """A ROS 2 parameter type (``rcl_interfaces/ParameterType``), by its name."""

    BOOL = "bool"
    INTEGER = "integer"
    DOUBLE = "double"
    STRING = "string"
    BOOL_ARRAY = "bool_array"
    INTEGER_ARRAY = "integer_array"
    DOUBLE_ARRAY = "double_array"
    STRING_ARRAY = "string_array"


_ELEMENT = {
    ParameterType.BOOL_ARRAY: ParameterType.BOOL,
    ParameterType.INTEGER_ARRAY: ParameterType.INTEGER,
    ParameterType.DOUBLE_ARRAY: ParameterType.DOUBLE,
    ParameterType.STRING_ARRAY: ParameterType.STRING,
}
_ARRAY = {v: k for k, v in _ELEMENT.items()}


@dataclass(frozen=True, kw_only=True)
class ParameterInfo:
    """One known parameter.

    Attributes
    ----------
    name : str
        Dotted ROS parameter name.
    type : ParameterType
        Its ROS type (a file's value must have exactly this type).
    allowed : str
        Unit and allowed values, for messages (e.g. ``"N, > 0"``).
    description : str
        One line: what it is.
    methods : tuple of str
        Methods that read it (method options only).
    required_by : tuple of str
        Methods that cannot plan without it (method options only).
    choices : tuple of str
        The only values a string parameter may take (empty: any); checked
        here, so that ``flexmotion plan`` and the nodes refuse the same file.
    alternatives : tuple of ParameterType
        Other ROS types accepted (``model.b0``, ``model.c``, ``u_max``: a double
        for one input, a double array for several; the nodes declare them with
        dynamic typing).
    """

    name: str
    type: ParameterType
    allowed: str
    description: str
    methods: tuple[str, ...] = ()
    required_by: tuple[str, ...] = ()
    choices: tuple[str, ...] = ()
    alternatives: tuple[ParameterType, ...] = ()


def _p(name: str, type_: ParameterType, allowed: str, description: str, **kw: Any) -> ParameterInfo:
    return ParameterInfo(name=name, type=type_, allowed=allowed, description=description, **kw)


D, I, S, B = ParameterType.DOUBLE, ParameterType.INTEGER, ParameterType.STRING, ParameterType.BOOL
DA, SA = ParameterType.DOUBLE_ARRAY, ParameterType.STRING_ARRAY

#: Default of ``max_move_duration_s`` (s): the longest move a goal may ask for (one hour).
MAX_MOVE_DURATION_S = 3600.0
#: Default of ``max_move_samples``: the most command samples a goal's plan may need (100 s at 1 kHz,
#: 500 s at 200 Hz; a plan's arrays are then ~10 MB and it plans in seconds, not minutes).
MAX_MOVE_SAMPLES = 100_000

#: The planner configuration (:class:`~flexmotion_ros.core.config.PlannerConfig`).
CONFIG_PARAMETERS: tuple[ParameterInfo, ...] = (
    _p(
        "model.b0",
        D,
        "non-zero, e.g. 1/kg; several inputs: k x m, row-major",
        "rigid-body input gain b0",
        alternatives=(DA,),
    ),
    _p("model.c", D, "1/s, <= 0; several inputs: one per rigid body", "rigid-body viscous term c", alternatives=(DA,)),
    _p("model.omega", DA, "rad/s, each > 0", "undamped modal frequencies"),
    _p("model.zeta", DA, "each in [0, 1)", "modal damping ratios"),
    _p("model.b", DA, "each non-zero; several inputs: N x m, row-major", "modal input gains"),
    _p(
        "u_max",
        D,
        "N or the model's input unit, > 0; several inputs: one per input (or one for all)",
        "actuator bound |u| <= u_max",
        alternatives=(DA,),
    ),
    # several inputs (issue 12): model.inputs makes a file multi-input (core/multi_input/parse.py)
    _p("model.inputs", SA, "one name per input (m >= 1)", "the actuated joints (inputs) of a multi-input model"),
    _p("model.rigid_bodies", SA, "one name per rigid body (k)", "rigid-body coordinates of a multi-input model"),
    _p("model.mode_names", SA, "one name per mode", "names of the modes of a multi-input model"),
    _p(
        "sync",
        S,
        "'time', 'none' or 'phase'",
        "multi-input time_optimal: how the inputs that do not set the time arrive",
        choices=("time", "none", "phase"),
    ),
    _p("fuel_weights", DA, "one per input, each > 0", "multi-input min_fuel: weights c_i of eq. 2.38"),
    _p("rate_hz", D, "Hz, in (0, 1e6]", "command rate"),
    _p("method", S, "a method name", "planning method"),
    _p("limits.position_min", D, "m or rad; -.inf: no limit", "lowest goal position"),
    _p("limits.position_max", D, "m or rad; .inf: no limit", "highest goal position"),
    _p(
        "max_move_duration_s",
        D,
        f"s, > 0, default {MAX_MOVE_DURATION_S:g}",
        "longest move a goal may ask for (rigid-body minimum time); longer goals are refused up front",
    ),
    _p(
        "max_move_samples",
        I,
        f"integer >= 1, default {MAX_MOVE_SAMPLES}",
        "most command samples a goal's plan may need at rate_hz (rigid-body minimum time x rate_hz); "
        "larger goals are refused up front",
    ),
)

_SHAPERS = tuple(SHAPERS)
_ROBUST = ("robust_time_optimal",)

#: Options of the planning methods (``PlannerConfig.options``).
METHOD_OPTIONS: tuple[ParameterInfo, ...] = (
    _p("shaper.tolerance", D, "fraction, in (0, 0.5), default 0.05", "EI vibration limit V", methods=_SHAPERS),
    _p(
        "shaper.negative_amplitude",
        D,
        "in (0.5, 2], default 0.75",
        "SNA negative impulse amplitude P",
        methods=_SHAPERS,
    ),
    _p("shaper.multimode", S, "'convolve' or 'direct'", "multi-mode shaper construction", methods=_SHAPERS),
    _p(
        "robustness.tolerance",
        D,
        "fraction, in (0, 1), default 0.05",
        "tolerance of the reported insensitivity",
        methods=_SHAPERS + _ROBUST,
    ),
    _p("robust_order", I, "integer, 0..4, default 1", "derivative order of robust_time_optimal", methods=_ROBUST),
    _p(
        "coulomb_force",
        D,
        "N, in [0, u_max)",
        "Coulomb friction on the rigid body",
        methods=("time_optimal_friction",),
        required_by=("time_optimal_friction",),
    ),
    _p(
        "arrival_time",
        D,
        "s, >= the time-optimal move time T*",
        "arrival time of fixed_time",
        methods=("fixed_time",),
        required_by=("fixed_time",),
    ),
    _p("move_time", D, "s, >= T*, default 1.2 T*", "move time of min_fuel", methods=("min_fuel",)),
    _p("fuel_curve.longest_time", D, "s, >= T*", "longest move time of the fuel/time curve", methods=("min_fuel",)),
    _p(
        "fuel_curve.points",
        I,
        "integer in [2, 1000], default 9",
        "points of the fuel/time curve",
        methods=("min_fuel",),
    ),
    _p("limits.velocity_max", D, "m/s, > 0", "rigid-body velocity limit", methods=("limited",)),
    _p(
        "limits.deflection_max",
        DA,
        "one per mode, each > 0; .inf: no limit",
        "modal deflection limits",
        methods=("limited",),
    ),
    _p("limits.slew_rate", D, "N/s, > 0", "command slew-rate limit", methods=("limited",)),
    _p("limits.report_each", B, "true or false", "also plan with each limit alone", methods=("limited",)),
)

#: Parameters of ``flexmotion_planner`` that are not part of the configuration (add new ones here).
PLANNER_NODE_PARAMETERS: tuple[ParameterInfo, ...] = (
    _p("publish_hold_when_idle", B, "true or false", "keep publishing the hold while idle"),
    _p("stream_priority", I, "integer 0..99", "SCHED_FIFO priority of the stream thread"),
    _p(
        "initial_position",
        D,
        "m or rad; several rigid bodies: one each",
        "position assumed at start-up",
        alternatives=(DA,),
    ),
    _p("replan_lead_s", D, "s, in [0, 60]", "smallest look-ahead of a preemption"),
    _p("max_trajectory_points", I, "integer >= 2", "most points in a published path"),
    _p("frame_id", S, "a frame name", "frame_id of the answered paths"),
    _p("diagnostics_period_s", D, "s, in [0.01, 3600]", "period of /diagnostics"),
    _p("joint_name", S, "a joint name", "the joint this planner moves"),
    _p("joint_names", SA, "one name per input", "multi-input: the joints of 'commands', in order"),
    _p(
        "state.source", S, "'measured' or 'assumed'", "start state of a move from idle", choices=("measured", "assumed")
    ),
    _p("state.topic", S, "a topic name", "topic of the measured state"),
    _p("state.mode_joint_names", SA, "one joint name per mode", "joints holding the modal coordinates"),
    _p("state.timeout_s", D, "s, in (0, 3600]", "age after which a measured state is stale"),
    _p(
        "trajectory.early_arrival",
        S,
        "'refuse' or 'optimum'",
        "a trajectory goal arriving before T*",
        choices=("refuse", "optimum"),
    ),
)

#: Parameters of ``flexmotion_plant`` (add new ones here).
PLANT_NODE_PARAMETERS: tuple[ParameterInfo, ...] = (
    _p("lockstep", B, "true or false", "advance one sample per command"),
    _p("publish_rate_hz", D, "Hz, >= 0", "real-time publish rate"),
    _p("command_timeout", D, "s, in [0, 3600]", "zero force after this long without a command"),
    _p("plant.omega_scale", DA, "each > 0", "model error: frequency ratios"),
    _p("plant.extra_zeta", DA, "each >= 0", "model error: added damping"),
    _p("plant.coulomb_force", D, "N, >= 0", "simulated Coulomb friction"),
    _p("plant.apply_at", S, "'arrival' or 'send'", "when a command acts", choices=("arrival", "send")),
    _p(
        "plant.initial_position",
        D,
        "m or rad; several rigid bodies: one each",
        "initial rigid-body position",
        alternatives=(DA,),
    ),
    _p("plant.idle_state_period_s", D, "s, >= 0", "lockstep heartbeat period while idle"),
)

#: Parameters rclpy declares on every node.
ROS_PARAMETERS: tuple[ParameterInfo, ...] = (
    _p("use_sim_time", B, "true or false", "rclpy: use /clock"),
    _p("start_type_description_service", B, "true or false", "rclpy: type description service"),
)

#: Namespaces whose names are validated by their owner, not here.
KNOWN_PREFIXES: tuple[str, ...] = ("qos_overrides.", "design.")

#: Every known parameter by name.
KNOWN: dict[str, ParameterInfo] = {
    p.name: p
    for p in CONFIG_PARAMETERS + METHOD_OPTIONS + PLANNER_NODE_PARAMETERS + PLANT_NODE_PARAMETERS + ROS_PARAMETERS
}
#: Names of the method options.
OPTION_NAMES: frozenset[str] = frozenset(p.name for p in METHOD_OPTIONS)
#: Names that are neither configuration nor method options (nodes, rclpy).
NODE_NAMES: frozenset[str] = frozenset(p.name for p in PLANNER_NODE_PARAMETERS + PLANT_NODE_PARAMETERS + ROS_PARAMETERS)


def option(name: str) -> ParameterInfo:
    """The registry entry of method option ``name`` (a programming error if unknown)."""
    info = KNOWN[name]
    assert name in OPTION_NAMES, name
    return info


def required_options(method: str) -> tuple[ParameterInfo, ...]:
    """The options ``method`` cannot plan without (e.g. ``coulomb_force`` for ``time_optimal_friction``)."""
    return tuple(p for p in METHOD_OPTIONS if method in p.required_by)


def check_required_options(method: str, options: Mapping[str, Any]) -> None:
    """Raise :class:`ConfigError` naming the first option ``method`` requires and ``options`` lacks."""
    for p in required_options(method):
        if options.get(p.name) is None:
            raise ConfigError(
                p.name, f"required by method {method}: set '{p.name}' ({p.allowed}) in the parameter file"
            )


def is_known(name: str, extra: Iterable[str] = ()) -> bool:
    """Whether ``name`` is a known parameter (or in ``extra``, or under a :data:`KNOWN_PREFIXES` namespace)."""
    return name in KNOWN or name in set(extra) or name.startswith(KNOWN_PREFIXES)


#: How alike (difflib ratio) a mistyped name and a valid one must be for the valid one to be suggested.
CLOSE_NAME_CUTOFF = 0.6


def closest_name(name: str, valid: Iterable[str]) -> str | None:
    """The valid name closest to a mistyped ``name`` (None if none is close): the one did-you-mean helper."""
    match = difflib.get_close_matches(name, sorted(set(valid)), n=1, cutoff=CLOSE_NAME_CUTOFF)
    return match[0] if match else None


def closest_hint(name: str, valid: Iterable[str]) -> str:
    """`` (closest: 'x')`` for a mistyped ``name``, or ``""`` if nothing is close."""
    match = closest_name(name, valid)
    return f" (closest: {match!r})" if match is not None else ""


def check_name(name: str, extra: Iterable[str] = ()) -> None:
    """Raise :class:`ConfigError` for an unknown name, with the closest known one."""
    extra = set(extra)
    if is_known(name, extra):
        return
    close = closest_name(name, set(KNOWN) | extra)
    hint = f"did you mean {close}?" if close else "see flexmotion_ros/core/parameters.py for the known names"
    raise ConfigError(name, f"unknown parameter; {hint}")


def check_choice(name: str, value: Any, choices: Sequence[str]) -> str:
    """``value`` as one of ``choices``, else :class:`ConfigError` naming ``name``, the choices and the closest.

    The one text for a value outside its choices, in the command line and the nodes alike.
    """
    text = str(value)
    if text not in choices:
        raise ConfigError(name, f"must be one of {list(choices)}, got {value!r}{closest_hint(text, choices)}")
    return text


def ros_type(value: Any) -> ParameterType | None:
    """The ROS type of a plain value (``None`` or ``[]``: not set); ``TypeError`` for a mixed list."""
    if value is None:
        return None
    if isinstance(value, bool):
        return ParameterType.BOOL
    if isinstance(value, int):
        return ParameterType.INTEGER
    if isinstance(value, float):
        return ParameterType.DOUBLE
    if isinstance(value, str):
        return ParameterType.STRING
    if isinstance(value, (list, tuple)):
        if not value:
            return None
        kinds = {ros_type(v) for v in value}
        if len(kinds) != 1 or next(iter(kinds)) not in _ARRAY:
            raise TypeError(f"a list of mixed or unsupported types: {value!r}")
        return _ARRAY[next(iter(kinds))]
    raise TypeError(f"unsupported value {value!r}")


def _with_type(value: Any) -> str:
    t = ros_type(value)
    return f"the {t.value.replace('_', ' ')} {value!r}" if t is not None else repr(value)


def _a(t: ParameterType) -> str:
    """``"a double"``, ``"an integer"``, ``"a double array"``."""
    text = t.value.replace("_", " ")
    return ("an " if text[0] in "aeiou" else "a ") + text


def check_type(name: str, value: Any) -> None:
    """Raise :class:`ConfigError` if ``value`` is not of the ROS type the registry declares for ``name``.

    A string parameter with fixed :attr:`ParameterInfo.choices` must also be one of them.

    Unregistered names (``design.*``, ``qos_overrides.*``) and unset values pass.
    """
    info = KNOWN.get(name)
    if info is None:
        return
    try:
        t = ros_type(value)
    except TypeError:
        raise ConfigError(
            name, f"must be {_a(info.type)} ({info.allowed}); a list needs one type, got {value!r}"
        ) from None
    if t is None:
        return
    if t == info.type or t in info.alternatives:
        if info.choices:
            check_choice(name, value, info.choices)
        return
    hint = ""
    if info.type == ParameterType.DOUBLE and t == ParameterType.INTEGER:
        hint = f": write {float(value)!r} (ROS types {value!r} as an integer)"
    elif ParameterType.DOUBLE_ARRAY in (info.type, *info.alternatives) and t == ParameterType.INTEGER_ARRAY:
        hint = f": write {[float(v) for v in value]!r} (ROS types {value!r} as integers)"
    kinds = " or ".join(_a(k) for k in (info.type, *info.alternatives))
    raise ConfigError(name, f"must be {kinds} ({info.allowed}), got {_with_type(value)}{hint}")


def check_parameters(params: Mapping[str, Any], extra: Iterable[str] = ()) -> None:
    """Every name known (:func:`check_name`) and of its ROS type (:func:`check_type`); first error raised.

    The one check of a parameter set from a file, ``--option`` or a node's start-up overrides.
    """
    extra = set(extra)
    for name, value in params.items():
        check_name(name, extra)
        check_type(name, value)


# ----------------------------------------------------------------- rcl typing rules
_TRUE = {"Y", "y", "yes", "Yes", "YES", "true", "True", "TRUE", "on", "On", "ON"}
_FALSE = {"N", "n", "no", "No", "NO", "false", "False", "FALSE", "off", "Off", "OFF"}
_SPECIAL_FLOATS = {
    ".nan": math.nan,
    ".NaN": math.nan,
    ".NAN": math.nan,
    **{f"{s}.{w}": (-math.inf if s == "-" else math.inf) for s in ("", "+", "-") for w in ("inf", "Inf", "INF")},
}
#: What C ``strtol(s, &end, 0)`` consumes whole: decimal, ``0x`` hex, ``0`` octal.
_C_INT = re.compile(r"[ \t\n\v\f\r]*[+-]?(0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)")
#: What C ``strtod`` consumes whole (decimal and hex floats, inf, infinity, nan).
_C_FLOAT = re.compile(
    r"[ \t\n\v\f\r]*[+-]?("
    r"([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?"
    r"|0[xX]([0-9a-fA-F]+\.?[0-9a-fA-F]*|\.[0-9a-fA-F]+)([pP][+-]?[0-9]+)?"
    r"|inf|infinity|nan(\([0-9A-Za-z_]*\))?)",
    re.IGNORECASE,
)
_INT64 = 2**63


def rcl_scalar(text: str, quoted: bool = False) -> bool | int | float | str:
    """One YAML scalar typed as ``rcl_yaml_param_parser`` types it.

    Quoted: a string.  Otherwise, in order: ``y/yes/true/on`` (and their
    capitalisations) a BOOL, ``n/no/false/off`` likewise; what C ``strtol``
    (base 0: ``10``, ``0x10``, ``010``) reads whole without overflow an
    INTEGER; ``.inf``, ``.nan`` and what ``strtod`` reads whole without
    overflow a DOUBLE; anything else a STRING (``null`` and ``~`` included).
    """
    if quoted:
        return text
    if text in _TRUE:
        return True
    if text in _FALSE:
        return False
    if _C_INT.fullmatch(text):
        body = text.strip()
        sign = -1 if body.startswith("-") else 1
        digits = body.lstrip("+-")
        if digits[:2] in ("0x", "0X"):
            value = int(digits, 16)
        elif len(digits) > 1 and digits.startswith("0"):
            value = int(digits, 8)
        else:
            value = int(digits)
        value *= sign
        if -_INT64 <= value < _INT64:
            return value
        # strtol overflows: rcl falls through to strtod
    if text in _SPECIAL_FLOATS:
        return _SPECIAL_FLOATS[text]
    if _C_FLOAT.fullmatch(text):
        body = text.strip()
        low = body.lower().lstrip("+-")
        if low.startswith("0x"):
            x = float.fromhex(body)
        elif low.startswith("nan"):
            x = math.nan
        else:
            x = float(body)
        finite_text = not low.startswith(("inf", "nan"))
        mantissa = re.split(r"[eEpP]", low)[0]
        underflow = x == 0.0 and any(c not in "0.x" for c in mantissa)
        if finite_text and (math.isinf(x) or underflow or 0.0 < abs(x) < sys.float_info.min):
            return text  # strtod sets ERANGE: rcl keeps the text as a string
        return x
    return text


def parse_parameter_value(text: str, name: str = "--option") -> Any:
    """A command-line value (``-p NAME:=VALUE``, ``--option NAME=VALUE``) typed by the rcl rules.

    A flow list ``[1.0, 2.0]`` becomes a homogeneous list; a mixed one raises
    :class:`ConfigError` naming ``name``.
    """
    stripped = text.strip()
    if stripped.startswith("[") and stripped.endswith("]"):
        inner = stripped[1:-1].strip()
        if not inner:
            return []
        items = [rcl_scalar(*_unquote(part.strip())) for part in inner.split(",")]
        try:
            ros_type(items)
        except TypeError:
            raise ConfigError(name, f"list items must all have one type (write doubles as 2.0), got {text!r}") from None
        return items
    return rcl_scalar(*_unquote(stripped))


def _unquote(text: str) -> tuple[str, bool]:
    if len(text) >= 2 and text[0] == text[-1] and text[0] in "'\"":
        return text[1:-1], True
    return text, False
