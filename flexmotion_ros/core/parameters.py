"""The one registry of parameter names, and the checks of a parameter set against it.

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
:mod:`flexmotion_ros.nodes.planner_parameters` (or
:mod:`~flexmotion_ros.nodes.plant_parameters`, :mod:`~flexmotion_ros.nodes.parameter_specs`) *and* one :class:`ParameterInfo` line to
:data:`PLANNER_NODE_PARAMETERS` or :data:`PLANT_NODE_PARAMETERS` below
(``test/ros/test_parameters.py`` checks that both lists agree).  A name not
listed is refused by ``flexmotion plan`` and by the nodes alike, with the
closest known name.

The checks of a parameter set against this registry (names, ROS types,
choices, required options, the closest known name) are
:mod:`.parameter_checks`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .ros_types import ParameterType
from .shaping.shapers import SHAPERS


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
        dynamic typing; ``plant.noise_std``: one level or one per channel).
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
_AUTO = ("auto_robust",)

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
        methods=_SHAPERS + _ROBUST + _AUTO,
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
    _p("auto_robust.omega_min", DA, "rad/s, one per mode, > 0", "lowest frequency of each mode", methods=_AUTO),
    _p(
        "auto_robust.omega_max",
        DA,
        "rad/s, one per mode, >= omega_min",
        "highest frequency of each mode",
        methods=_AUTO,
    ),
    _p(
        "auto_robust.relative_error",
        D,
        "fraction, in [0, 1), default 0.02",
        "frequency interval omega (1 +- this) when omega_min/max are unset",
        methods=_AUTO,
    ),
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
    # issue 14: outputs, command interfaces, closed-loop replanning (command_interface and
    # trajectory.topic are read by the plant too: one file serves both)
    _p("output", S, "'stream' or 'trajectory'", "what the planner publishes", choices=("stream", "trajectory")),
    _p(
        "command_interface",
        S,
        "'effort', 'velocity' or 'position'",
        "command interface of the actuated joint",
        choices=("effort", "velocity", "position"),
    ),
    _p("trajectory.topic", S, "a topic name", "trajectory_msgs/JointTrajectory topic of output: trajectory"),
    _p(
        "trajectory.interpolation",
        S,
        "'none' or 'splines'",
        "the receiver's interpolation_method",
        choices=("none", "splines"),
    ),
    _p("trajectory.receiver_update_rate", D, "Hz, 0 or >= 1", "the receiver's update_rate (look-ahead); 0: none"),
    _p("trajectory.start_delay_s", D, "s, in [0, 10]", "a move from idle starts this far ahead (transport margin)"),
    _p("feedback.replan_period_s", D, "s, >= 0; 0: off", "period of closed-loop replanning during a move"),
    _p("feedback.measurement_std", D, "> 0, the measurements' units", "measurement noise assumed by the filter"),
    _p("feedback.input_noise_std", D, ">= 0, the input's unit", "input disturbance assumed by the filter"),
    _p("feedback.min_deviation", D, "in (0, 1), a fraction of the move", "replan only above this deviation"),
    # identification on the machine (nodes/planner_identify.py, execution/learning.py)
    _p("identification.band", DA, "[lo, hi] rad/s, 0 < lo < hi; empty: around the model's modes", "excitation band"),
    _p("identification.modes", I, "integer in [-1, 8]; -1: the model's", "modes to identify"),
    _p("identification.duration_s", D, "s, in [0, 120]; 0: 4 periods of the band's low end", "excitation length"),
    _p("identification.adopt", B, "true or false", "~/identify adopts what the data contradict"),
    _p("identification.learn_from_moves", B, "true or false", "refine the model from every move's record"),
    _p("identification.ringdown_s", D, "s, in [0, 60]", "idle time recorded after a move before fitting"),
    _p("identification.max_omega_interval", D, "fraction, in (0, 1]", "confident: 95 % half-width of omega below this"),
    _p("identification.max_zeta_interval", D, "in (0, 1]", "confident: 95 % half-width of zeta below this"),
    _p("identification.max_record_s", D, "s, in (0, 120]", "longest learning record"),
)

#: The measured channels (``core/model/measurement.py``): the same names in the planner's and the plant's file.
MEASUREMENT_PARAMETERS: tuple[ParameterInfo, ...] = (
    _p("measurement.names", SA, "unique physical coordinate names", "channels of the plant's measurements topic"),
    _p(
        "measurement.map",
        DA,
        "row-major, len(measurement.names) x (rigid bodies + modes)",
        "y = map @ [p, q_1, ..., q_N] (positions; velocities and accelerations likewise)",
    ),
    _p(
        "measurement.kinds",
        SA,
        "one per name: position, velocity or acceleration; default position",
        "what each channel reads",
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
    _p("plant.input", S, "'commands' or 'trajectory'", "what drives the plant", choices=("commands", "trajectory")),
    _p("plant.servo_bandwidth", D, "rad/s, >= 0; 0: ideal", "first-order servo of a velocity / position joint"),
    _p(
        "plant.disturbance.type",
        S,
        "'none', 'impulse' or 'step'",
        "a force disturbance on the rigid body's input",
        choices=("none", "impulse", "step"),
    ),
    _p("plant.disturbance.time_s", D, "s, >= 0", "when it acts, from the first non-zero force (the first move)"),
    _p("plant.disturbance.value", D, "N s (impulse) or N (step)", "its size"),
    _p(
        "plant.noise_std",
        D,
        "units of each channel, >= 0: one value or one per measured channel",
        "white noise on the measurements topic",
        alternatives=(DA,),
    ),
    _p("plant.noise_seed", I, "integer >= 0", "seed of the measurement noise"),
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
    for p in CONFIG_PARAMETERS
    + METHOD_OPTIONS
    + PLANNER_NODE_PARAMETERS
    + PLANT_NODE_PARAMETERS
    + MEASUREMENT_PARAMETERS
    + ROS_PARAMETERS
}
#: Names of the method options.
OPTION_NAMES: frozenset[str] = frozenset(p.name for p in METHOD_OPTIONS)
#: Names that are neither configuration nor method options (nodes, rclpy).
NODE_NAMES: frozenset[str] = frozenset(
    p.name for p in PLANNER_NODE_PARAMETERS + PLANT_NODE_PARAMETERS + MEASUREMENT_PARAMETERS + ROS_PARAMETERS
)


def option(name: str) -> ParameterInfo:
    """The registry entry of method option ``name`` (a programming error if unknown)."""
    info = KNOWN[name]
    assert name in OPTION_NAMES, name
    return info


def required_options(method: str) -> tuple[ParameterInfo, ...]:
    """The options ``method`` cannot plan without (e.g. ``coulomb_force`` for ``time_optimal_friction``)."""
    return tuple(p for p in METHOD_OPTIONS if method in p.required_by)
