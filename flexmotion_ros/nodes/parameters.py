"""ROS parameters of the nodes: declarations, descriptors and validation.

Both nodes read the same parameter file as ``flexmotion plan``
(``--ros-args --params-file FILE``; nested keys such as ``model: {b0: ...}``
become the dotted names ``model.b0``).  Every parameter is declared with a
default and a :class:`ParameterDescriptor` (description with units, a range
where one is meaningful, ``read_only`` where a change cannot apply live).

Validation is the core's: a candidate parameter set is turned into a
:class:`~flexmotion_ros.core.config.PlannerConfig` by
:func:`~flexmotion_ros.core.config.config_from_parameters` (the same function
``flexmotion plan`` uses), so the command line and the nodes accept and
refuse exactly the same files.  The plant adds its model-error and friction
parameters (:func:`plant_config_from_parameters`).

Several inputs (issue 12): ``model.inputs`` makes the parameter set a
multi-input machine (:mod:`flexmotion_ros.core.multi_input.dispatch` decides,
for the command line and the nodes alike); ``model.b0``, ``model.c``, ``u_max``
and the initial positions are then double arrays, so they are declared with
dynamic typing (a double for one input, a double array for several).

Changing the number of modes needs ``model.omega``, ``model.zeta`` and
``model.b`` in one atomic set (``SetParametersAtomically``); one at a time,
each intermediate set has mismatched lengths and is refused.
"""

from __future__ import annotations

import array
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
)
from rclpy.node import Node
from rclpy.parameter import Parameter

from ..core.config import DEFAULTS
from ..core.errors import ConfigError, FlexmotionError, InputError
from ..core.methods import METHODS
from ..core.model.measurement import MeasurementMap, measurement_map, noise_levels
from ..core.multi_input.config import MultiPlannerConfig
from ..core.multi_input.dispatch import AnyConfig, AnyModel, config_from_any
from ..core.multi_input.model import MultiModel
from ..core.parameters import METHOD_OPTIONS, check_name, check_type, required_options

INF = math.inf


@dataclass(frozen=True)
class Spec:
    """One declared parameter.

    Attributes
    ----------
    name : str
        Dotted ROS parameter name.
    default : Any
        Default value, or a :class:`Parameter.Type` for lists whose default is
        empty (rclpy cannot infer a type from ``[]``).
    description : str
        What it is, with its unit and allowed values.
    read_only : bool
        A change cannot apply live (fixed at start-up).
    fp_range, int_range : tuple, optional
        ``(from, to)`` for a descriptor range.
    dynamic : bool
        Declared with dynamic typing: a double for one input, a double array for several.
    """

    name: str
    default: Any
    description: str
    read_only: bool = False
    fp_range: tuple[float, float] | None = None
    int_range: tuple[int, int] | None = None
    dynamic: bool = False

    def descriptor(self) -> ParameterDescriptor:
        d = ParameterDescriptor(description=self.description, read_only=self.read_only, dynamic_typing=self.dynamic)
        if self.fp_range is not None:
            d.floating_point_range = [
                FloatingPointRange(from_value=float(self.fp_range[0]), to_value=float(self.fp_range[1]), step=0.0)
            ]
        if self.int_range is not None:
            d.integer_range = [IntegerRange(from_value=int(self.int_range[0]), to_value=int(self.int_range[1]), step=1)]
        return d


def _model_specs(read_only: bool) -> list[Spec]:
    tail = " Fixed at start-up (the simulated machine)." if read_only else " A change applies to the next goal."
    return [
        Spec(
            "model.b0",
            DEFAULTS["model.b0"],
            "rigid-body input gain b0 (acceleration per unit input, e.g. 1/kg); non-zero. Several inputs: a double "
            "array, k x m row-major." + tail,
            read_only,
            dynamic=True,
        ),
        Spec(
            "model.c",
            DEFAULTS["model.c"],
            "rigid-body viscous term c (1/s), <= 0. Several inputs: one per rigid body." + tail,
            read_only,
            fp_range=(-1e12, 0.0),
            dynamic=True,
        ),
        Spec(
            "model.omega",
            Parameter.Type.DOUBLE_ARRAY,
            "undamped modal frequencies omega_i (rad/s), each > 0, no two equal; empty: rigid body only." + tail,
            read_only,
        ),
        Spec(
            "model.zeta",
            Parameter.Type.DOUBLE_ARRAY,
            "modal damping ratios zeta_i, each in [0, 1), one per mode." + tail,
            read_only,
        ),
        Spec(
            "model.b",
            Parameter.Type.DOUBLE_ARRAY,
            "modal input gains b_i, each non-zero, one per mode. Several inputs: N x m, row-major." + tail,
            read_only,
        ),
        *_multi_model_specs(read_only, tail),
    ]


def _multi_model_specs(read_only: bool, tail: str) -> list[Spec]:
    """The multi-input model's names (issue 12): set ``model.inputs`` and the model has several inputs."""
    return [
        Spec(
            "model.inputs",
            Parameter.Type.STRING_ARRAY,
            "names of the m actuated joints (inputs); set: a multi-input model (b0, b, u_max per input); "
            "empty: one input." + tail,
            read_only,
        ),
        Spec(
            "model.rigid_bodies",
            Parameter.Type.STRING_ARRAY,
            "multi-input: names of the k rigid-body coordinates (default [rigid_body]); the measured and simulated "
            "joint_states name them." + tail,
            read_only,
        ),
        Spec(
            "model.mode_names",
            Parameter.Type.STRING_ARRAY,
            "multi-input: names of the N modes (default mode_1 ... mode_N); the joint_states name them." + tail,
            read_only,
        ),
    ]


def _method_description() -> str:
    needs = "; ".join(
        f"{m} needs {', '.join(o.name for o in required_options(m))}" for m in METHODS if required_options(m)
    )
    return (
        "profile type, one of: "
        + ", ".join(sorted(METHODS))
        + f". A change applies to the next goal; a method whose required options are unset is refused ({needs}: "
        "set them in the same atomic call)."
    )


def planner_specs() -> list[Spec]:
    """Declared parameters of ``flexmotion_planner``."""
    return _model_specs(read_only=False) + [
        Spec(
            "u_max",
            DEFAULTS["u_max"],
            "actuator bound |u| <= u_max (N or the model's input unit), > 0; several inputs: one per input (a double "
            "array) or one for all. Applies to the next goal.",
            fp_range=(0.0, 1e12),
            dynamic=True,
        ),
        Spec(
            "sync",
            Parameter.Type.STRING,
            "multi-input time_optimal: 'time' (unset: every axis arrives at T*), 'none' (each decoupled axis "
            "as fast as it can) or 'phase' (a straight rigid-body path). Applies to the next goal.",
        ),
        Spec(
            "fuel_weights",
            Parameter.Type.DOUBLE_ARRAY,
            "multi-input min_fuel: weight c_i of each input's fuel (eq. 2.38), each > 0; unset: all 1.",
        ),
        Spec(
            "rate_hz",
            DEFAULTS["rate_hz"],
            "command rate (Hz) of the stream on 'commands' and of the exact zero-order-hold plan, in (0, 1e6]. Fixed at start-up.",
            read_only=True,
            fp_range=(0.0, 1e6),
        ),
        Spec("method", DEFAULTS["method"], _method_description()),
        Spec(
            "limits.position_min",
            DEFAULTS["limits.position_min"],
            "lowest goal position accepted (m or rad); -inf: no limit.",
        ),
        Spec(
            "limits.position_max",
            DEFAULTS["limits.position_max"],
            "highest goal position accepted (m or rad); inf: no limit.",
        ),
        Spec(
            "max_move_duration_s",
            DEFAULTS["max_move_duration_s"],
            "longest move (s) a goal may ask for, > 0: a goal whose rigid-body minimum time exceeds it is refused "
            "before planning (e.g. a goal of 1e300). A change applies to the next goal.",
            fp_range=(0.0, 1e9),
        ),
        Spec(
            "max_move_samples",
            DEFAULTS["max_move_samples"],
            "most command samples (>= 1) a goal's plan may need at rate_hz: a goal whose rigid-body minimum time "
            "x rate_hz exceeds it is refused in microseconds, before planning (e.g. a goal of 1e6 m). A change "
            "applies to the next goal.",
            int_range=(1, 1_000_000_000),
        ),
        Spec(
            "publish_hold_when_idle",
            True,
            "true: keep publishing the hold command (0) at rate_hz while idle; false: the stream ends with one explicit hold sample after each move.",
        ),
        Spec(
            "stream_priority",
            0,
            "1..99: run the command stream thread under SCHED_FIFO at this priority, and the node's other threads "
            "(which share its interpreter lock) one step below while planning runs in child processes (Linux, needs "
            "CAP_SYS_NICE or an rtprio limit; refused: a warning and normal scheduling); 0: normal scheduling. Fixed "
            "at start-up.",
            read_only=True,
            int_range=(0, 99),
        ),
        Spec(
            "initial_position",
            0.0,
            "position (m or rad) the planner assumes, at rest, at start-up (state.source: assumed); several rigid "
            "bodies: one each, or one for all. Fixed at start-up.",
            read_only=True,
            dynamic=True,
        ),
        Spec(
            "replan_lead_s",
            0.05,
            "smallest look-ahead (s) of a preemption or stop: the new plan starts at a sample at least this far ahead "
            "(and 1.5 x the recent planning time + 20 ms, the slowest 20 % of the last 20 plans set aside, at most "
            "1 s), in [0, 60].",
            fp_range=(0.0, 60.0),
        ),
        Spec(
            "max_trajectory_points",
            10000,
            "most points in ~/planned_trajectory and in a GetPlan path; longer plans are decimated (every m-th sample, last one kept).",
            int_range=(2, 10_000_000),
        ),
        Spec("frame_id", "world", "frame_id of the paths answered by ~/move and ~/plan."),
        Spec(
            "diagnostics_period_s",
            1.0,
            "period (s) of the status on /diagnostics (also sent on every change), in [0.01, 3600]. Fixed at start-up.",
            read_only=True,
            fp_range=(0.01, 3600.0),
        ),
        *_goal_specs(),
        *measurement_specs(),
        *identification_specs(),
    ]


def _goal_specs() -> list[Spec]:
    """The planner's joint, measured start state and trajectory-goal parameters (all fixed at start-up)."""
    return [
        Spec(
            "joint_name",
            "rigid_body",
            "the joint this planner moves: ~/joint_trajectory goals must name it (others are refused), and the "
            "rigid body's name in the measured joint_states. Fixed at start-up.",
            read_only=True,
        ),
        Spec(
            "joint_names",
            Parameter.Type.STRING_ARRAY,
            "multi-input: the joints of 'commands', one per input, in the order of its values (a ros2_control "
            "forward command controller with these joints); empty: model.inputs. Fixed at start-up.",
            read_only=True,
        ),
        Spec(
            "state.source",
            "measured",
            "start state of a move from idle: 'measured' (the last joint_states, refused if missing or older than "
            "state.timeout_s) or 'assumed' (at rest at initial_position, then where the last plan ended; open loop). "
            "Fixed at start-up.",
            read_only=True,
        ),
        Spec(
            "state.topic",
            "joint_states",
            "sensor_msgs/JointState topic of the machine's measured state (position, velocity per joint). Fixed at start-up.",
            read_only=True,
        ),
        Spec(
            "state.mode_joint_names",
            Parameter.Type.STRING_ARRAY,
            "joints of the measured state holding the modal coordinates, one per mode; empty: mode_1 ... mode_N. "
            "Fixed at start-up.",
            read_only=True,
        ),
        Spec(
            "state.timeout_s",
            0.5,
            "a measured state received longer ago than this (s) is stale: a goal waits this long for a fresh one, "
            "then is refused, in (0, 3600]. Fixed at start-up.",
            read_only=True,
            fp_range=(0.0, 3600.0),
        ),
        Spec(
            "trajectory.early_arrival",
            "refuse",
            "a ~/joint_trajectory whose last time_from_start is before the time-optimal arrival: 'refuse' it, or "
            "take the 'optimum' (arrive as fast as possible). Fixed at start-up.",
            read_only=True,
        ),
        *_actuator_specs(),
    ]


def command_interface_spec() -> Spec:
    """``command_interface``, declared by both nodes (one file serves the planner and the plant)."""
    return Spec(
        "command_interface",
        "effort",
        "what the actuated joint is commanded in: 'effort' (the force, u_max in N), 'velocity' or 'position' "
        "(a servo tracks the reference the planner sends, integrated exactly from the plan; the model's input "
        "is then the joint's acceleration, u_max in m/s^2, model.c = 0.0: build it with "
        "'flexmotion model crane --input acceleration'). Fixed at start-up.",
        read_only=True,
    )


def trajectory_topic_spec() -> Spec:
    """``trajectory.topic``, declared by both nodes."""
    return Spec(
        "trajectory.topic",
        "joint_trajectory",
        "trajectory_msgs/JointTrajectory topic: the planner publishes on it with output: trajectory (e.g. "
        "/<controller>/joint_trajectory of a joint_trajectory_controller), the plant reads it with plant.input: "
        "trajectory. Fixed at start-up.",
        read_only=True,
    )


def _actuator_specs() -> list[Spec]:
    """The planner's output, command interface and closed-loop replanning (issue 14; fixed at start-up)."""
    return [
        Spec(
            "output",
            "stream",
            "'stream': one command per sample on 'commands'; 'trajectory': each plan as one "
            "trajectory_msgs/JointTrajectory on trajectory.topic, played by the receiver's clock. Fixed at start-up.",
            read_only=True,
        ),
        command_interface_spec(),
        trajectory_topic_spec(),
        Spec(
            "trajectory.interpolation",
            "none",
            "the receiver's interpolation_method: 'none' (the points are its zero-order hold; required for effort) "
            "or 'splines' (velocity / position: the cubic through (p, v) is the exact reference). Fixed at start-up.",
            read_only=True,
        ),
        Spec(
            "trajectory.receiver_update_rate",
            0.0,
            "update_rate (Hz) of a Jazzy joint_trajectory_controller receiving output: trajectory (it commands the "
            "point due one period ahead: the points are shifted by it); 0: no look-ahead (the plant node, Humble). "
            "Fixed at start-up.",
            read_only=True,
            fp_range=(0.0, 1e6),
        ),
        Spec(
            "trajectory.start_delay_s",
            0.2,
            "output: trajectory: a move from idle starts this long (s) after the request's plan is ready, and a "
            "preemption is spliced at least this far ahead: the time a trajectory has to reach the receiver, in "
            "[0, 10] (at least 2 samples). Fixed at start-up.",
            read_only=True,
            fp_range=(0.0, 10.0),
        ),
        Spec(
            "feedback.replan_period_s",
            0.0,
            "closed-loop replanning: during a move, every this many seconds, replan from the state a Kalman filter "
            "estimates from the commands sent and the plant's measurements topic (spliced ahead of the planning time; "
            "certified plans only; a failed replan leaves the plan running); 0: off (open loop). Fixed at start-up.",
            read_only=True,
            fp_range=(0.0, 3600.0),
        ),
        Spec(
            "feedback.measurement_std",
            1e-6,
            "standard deviation the filter assumes for each measured coordinate (their units), > 0. Fixed at start-up.",
            read_only=True,
            fp_range=(0.0, 1e12),
        ),
        Spec(
            "feedback.min_deviation",
            1e-6,
            "replan only when the estimated state deviates from the plan by more than this fraction of the move "
            "(position, velocity over the rest of the plan, every mode's amplitude), in (0, 1): the residual the "
            "closed loop settles for. Fixed at start-up.",
            read_only=True,
            fp_range=(0.0, 1.0),
        ),
        Spec(
            "feedback.input_noise_std",
            0.0,
            "standard deviation of the unknown input disturbance the filter assumes per sample (the input's unit, "
            "N), >= 0. Fixed at start-up.",
            read_only=True,
            fp_range=(0.0, 1e12),
        ),
    ]


def measurement_specs() -> list[Spec]:
    """``measurement.*``: the machine's measured channels (:mod:`flexmotion_ros.core.model.measurement`)."""
    tail = " Fixed at start-up."
    return [
        Spec(
            "measurement.names",
            Parameter.Type.STRING_ARRAY,
            "physical coordinate names of the channels on 'measurements' (sensor_msgs/JointState), unique; empty: "
            "the rigid-body position only." + tail,
            read_only=True,
        ),
        Spec(
            "measurement.map",
            Parameter.Type.DOUBLE_ARRAY,
            "row-major len(measurement.names) x (1 + modes): y = map @ [p, q_1, ..., q_N] (velocity and "
            "acceleration channels: the same row on the derivatives)." + tail,
            read_only=True,
        ),
        Spec(
            "measurement.kinds",
            Parameter.Type.STRING_ARRAY,
            "one per name: position (m), velocity (m/s) or acceleration (m/s^2, feeds the command through); "
            "empty: all position." + tail,
            read_only=True,
        ),
    ]


def identification_specs() -> list[Spec]:
    """``identification.*``: ``~/identify`` and learning from moves (:mod:`.planner_identify`)."""
    tail = " A change applies to the next identification."
    return [
        Spec(
            "identification.band",
            Parameter.Type.DOUBLE_ARRAY,
            "frequency band [lo, hi] (rad/s, 0 < lo < hi < 0.8 x pi x rate_hz) of the ~/identify excitation; empty: "
            "half the lowest to 1.5 x the highest modal frequency." + tail,
        ),
        Spec(
            "identification.modes",
            -1,
            "number of modes identified, in [0, 8]; -1: as many as the model has (a different count is never "
            "adopted)." + tail,
            int_range=(-1, 8),
        ),
        Spec(
            "identification.duration_s",
            0.0,
            "length (s) of the ~/identify excitation (a quarter more of quiet tail follows), in [0, 120]; 0: four "
            "periods of the band's low end." + tail,
            fp_range=(0.0, 120.0),
        ),
        Spec(
            "identification.adopt",
            False,
            "true: ~/identify adopts every model parameter the data contradict (its value outside the 95 % "
            "interval) for the next goal, through these parameter services; false: it only reports." + tail,
        ),
        Spec(
            "identification.learn_from_moves",
            False,
            "true: each move's commands and measurements (from a move from rest on, with the ringdown while idle) "
            "refine the model when the estimate is confident (see identification.max_omega_interval).",
        ),
        Spec(
            "identification.ringdown_s",
            2.0,
            "learning: idle time (s) recorded after a move before its record is fitted, in [0, 60].",
            fp_range=(0.0, 60.0),
        ),
        Spec(
            "identification.max_omega_interval",
            0.01,
            "confident: every identified frequency's 95 % half-width below this fraction of it, in (0, 1]; "
            "otherwise nothing is adopted.",
            fp_range=(0.0, 1.0),
        ),
        Spec(
            "identification.max_zeta_interval",
            0.01,
            "confident: every identified damping ratio's 95 % half-width below this, in (0, 1]; otherwise nothing "
            "is adopted.",
            fp_range=(0.0, 1.0),
        ),
        Spec(
            "identification.max_record_s",
            60.0,
            "learning: the longest record (s of samples) from a move from rest on, in (0, 120]; longer, a new one "
            "starts at the next move from rest.",
            fp_range=(0.0, 120.0),
        ),
    ]


#: Planner parameters that are not part of the core's PlannerConfig.
PLANNER_NODE_ONLY = frozenset(
    {
        "publish_hold_when_idle",
        "stream_priority",
        "initial_position",
        "replan_lead_s",
        "max_trajectory_points",
        "frame_id",
        "diagnostics_period_s",
        "joint_name",
        "joint_names",
        "state.source",
        "state.topic",
        "state.mode_joint_names",
        "state.timeout_s",
        "trajectory.early_arrival",
        "output",
        "command_interface",
        "trajectory.topic",
        "trajectory.interpolation",
        "trajectory.receiver_update_rate",
        "trajectory.start_delay_s",
        "feedback.replan_period_s",
        "feedback.measurement_std",
        "feedback.input_noise_std",
        "feedback.min_deviation",
    }
)


def plant_specs() -> list[Spec]:
    """Declared parameters of ``flexmotion_plant``."""
    return _model_specs(read_only=True) + [
        Spec(
            "rate_hz",
            DEFAULTS["rate_hz"],
            "sample rate (Hz): lockstep advances 1/rate_hz per command; real time integrates and publishes at this rate. Fixed at start-up.",
            read_only=True,
            fp_range=(0.0, 1e6),
        ),
        Spec(
            "lockstep",
            False,
            "true: advance one sample period per command received (deterministic, for tests); false: real time. Fixed at start-up.",
            read_only=True,
        ),
        Spec(
            "publish_rate_hz",
            0.0,
            "real-time mode: rate (Hz) of the timer that integrates and publishes joint_states; 0: rate_hz. "
            "Commands apply from their arrival times whatever this rate. Fixed at start-up.",
            read_only=True,
            fp_range=(0.0, 1e6),
        ),
        Spec(
            "command_timeout",
            0.1,
            "real-time mode: seconds without a command after which zero force is applied, in [0, 3600].",
            fp_range=(0.0, 3600.0),
        ),
        Spec(
            "plant.omega_scale",
            Parameter.Type.DOUBLE_ARRAY,
            "model error: true/nominal frequency ratio of each mode (each > 0); empty: 1 for every mode.",
        ),
        Spec(
            "plant.extra_zeta",
            Parameter.Type.DOUBLE_ARRAY,
            "model error: damping ratio added to each mode (each >= 0, total < 1); empty: none.",
        ),
        Spec(
            "plant.coulomb_force",
            0.0,
            "Coulomb friction force (N, >= 0) at the rigid body (eq. 2.11), simulated by core.friction; 0: none.",
            fp_range=(0.0, 1e12),
        ),
        Spec(
            "plant.apply_at",
            "arrival",
            "real-time mode: a command acts from its DDS 'arrival' time at this node, or from its 'send' time at the "
            "publisher (a transport of constant latency; same clock needed, i.e. one machine).",
        ),
        Spec(
            "plant.initial_position",
            0.0,
            "initial rigid-body position (m or rad), at rest; several rigid bodies: one each, or one for all. "
            "Fixed at start-up.",
            read_only=True,
            dynamic=True,
        ),
        Spec(
            "plant.idle_state_period_s",
            0.1,
            "lockstep: while no command has arrived for this long (s), publish the current state on joint_states "
            "this often as a best-effort heartbeat (a reliable subscriber still gets exactly one state per command; "
            "the planner's best-effort measured-state subscription sees the machine alive while idle); 0: never. "
            "Fixed at start-up.",
            read_only=True,
            fp_range=(0.0, 3600.0),
        ),
        Spec(
            "plant.input",
            "commands",
            "what drives the plant: 'commands' (one value per sample, lockstep or real time) or 'trajectory' "
            "(joint trajectories on trajectory.topic, played by the plant's own clock with the "
            "joint_trajectory_controller's rule, interpolation none, integrated exactly; lockstep: each one at "
            "once, a replacement rewinds the plant to its first point). Fixed at start-up.",
            read_only=True,
        ),
        command_interface_spec(),
        trajectory_topic_spec(),
        Spec(
            "joint_name",
            "rigid_body",
            "the joint a received trajectory must name. Fixed at start-up.",
            read_only=True,
        ),
        Spec(
            "plant.servo_bandwidth",
            0.0,
            "velocity / position joints: bandwidth (rad/s) of a first-order servo tracking the reference; 0: ideal "
            "tracking. Fixed at start-up.",
            read_only=True,
            fp_range=(0.0, 1e12),
        ),
        Spec(
            "plant.disturbance.type",
            "none",
            "a force on the rigid body's input channel (effort joints): 'none', 'impulse' (plant.disturbance.value "
            "N s at plant.disturbance.time_s) or 'step' (value N from time_s on); time from the first non-zero "
            "force (the first move). Fixed at start-up.",
            read_only=True,
        ),
        Spec(
            "plant.disturbance.time_s",
            0.0,
            "when the disturbance acts (s, >= 0), from the first non-zero force (the first move). Fixed at start-up.",
            read_only=True,
            fp_range=(0.0, 1e9),
        ),
        Spec(
            "plant.disturbance.value",
            0.0,
            "the disturbance: impulse (N s) or step (N). Fixed at start-up.",
            read_only=True,
        ),
        *measurement_specs(),
        Spec(
            "plant.noise_std",
            0.0,
            "white noise (standard deviation, units of each channel: m, m/s, m/s^2) added to 'measurements': one "
            "value for every channel or one per channel (a double array), each >= 0; 0: exact readings. Fixed at "
            "start-up.",
            read_only=True,
            dynamic=True,
        ),
        Spec(
            "plant.noise_seed",
            0,
            "seed of the measurement noise (integer >= 0): the same seed gives the same noise. Fixed at start-up.",
            read_only=True,
            int_range=(0, 2**62),
        ),
    ]


#: Names the planner must not mistake for method options (the plant's, rclpy's own).
PLANT_ONLY_PREFIXES = ("plant.", "qos_overrides.")
PLANT_ONLY_NAMES = frozenset(
    {"lockstep", "command_timeout", "publish_rate_hz", "use_sim_time", "start_type_description_service"}
)


# --------------------------------------------------------------------------- declaration
def plain(value: Any) -> Any:
    """A ROS parameter value as plain Python (arrays become lists)."""
    if isinstance(value, (array.array, tuple)):
        return list(value)
    return value


def check_overrides(node: Node, extra: Iterable[str] = ()) -> None:
    """The start-up parameters (file, ``-p``, constructor) judged as ``flexmotion plan`` judges a file.

    Every name must be in the core registry (:mod:`flexmotion_ros.core.parameters`) or in
    ``extra`` (the node's own declarations), every registered value of its ROS type: an
    unknown name raises :class:`ConfigError` with the closest known name, a wrong type
    names the key (e.g. ``u_max: 1``: write ``1.0``), with the same text as the command line.
    """
    extra = set(extra)
    for name, value in sorted(parameter_overrides(node).items()):
        if not node.has_parameter(name):  # declared already: known to this node
            check_name(name, extra)
        check_type(name, value)


def declare(node: Node, specs: Iterable[Spec]) -> None:
    """Declare ``specs`` on ``node``; a bad or unknown name in the parameter file raises :class:`ConfigError`."""
    specs = list(specs)
    check_overrides(node, [s.name for s in specs])
    for spec in specs:
        try:
            node.declare_parameter(spec.name, spec.default, spec.descriptor())
        except InvalidParameterTypeException as exc:
            hint = (
                " (write doubles as 2.0, not 2)"
                if isinstance(spec.default, float) or spec.default == Parameter.Type.DOUBLE_ARRAY
                else ""
            )
            raise ConfigError(spec.name, f"wrong type{hint}: {exc}") from None
        except InvalidParameterValueException as exc:
            raise ConfigError(spec.name, str(exc)) from None


def declared_values(node: Node, names: Iterable[str]) -> dict[str, Any]:
    """Current values of declared parameters (unset lists read as ``[]``)."""
    out: dict[str, Any] = {}
    for name in names:
        p = node.get_parameter_or(name, Parameter(name, Parameter.Type.DOUBLE_ARRAY, []))
        out[name] = plain(p.value) if p.value is not None else []
    return out


def parameter_overrides(node: Node) -> dict[str, Any]:
    """Values given to the node at start-up (parameter file, ``-p``, constructor).

    rclpy has no public accessor for these; the attribute has been stable since
    Foxy.  Used only to find method options the planner does not know by name.
    """
    overrides = getattr(node, "_parameter_overrides", {}) or {}
    return {name: plain(p.value) for name, p in overrides.items()}


def option_specs() -> list[Spec]:
    """Every method option of the core registry (:data:`~flexmotion_ros.core.parameters.METHOD_OPTIONS`).

    Declared with their ROS type and no value: unset unless the parameter file
    (or a later set) gives one, so that the node's options are exactly those of
    ``flexmotion plan --config`` on the same file.
    """
    specs = []
    for o in METHOD_OPTIONS:
        required = f"; required by {', '.join(o.required_by)}" if o.required_by else ""
        specs.append(
            Spec(
                o.name,
                Parameter.Type[o.type.name],
                f"option of the planning method (see 'method'): {o.description} ({o.allowed}); read by "
                f"{', '.join(o.methods)}{required}; unset: the method's default. A change applies to the next goal.",
            )
        )
    return specs


def declare_method_options(node: Node, known: Iterable[str]) -> list[str]:
    """Declare every method option (:func:`option_specs`) not in ``known``; return their names.

    Declared up front with descriptors, so that ``ros2 param set`` can give a
    method its options (``method`` with ``coulomb_force`` in one atomic call).
    The start-up parameters were checked by :func:`declare` (unknown names and
    wrong types refused).
    """
    known = set(known)
    specs = [s for s in option_specs() if s.name not in known and not node.has_parameter(s.name)]
    declare(node, specs)
    return [s.name for s in specs]


def planner_config(values: Mapping[str, Any]) -> AnyConfig:
    """The core configuration from the planner's parameter values (node-only names dropped): one input or several."""
    return config_from_any({k: v for k, v in values.items() if k not in PLANNER_NODE_ONLY})


def validating_callback(
    current: Callable[[], dict[str, Any]], validate: Callable[[dict[str, Any]], Any]
) -> Callable[[list[Parameter]], SetParametersResult]:
    """An on-set-parameters callback: build the whole candidate set and validate it.

    ``current()`` returns the node's parameter values; ``validate(candidate)``
    raises :class:`FlexmotionError` to refuse (its text becomes ``reason``).
    """

    def callback(params: list[Parameter]) -> SetParametersResult:
        candidate = current()
        for p in params:
            candidate[p.name] = plain(p.value) if p.value is not None else []
            try:  # the registry's ROS type: rclpy no longer checks the dynamically typed ones (u_max, model.b0, ...)
                check_type(p.name, candidate[p.name])
            except ConfigError as exc:
                return SetParametersResult(successful=False, reason=f"wrong type: {exc}")
        try:
            validate(candidate)
        except FlexmotionError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        except (TypeError, ValueError) as exc:  # e.g. a string where a number belongs
            return SetParametersResult(successful=False, reason=f"invalid value: {exc}")
        return SetParametersResult(successful=True)

    return callback


# --------------------------------------------------------------------------- plant
@dataclass(frozen=True)
class PlantConfig:
    """The simulated machine.

    Attributes
    ----------
    nominal : ModalModel or MultiModel
        The model in the parameter file (what the planner believes); a
        :class:`MultiModel` when the file sets ``model.inputs``.
    model : ModalModel or MultiModel
        The simulated machine: ``nominal`` with the model errors applied.
    rate_hz : float
        Sample rate (Hz).
    lockstep : bool
    command_timeout : float
        Seconds (s) without command before zero force (real-time mode).
    coulomb_force : float
        Coulomb friction force (N) at the rigid body; 0: none (one input only).
    initial_position : float or ndarray
        Initial rigid-body position (m or rad); one per rigid body for a multi-input model.
    apply_at : str
        Real time: commands act from their ``"arrival"`` or ``"send"`` time.
    measurement : MeasurementMap or None
        The channels published on ``measurements`` (None: the rigid-body position).
    noise_std : tuple of float
        White-noise standard deviation per channel (units of the channel).
    noise_seed : int
        Seed of that noise.
    """

    nominal: AnyModel
    model: AnyModel
    rate_hz: float
    lockstep: bool
    command_timeout: float
    coulomb_force: float
    initial_position: Any
    apply_at: str = "arrival"
    measurement: MeasurementMap | None = None
    noise_std: tuple[float, ...] = ()
    noise_seed: int = 0

    @property
    def dt(self) -> float:
        """Sample period (s)."""
        return 1.0 / self.rate_hz

    @property
    def inputs(self) -> int:
        """Values per command sample (``m``; 1 for a single-input model)."""
        return self.model.m if isinstance(self.model, MultiModel) else 1


#: What the plant reads of the planner's parameter file.
PLANT_MODEL_NAMES = (
    "model.b0",
    "model.c",
    "model.omega",
    "model.zeta",
    "model.b",
    "model.inputs",
    "model.rigid_bodies",
    "model.mode_names",
    "rate_hz",
)


def _perturbed(nominal: AnyModel, omega: tuple, zeta: tuple) -> AnyModel:
    if isinstance(nominal, MultiModel):
        return replace(nominal, omega=omega, zeta=zeta)
    return nominal.with_changes(omega=omega, zeta=zeta)


def _initial_position(value: Any, nominal: AnyModel) -> Any:
    if isinstance(nominal, MultiModel):
        p = [float(v) for v in (value if isinstance(value, (list, tuple)) else [value])]
        if len(p) == 1:
            p = p * nominal.k
        if len(p) != nominal.k or not all(math.isfinite(v) for v in p):
            raise ConfigError(
                "plant.initial_position",
                f"needs one finite position per rigid body {list(nominal.rigid_bodies)} (or one for all), got {value!r}",
            )
        return np.array(p)
    if isinstance(value, (list, tuple)):
        raise ConfigError("plant.initial_position", f"a single-input model takes one position, got {value!r}")
    p0 = float(value)
    if not math.isfinite(p0):
        raise ConfigError("plant.initial_position", f"must be finite, got {p0}")
    return p0


def plant_config_from_parameters(values: Mapping[str, Any]) -> PlantConfig:
    """Validate the plant's parameters; raise :class:`FlexmotionError` naming the bad one."""
    base = config_from_any({k: values[k] for k in PLANT_MODEL_NAMES if k in values})
    nominal = base.model
    n = nominal.n_modes
    scale = list(values.get("plant.omega_scale") or [])
    extra = list(values.get("plant.extra_zeta") or [])
    if scale and len(scale) != n:
        raise ConfigError("plant.omega_scale", f"needs one factor per mode ({n}) or none, got {len(scale)}")
    if extra and len(extra) != n:
        raise ConfigError("plant.extra_zeta", f"needs one value per mode ({n}) or none, got {len(extra)}")
    for i, s in enumerate(scale):
        if not (math.isfinite(s) and s > 0.0):
            raise ConfigError(f"plant.omega_scale[{i}]", f"must be a finite factor > 0, got {s}")
    for i, z in enumerate(extra):
        if not (math.isfinite(z) and z >= 0.0):
            raise ConfigError(f"plant.extra_zeta[{i}]", f"must be finite and >= 0, got {z}")
    omega = tuple(w * (scale[i] if scale else 1.0) for i, w in enumerate(nominal.omega))
    zeta = tuple(z + (extra[i] if extra else 0.0) for i, z in enumerate(nominal.zeta))
    try:
        model = _perturbed(nominal, omega, zeta)
    except InputError as exc:
        raise ConfigError("plant.omega_scale/extra_zeta", f"the perturbed model is invalid: {exc}") from None
    coulomb = float(values.get("plant.coulomb_force", 0.0))
    if not (math.isfinite(coulomb) and coulomb >= 0.0):
        raise ConfigError("plant.coulomb_force", f"must be finite and >= 0 N, got {coulomb}")
    if coulomb > 0.0 and isinstance(base, MultiPlannerConfig):
        raise ConfigError(
            "plant.coulomb_force", "Coulomb friction is simulated for one input only; set 0.0 for a multi-input model"
        )
    timeout = float(values.get("command_timeout", 0.1))
    if not (math.isfinite(timeout) and timeout >= 0.0):
        raise ConfigError("command_timeout", f"must be finite and >= 0 s, got {timeout}")
    p0 = _initial_position(values.get("plant.initial_position", 0.0), nominal)
    apply_at = str(values.get("plant.apply_at", "arrival"))
    if apply_at not in ("arrival", "send"):
        raise ConfigError("plant.apply_at", f"must be 'arrival' or 'send', got {apply_at!r}")
    # the default map reads every rigid body's position (named as the model names them)
    rigid_names = tuple(nominal.rigid_bodies) if isinstance(nominal, MultiModel) else ("rigid_body",)
    measurement = measurement_map(values, n, rigid_names)
    noise = noise_levels(values.get("plant.noise_std", 0.0), measurement.channels)
    seed = values.get("plant.noise_seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ConfigError("plant.noise_seed", f"must be an integer >= 0, got {seed!r}")
    return PlantConfig(
        measurement=measurement,
        noise_std=tuple(float(x) for x in noise),
        noise_seed=int(seed),
        apply_at=apply_at,
        nominal=nominal,
        model=model,
        rate_hz=base.rate_hz,
        lockstep=bool(values.get("lockstep", False)),
        command_timeout=timeout,
        coulomb_force=coulomb,
        initial_position=p0,
    )
