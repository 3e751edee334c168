"""Several inputs in the planner node: joints, goals per rigid body, and the messages of an ``m``-input plan.

A multi-input parameter file (``model.inputs`` set; issue 12) makes the
planner stream ``m`` values per sample and take one target per rigid body:

* ``commands``: one value per input, in the order of ``joint_names``
  (default ``model.inputs``): a ros2_control forward command controller with
  those joints;
* ``~/goals`` (``std_msgs/Float64MultiArray``): one target per rigid body
  (``model.rigid_bodies`` order); ``~/goal`` (``Float64``) only when there
  is one rigid body, refused with the reason otherwise;
* ``~/joint_trajectory``: ``joint_names`` are rigid-body names; a partial
  goal keeps the other rigid bodies' targets (as the joint trajectory
  controller's ``allow_partial_joints_goal``): NaN here, filled in when the
  start state is known (:func:`~flexmotion_ros.core.multi_input.dispatch.keep_targets`);
* ``~/move`` / ``~/plan``: ``pose.position.x, y, z`` are the first three rigid
  bodies' targets; the answered path has their predicted positions;
* ``~/planned_trajectory``: every rigid body and mode (positions and
  velocities); the commands are on ``commands``.

A single-input configuration goes through unchanged (the functions answer
what the node did before: one float target, :func:`.messages.trajectory_goal`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point
from nav_msgs.msg import Path
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from ..core.errors import ConfigError, GoalError
from ..core.multi_input.config import MultiPlannerConfig
from ..core.multi_input.dispatch import AnyConfig, body_positions, check_joint_names, keep_targets
from ..core.parameter_checks import closest_hint
from ..execution.measured_state import StateSettings
from . import messages

#: ``pose.position`` fields, in the order of the rigid bodies they carry.
POSE_AXES = ("x", "y", "z")


def is_multi(config: AnyConfig) -> bool:
    """A multi-input configuration."""
    return isinstance(config, MultiPlannerConfig)


def command_joint_names(config: AnyConfig, values: Mapping[str, Any]) -> tuple[str, ...]:
    """The joints of ``commands``, one per input: ``joint_names`` or ``model.inputs`` (one input: ``joint_name``).

    Raises
    ------
    ConfigError
        ``joint_names`` with another count than the inputs, or repeated names
        (:func:`~flexmotion_ros.core.multi_input.dispatch.check_joint_names`, as ``flexmotion plan``).
    """
    names = check_joint_names(config, values.get("joint_names"))
    return names or (str(values.get("joint_name", "rigid_body")),)


def state_joints(settings: StateSettings, config: AnyConfig) -> list[str]:
    """The joints of the measured state vector: the rigid body (bodies), then one per mode."""
    if not is_multi(config):
        return settings.state_joint_names(config.model.n_modes)
    model = config.model
    modes = list(settings.mode_joint_names) or list(model.mode_names)
    if len(modes) != model.n_modes:
        raise GoalError(
            "state.mode_joint_names",
            f"names {len(modes)} joint(s) but the model has {model.n_modes} mode(s); give one per mode or none",
        )
    names = [*model.rigid_bodies, *modes]
    if len(set(names)) != len(names):
        raise ConfigError("state.mode_joint_names", f"joint names must differ from each other, got {names}")
    return names


def initial_position(config: AnyConfig, value: Any):
    """``initial_position``: a float for one input; one per rigid body (or one for all) for several."""
    if not is_multi(config):
        if isinstance(value, (list, tuple)):
            raise ConfigError("initial_position", f"a single-input model takes one position, got {value!r}")
        return float(value)
    p = [float(v) for v in (value if isinstance(value, (list, tuple)) else [value])]
    k = config.model.k
    if len(p) == 1:
        p = p * k
    if len(p) != k or not all(math.isfinite(v) for v in p):
        raise ConfigError(
            "initial_position",
            f"needs one finite position per rigid body {list(config.model.rigid_bodies)} (or one for all), got {value!r}",
        )
    return np.array(p)


def position_of(config: AnyConfig, x: np.ndarray):
    """The rigid-body position(s) of state ``x``: a float for one input, an array of ``k`` for several."""
    if not is_multi(config):
        return float(x[0])
    return np.array(body_positions(config.model, x), float)


# ----------------------------------------------------------------------- goals
def goal_target(config: AnyConfig, value: float):
    """A ``~/goal`` (one ``Float64``): the target, or :class:`GoalError` when there are several rigid bodies."""
    if not is_multi(config):
        return float(value)
    if config.model.k != 1:
        raise GoalError(
            "~/goal",
            f"carries one target but the model has {config.model.k} rigid bodies {list(config.model.rigid_bodies)}: "
            "send ~/goals (std_msgs/Float64MultiArray, one target per rigid body) or ~/joint_trajectory",
        )
    return np.array([float(value)])


def goals_target(config: AnyConfig, data: Sequence[float]):
    """A ``~/goals`` message: one target per rigid body (a float for a single-input model)."""
    values = [float(v) for v in data]
    k = config.model.k if is_multi(config) else 1
    names = list(config.model.rigid_bodies) if is_multi(config) else ["rigid_body"]
    if len(values) != k:
        raise GoalError("~/goals", f"needs one target per rigid body {names} ({k}), got {len(values)}: {values}")
    for j, v in enumerate(values):
        if not math.isfinite(v):
            raise GoalError(f"~/goals[{j}]", f"must be a finite position ({names[j]}), got {v}")
    return np.array(values) if is_multi(config) else values[0]


def pose_target(config: AnyConfig, position: Point):
    """``~/move`` / ``~/plan``: ``x`` (one input); ``x, y, z`` for the first three rigid bodies (the rest kept)."""
    if not is_multi(config):
        return position.x
    k = config.model.k
    axes = [float(getattr(position, a)) for a in POSE_AXES]
    return np.array(axes[:k] + [math.nan] * max(0, k - len(axes)))


def trajectory_target(config: AnyConfig, msg: JointTrajectory, joint_name: str) -> messages.TrajectoryGoal:
    """A ``~/joint_trajectory`` goal: one input as before; several: targets per rigid-body name, NaN = keep.

    Raises
    ------
    GoalError
        A joint that is no rigid body (with the closest name), repeated names,
        a position count other than the names', a non-finite target, a non-zero
        final velocity or a negative ``time_from_start``.
    """
    if not is_multi(config):
        return messages.trajectory_goal(msg, joint_name)
    if not msg.points:
        return messages.TrajectoryGoal(target=None)
    bodies = list(config.model.rigid_bodies)
    names = [str(n) for n in msg.joint_names]
    if not names:
        raise GoalError("joint_trajectory.joint_names", f"is empty; this planner moves the rigid bodies {bodies}")
    for n in names:
        if n not in bodies:
            raise GoalError(
                "joint_trajectory.joint_names",
                f"unknown joint {n!r}: the targets are per rigid body {bodies} (model.rigid_bodies)"
                + closest_hint(n, bodies),
            )
    if len(set(names)) != len(names):
        raise GoalError("joint_trajectory.joint_names", f"names a joint twice: {names}")
    last = msg.points[-1]
    if len(last.positions) != len(names):
        raise GoalError(
            "joint_trajectory.points[-1].positions",
            f"needs one position per joint name ({len(names)}), got {len(last.positions)}",
        )
    targets = np.full(len(bodies), math.nan)  # NaN: keep this rigid body's target (a partial goal)
    for n, p in zip(names, last.positions):
        if not math.isfinite(float(p)):
            raise GoalError("joint_trajectory.points[-1].positions", f"must be finite, got {float(p)} ({n})")
        targets[bodies.index(n)] = float(p)
    if len(last.velocities) and any(float(v) != 0.0 for v in last.velocities):
        raise GoalError(
            "joint_trajectory.points[-1].velocities",
            f"must be 0 (or empty): the planner arrives at rest, got {[float(v) for v in last.velocities]}",
        )
    t = messages.from_time(last.time_from_start)
    if t < 0.0:
        raise GoalError(
            "joint_trajectory.points[-1].time_from_start", f"must be >= 0 s (0: as fast as possible), got {t}"
        )
    return messages.TrajectoryGoal(target=targets, arrival_time=t if t > 0.0 else None)


def resolve_target(config: AnyConfig, target, kept_state: np.ndarray):
    """``target`` with the rigid bodies to keep (NaN) at their position in ``kept_state``.

    ``kept_state``: where the machine comes to rest if nothing changes (the end
    of the timeline during a move, the measured state when idle).
    """
    if target is None or not is_multi(config):
        return target
    return keep_targets(target, body_positions(config.model, kept_state))


# -------------------------------------------------------------------- messages
def path(config: AnyConfig, states: np.ndarray, dt: float, start_time: float, frame_id: str, max_points: int) -> Path:
    """The answered path: ``x`` (one input), or ``x, y, z`` = the first three rigid bodies' predicted positions."""
    msg = messages.path(states, dt, start_time, frame_id, max_points)
    if is_multi(config):
        idx = messages.decimation(len(states), max_points)
        pos = body_positions(config.model, np.asarray(states)[idx])
        for pose, p in zip(msg.poses, pos):
            for a, v in zip(POSE_AXES, p):
                setattr(pose.pose.position, a, float(v))
    return msg


def planned_trajectory(
    config: AnyConfig, states: np.ndarray, commands: np.ndarray, dt: float, stamp: Time, max_points: int
) -> JointTrajectory:
    """``~/planned_trajectory``: one input as before; several: every rigid body and mode (position, velocity)."""
    if not is_multi(config):
        return messages.planned_trajectory(states, commands, dt, stamp, max_points)
    model = config.model
    msg = JointTrajectory()
    msg.header.stamp = stamp
    msg.joint_names = [*model.rigid_bodies, *model.mode_names]
    states = np.asarray(states, float)
    for i in messages.decimation(len(states), max_points):
        msg.points.append(
            JointTrajectoryPoint(
                positions=[float(v) for v in states[i, 0::2]],
                velocities=[float(v) for v in states[i, 1::2]],
                time_from_start=messages.to_duration(i * dt),
            )
        )
    return msg


__all__ = [
    "POSE_AXES",
    "command_joint_names",
    "goal_target",
    "goals_target",
    "initial_position",
    "is_multi",
    "path",
    "planned_trajectory",
    "pose_target",
    "position_of",
    "resolve_target",
    "state_joints",
    "trajectory_target",
]
