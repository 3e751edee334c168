"""Conversions between the core's results and standard ROS messages.

Only standard types (no custom interfaces):

* ``commands``: ``std_msgs/Float64MultiArray`` with one element (the
  ros2_control forward command controller's format);
* ``~/planned_trajectory``: ``trajectory_msgs/JointTrajectory``, one joint
  ``rigid_body``; each point: ``positions [p]``, ``velocities [v]``,
  ``effort [u]`` (the command sent from that sample on; 0 after the last);
  ``time_from_start = i / rate_hz``.  Plans longer than
  ``max_trajectory_points`` are decimated (every m-th sample, the last kept);
* ``~/move`` / ``~/plan`` answers: ``nav_msgs/Path`` with the predicted
  position ``pose.position.x`` per (decimated) sample.  ``GetPlan`` has no
  error field: a refused request answers an empty path whose
  ``header.frame_id`` is ``"error: <reason>"``;
* ``~/joint_trajectory`` goals: :func:`trajectory_goal` (the last point of
  the planner's joint; its ``time_from_start`` is the requested arrival);
* ``joint_states``: ``sensor_msgs/JointState`` (``rigid_body``, ``mode_1``,
  ...: position, velocity; effort = the applied command on every joint);
* ``/diagnostics``: ``diagnostic_msgs/DiagnosticArray``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from builtin_interfaces.msg import Duration, Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from ..core.errors import GoalError
from ..core.parameter_checks import closest_hint
from ..execution.measured_state import RIGID_BODY

#: Prefix of ``Path.header.frame_id`` when a GetPlan request is refused.
ERROR_PREFIX = "error: "


def command(value: float, inputs: int = 1) -> Float64MultiArray:
    """One command sample (N): one value, or ``inputs`` values (all ``value``) for a multi-input machine."""
    return Float64MultiArray(data=[float(value)] * int(inputs))


def command_value(msg: Float64MultiArray) -> float:
    """The command in a ``commands`` message (first element; NaN if empty)."""
    return float(msg.data[0]) if len(msg.data) else math.nan


def command_values(msg: Float64MultiArray, inputs: int) -> np.ndarray:
    """The ``inputs`` values of a multi-input ``commands`` message (NaN if it has another count)."""
    if len(msg.data) != inputs:
        return np.full(inputs, math.nan)
    return np.asarray(msg.data, dtype=float)


def decimation(n: int, max_points: int) -> np.ndarray:
    """Indices of at most ``max_points`` of ``n`` samples: every m-th, the last always kept."""
    if n <= max_points:
        return np.arange(n)
    step = math.ceil((n - 1) / (max_points - 1))
    idx = np.arange(0, n, step)
    if idx[-1] != n - 1:
        idx = np.append(idx, n - 1)
    return idx


def to_time(seconds: float) -> Time:
    """A ``builtin_interfaces/Time`` from seconds."""
    return ns_to_time(round(seconds * 1e9))


def ns_to_time(ns: int) -> Time:
    """A ``builtin_interfaces/Time`` from integer nanoseconds."""
    sec, nanosec = divmod(int(ns), 1_000_000_000)
    return Time(sec=sec, nanosec=nanosec)


def to_duration(seconds: float) -> Duration:
    """A ``builtin_interfaces/Duration`` from seconds (>= 0)."""
    sec = math.floor(seconds)
    return Duration(sec=int(sec), nanosec=min(round((seconds - sec) * 1e9), 999_999_999))


def from_time(t: Time) -> float:
    """Seconds from a ``builtin_interfaces/Time`` or ``Duration``."""
    return t.sec + 1e-9 * t.nanosec


def planned_trajectory(
    states: np.ndarray, commands: np.ndarray, dt: float, stamp: Time, max_points: int
) -> JointTrajectory:
    """The predicted rigid-body motion of a plan, one point per (decimated) sample."""
    msg = JointTrajectory()
    msg.header.stamp = stamp
    msg.joint_names = [RIGID_BODY]
    u = np.append(np.asarray(commands, float), 0.0)  # command from each sample on; hold after
    for i in decimation(len(states), max_points):
        msg.points.append(
            JointTrajectoryPoint(
                positions=[float(states[i, 0])],
                velocities=[float(states[i, 1])],
                effort=[float(u[i])],
                time_from_start=to_duration(i * dt),
            )
        )
    return msg


def path(states: np.ndarray, dt: float, start_time: float, frame_id: str, max_points: int) -> Path:
    """The predicted positions of a plan as a ``nav_msgs/Path`` (stamps: predicted sample times)."""
    msg = Path()
    start_ns = round(start_time * 1e9)  # integer ns: seconds since 1970 as a float lose ~0.2 us
    msg.header.stamp = ns_to_time(start_ns)
    msg.header.frame_id = frame_id
    for i in decimation(len(states), max_points):
        pose = PoseStamped()
        pose.header.stamp = ns_to_time(start_ns + round(i * dt * 1e9))
        pose.header.frame_id = frame_id
        pose.pose.position.x = float(states[i, 0])
        pose.pose.orientation.w = 1.0
        msg.poses.append(pose)
    return msg


def error_path(reason: str, stamp: Time) -> Path:
    """The answer to a refused GetPlan: no poses, ``frame_id = "error: <reason>"``."""
    msg = Path()
    msg.header.stamp = stamp
    msg.header.frame_id = ERROR_PREFIX + reason
    return msg


def path_error(msg: Path) -> str | None:
    """The reason of a refused GetPlan answer, or None if it is a plan."""
    fid = msg.header.frame_id
    return fid[len(ERROR_PREFIX) :] if fid.startswith(ERROR_PREFIX) else None


@dataclass(frozen=True, kw_only=True)
class TrajectoryGoal:
    """What a ``~/joint_trajectory`` message asks for.

    Attributes
    ----------
    target : float or None
        The last point's position of the planner's joint (m or rad); None: stop (no points).
    arrival_time : float or None
        The last point's ``time_from_start`` (s) as the requested arrival,
        counted from the move's first command; None: as fast as possible (0).
    """

    target: float | None
    arrival_time: float | None = None


def trajectory_goal(msg: JointTrajectory, joint_name: str = RIGID_BODY) -> TrajectoryGoal:
    """A joint trajectory controller's goal for the joint ``joint_name``: its last point, at rest.

    Only the last point counts (the planner plans its own path there); its
    ``time_from_start`` is the requested arrival (0: as fast as possible).
    An empty message (no points) stops.

    Raises
    ------
    GoalError
        ``joint_names`` empty, repeating a name or naming a joint this planner
        does not move (with the closest valid name); the last point without a
        finite position for each joint, with a non-zero final velocity, or a
        negative ``time_from_start``.
    """
    if not msg.points:
        return TrajectoryGoal(target=None)
    names = [str(n) for n in msg.joint_names]
    if not names:
        raise GoalError("joint_trajectory.joint_names", f"is empty; this planner moves the joint {joint_name!r}")
    for n in names:
        if n != joint_name:
            raise GoalError(
                "joint_trajectory.joint_names",
                f"unknown joint {n!r}: this planner moves only {joint_name!r} (parameter joint_name)"
                + closest_hint(n, [joint_name]),
            )
    if len(names) != 1:
        raise GoalError("joint_trajectory.joint_names", f"names {joint_name!r} {len(names)} times; give it once")
    last = msg.points[-1]
    if len(last.positions) != 1:
        raise GoalError(
            "joint_trajectory.points[-1].positions",
            f"needs one position per joint name (1), got {len(last.positions)}",
        )
    target = float(last.positions[0])
    if not math.isfinite(target):
        raise GoalError("joint_trajectory.points[-1].positions", f"must be finite, got {target}")
    if len(last.velocities) and float(last.velocities[0]) != 0.0:
        raise GoalError(
            "joint_trajectory.points[-1].velocities",
            f"must be 0 (or empty): the planner arrives at rest, got {float(last.velocities[0])}",
        )
    t = from_time(last.time_from_start)
    if t < 0.0:
        raise GoalError(
            "joint_trajectory.points[-1].time_from_start", f"must be >= 0 s (0: as fast as possible), got {t}"
        )
    return TrajectoryGoal(target=target, arrival_time=t if t > 0.0 else None)


def joint_state(names: list[str], x: np.ndarray, u: float, stamp: Time) -> JointState:
    """Plant state ``[p, v, q1, q1', ...]`` as a JointState (effort: the applied command)."""
    msg = JointState()
    msg.header.stamp = stamp
    msg.name = list(names)
    msg.position = [float(v) for v in x[0::2]]
    msg.velocity = [float(v) for v in x[1::2]]
    # one input: its command on every joint; several: no effort (one command per input, not per joint)
    msg.effort = [float(u)] * len(names) if np.ndim(u) == 0 else []
    return msg


def state_from_joint_state(msg: JointState) -> np.ndarray:
    """Inverse of :func:`joint_state`: ``[p, v, q1, q1', ...]``."""
    x = np.empty(2 * len(msg.position))
    x[0::2] = msg.position
    x[1::2] = msg.velocity
    return x


def diagnostics(
    name: str, hardware_id: str, level: int, message: str, values: Mapping[str, object], stamp: Time
) -> DiagnosticArray:
    """One status in a DiagnosticArray (values as strings)."""
    status = DiagnosticStatus(level=bytes([level]), name=name, message=message, hardware_id=hardware_id)
    status.values = [KeyValue(key=str(k), value=value_text(v)) for k, v in values.items()]
    arr = DiagnosticArray()
    arr.header.stamp = stamp
    arr.status = [status]
    return arr


def diagnostic_values(
    msg: DiagnosticArray, name: str | None = None, hardware_id: str | None = None
) -> tuple[int, str, dict[str, str]] | None:
    """``(level, message, values)`` of the first status named ``name`` from ``hardware_id``, if given.

    Our nodes set ``hardware_id`` to their fully qualified name: ``/diagnostics``
    is one global topic, and another planner in the same DDS domain publishes
    statuses with the same ``name``.
    """
    for st in msg.status:
        if (name is None or st.name == name) and (hardware_id is None or st.hardware_id == hardware_id):
            level = st.level[0] if isinstance(st.level, (bytes, bytearray)) else int(st.level)
            return level, st.message, {kv.key: kv.value for kv in st.values}
    return None


def value_text(v: object) -> str:
    """A diagnostic or log value as text: floats to 9 significant digits, booleans as ``true`` / ``false``."""
    if isinstance(v, float):
        return f"{v:.9g}"
    if isinstance(v, bool):
        return "true" if v else "false"
    return str(v)
