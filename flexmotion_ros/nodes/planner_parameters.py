"""Declared parameters of ``flexmotion_planner`` and its core configuration.

Validation is the core's: :func:`planner_config` drops the node-only names
(:data:`PLANNER_NODE_ONLY`) and hands the rest to
:func:`~flexmotion_ros.core.multi_input.dispatch.config_from_any`, the function
``flexmotion plan`` uses, so the command line and the node accept and refuse
the same files.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rclpy.parameter import Parameter

from ..core.config import DEFAULTS
from ..core.methods import METHODS
from ..core.multi_input.dispatch import AnyConfig, config_from_any
from ..core.parameters import required_options
from .parameter_specs import command_interface_spec, measurement_specs, model_specs, trajectory_topic_spec
from .parameters import Spec


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
    return model_specs(read_only=False) + [
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
            "(which share its interpreter lock) one step below while planning runs in child processes, the goal-planning "
            "child's first 50 ms of each plan three below (Linux, needs "
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


def planner_config(values: Mapping[str, Any]) -> AnyConfig:
    """The core configuration from the planner's parameter values (node-only names dropped): one input or several."""
    return config_from_any({k: v for k, v in values.items() if k not in PLANNER_NODE_ONLY})
