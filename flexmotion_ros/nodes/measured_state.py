"""The planner's ``joint_states`` subscription, on an executor of its own.

The planner's executor is single-threaded and busy while it plans; a goal
that finds no fresh measured state waits (up to ``state.timeout_s``) for the
next message, so the subscription must be served elsewhere: a small internal
node (``<planner>_state``, same namespace, no global arguments; the topic is
resolved with the planner's own remappings) spun by its own
``SingleThreadedExecutor`` in a daemon thread.  The callback only stores the
fields (:class:`~flexmotion_ros.execution.measured_state.MeasuredState`).

QoS: best effort, depth 10 (the sensor-data convention): it matches both a
reliable ``joint_states`` publisher and the best-effort idle heartbeat of the
lockstep plant (:mod:`.plant_node`); only the latest message matters.
"""

from __future__ import annotations

from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

from ..execution.measured_state import MeasuredState
from .side_subscription import SideSubscription

#: Best effort, keep last 10: matches reliable and best-effort publishers alike.
STATE_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT, history=HistoryPolicy.KEEP_LAST)


class StateListener(SideSubscription):
    """Subscribe to ``topic`` (resolved by ``owner``) and keep the latest state in :attr:`store`.

    Parameters
    ----------
    owner : Node
        The planner: its context, namespace and remappings are used.
    topic : str
        ``sensor_msgs/JointState`` topic name (relative names resolve in the owner's namespace).
    """

    def __init__(self, owner: Node, topic: str) -> None:
        self.store = MeasuredState()
        super().__init__(owner, "state", topic, STATE_QOS)

    def _on(self, msg: JointState) -> None:
        self.store.update(msg.name, msg.position, msg.velocity)

    def publisher_count(self) -> int:
        """Publishers on the state topic (the graph's count: also those the subscription has not matched yet)."""
        return self._node.count_publishers(self.topic)


__all__ = ["STATE_QOS", "StateListener"]
