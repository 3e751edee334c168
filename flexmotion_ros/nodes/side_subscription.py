"""A ``sensor_msgs/JointState`` subscription on an internal node and executor of its own.

The planner's executor is single-threaded and busy while it plans, so what it
must not miss is served elsewhere: a small internal node (``<owner>_<suffix>``,
the owner's namespace and context, no global arguments, no parameter
services; the topic resolved with the owner's own remappings) spun by its own
``SingleThreadedExecutor`` in a daemon thread.  Subclasses say what a message
does (:meth:`SideSubscription._on`): :class:`~.measured_state.StateListener`
(``joint_states``) and :class:`~.measurement_listener.MeasurementListener`
(``measurements``).
"""

from __future__ import annotations

import threading

from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from sensor_msgs.msg import JointState


class SideSubscription:
    """Subscribe to ``topic`` (resolved by ``owner``) on an internal node spun in a thread of its own.

    Parameters
    ----------
    owner : Node
        The planner: its context, namespace and remappings are used.
    suffix : str
        The internal node is ``<owner's name>_<suffix>``.
    topic : str
        ``sensor_msgs/JointState`` topic name (relative names resolve in the owner's namespace).
    qos : QoSProfile
        The subscription's QoS.
    """

    def __init__(self, owner: Node, suffix: str, topic: str, qos: QoSProfile) -> None:
        self.topic = owner.resolve_topic_name(topic)
        self._node = Node(
            f"{owner.get_name()}_{suffix}",
            namespace=owner.get_namespace(),
            context=owner.context,
            use_global_arguments=False,
            start_parameter_services=False,
        )
        self._sub = self._node.create_subscription(JointState, self.topic, self._on, qos)
        self._executor = SingleThreadedExecutor(context=owner.context)
        self._executor.add_node(self._node)
        self._thread = threading.Thread(target=self._spin, name=f"flexmotion-{suffix}", daemon=True)
        self._thread.start()

    def _on(self, msg: JointState) -> None:
        raise NotImplementedError

    def _spin(self) -> None:
        try:
            self._executor.spin()
        except Exception:  # noqa: BLE001 -- context shut down under us: nothing more to receive
            pass

    def publisher_count(self) -> int:
        """Publishers matched with this subscription."""
        return self._sub.get_publisher_count()

    def close(self) -> None:
        """Stop the executor thread and destroy the internal node."""
        self._executor.shutdown(timeout_sec=1.0)
        self._thread.join(timeout=2.0)
        self._node.destroy_node()


__all__ = ["SideSubscription"]
