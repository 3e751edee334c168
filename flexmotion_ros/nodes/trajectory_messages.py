"""``trajectory_msgs/JointTrajectory`` <-> the ROS-free :class:`~flexmotion_ros.execution.trajectory.JointTrajectory`.

Field for field, times in integer nanoseconds (``header.stamp`` and every
``time_from_start``), so that a replacement's points fall on exactly the
instants of the trajectory it replaces.  Empty fields stay empty.
"""

from __future__ import annotations

from builtin_interfaces.msg import Duration
from trajectory_msgs.msg import JointTrajectory as JointTrajectoryMsg
from trajectory_msgs.msg import JointTrajectoryPoint

from ..execution.trajectory import NS, JointTrajectory, TrajectoryPoint
from .messages import ns_to_time


def trajectory_msg(trajectory: JointTrajectory) -> JointTrajectoryMsg:
    """The message to publish (``header.stamp`` = the trajectory's stamp, 0 = start now)."""
    msg = JointTrajectoryMsg()
    msg.header.stamp = ns_to_time(trajectory.stamp_ns)
    msg.joint_names = list(trajectory.joint_names)
    points = []
    for p in trajectory.points:
        sec, nanosec = divmod(int(p.time_from_start_ns), NS)
        points.append(
            JointTrajectoryPoint(
                positions=p.positions,
                velocities=p.velocities,
                accelerations=p.accelerations,
                effort=p.effort,
                time_from_start=Duration(sec=sec, nanosec=nanosec),
            )
        )
    msg.points = points
    return msg


def trajectory_from_msg(msg: JointTrajectoryMsg) -> JointTrajectory:
    """The ROS-free trajectory of a received message."""
    stamp = int(msg.header.stamp.sec) * NS + int(msg.header.stamp.nanosec)
    points = tuple(
        TrajectoryPoint(
            time_from_start_ns=int(p.time_from_start.sec) * NS + int(p.time_from_start.nanosec),
            positions=tuple(p.positions),
            velocities=tuple(p.velocities),
            accelerations=tuple(p.accelerations),
            effort=tuple(p.effort),
        )
        for p in msg.points
    )
    return JointTrajectory(joint_names=tuple(msg.joint_names), stamp_ns=stamp, points=points)


__all__ = ["trajectory_from_msg", "trajectory_msg"]
