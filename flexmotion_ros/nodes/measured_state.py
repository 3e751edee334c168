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

import threading

from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

from ..execution.measured_state import MeasuredState

#: Best effort, keep last 10: matches reliable and best-effort publishers alike.
STATE_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT, history=HistoryPolicy.KEEP_LAST)


class StateListener:
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
        self.topic = owner.resolve_topic_name(topic)
        self._node = Node(
            f"{owner.get_name()}_state",
            namespace=owner.get_namespace(),
            context=owner.context,
            use_global_arguments=False,
            start_parameter_services=False,
        )
        self._node.create_subscription(JointState, self.topic, self._on_state, STATE_QOS)
        self._executor = SingleThreadedExecutor(context=owner.context)
        self._executor.add_node(self._node)
        self._thread = threading.Thread(target=self._spin, name="flexmotion-state", daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        try:
            self._executor.spin()
        except Exception:  # noqa: BLE001 -- context shut down under us: nothing more to receive
            pass

    def _on_state(self, msg: JointState) -> None:
        self.store.update(msg.name, msg.position, msg.velocity)

    def publisher_count(self) -> int:
        """Publishers matched on the state topic."""
        return self._node.count_publishers(self.topic)

    def close(self) -> None:
        """Stop the executor thread and destroy the internal node."""
        self._executor.shutdown(timeout_sec=1.0)
        self._thread.join(timeout=2.0)
        self._node.destroy_node()


__all__ = ["STATE_QOS", "StateListener"]
