"""The quality of service of the planner's topics (the tests' and the demo's probes subscribe with the same)."""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

#: ``commands``: reliable and deep (10 s at 1 kHz), so that a lagging lockstep plant never loses a sample.
COMMAND_QOS = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
#: ``~/goal``, ``~/joint_trajectory``: deep enough that a burst reaches the node, which keeps the newest goal and
#: counts the others as superseded on /diagnostics (nothing is dropped unseen in DDS).
GOAL_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
#: ``~/planned_trajectory``: late joiners get the current plan.
LATCHED_QOS = QoSProfile(
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
    history=HistoryPolicy.KEEP_LAST,
)


__all__ = ["COMMAND_QOS", "GOAL_QOS", "LATCHED_QOS"]
