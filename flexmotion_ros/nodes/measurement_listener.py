"""The planner's ``measurements`` subscription, on an internal node and executor of its own.

Like :mod:`.measured_state`: a small internal node (``<planner>_measurements``,
same namespace, no global arguments; the topic resolved with the planner's own
remappings) spun by its own ``SingleThreadedExecutor`` in a daemon thread, so
that a busy planner executor never delays a reading.  Each reading goes into a
:class:`~flexmotion_ros.execution.records.SignalLog` (stamp, one value per
``measurement.names`` channel, in that order).  QoS: the plant's
(:data:`~.plant_measurements.MEASUREMENT_QOS`, reliable): a record needs
every sample.
"""

from __future__ import annotations

import threading

from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import JointState

from ..execution.records import SignalLog
from .plant_measurements import MEASUREMENT_QOS, TOPIC


class MeasurementListener:
    """``measurements`` on an internal node and executor of its own; each reading goes into ``log``.

    Parameters
    ----------
    owner : Node
        The planner (context, namespace, remappings).
    names : tuple of str
        ``measurement.names``: the columns of ``log`` (a message's channels are put in this order).
    log : SignalLog
        Where the readings go (stamp ns, values).
    """

    def __init__(self, owner: Node, names: tuple[str, ...], log: SignalLog) -> None:
        self.log = log
        self.names = tuple(names)
        self.mismatched = 0  # messages whose names are not measurement.names
        self.topic = owner.resolve_topic_name(TOPIC)
        self._node = Node(
            f"{owner.get_name()}_measurements",
            namespace=owner.get_namespace(),
            context=owner.context,
            use_global_arguments=False,
            start_parameter_services=False,
        )
        self._sub = self._node.create_subscription(JointState, self.topic, self._on, MEASUREMENT_QOS)
        self._executor = SingleThreadedExecutor(context=owner.context)
        self._executor.add_node(self._node)
        self._thread = threading.Thread(target=self._spin, name="flexmotion-measurements", daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        try:
            self._executor.spin()
        except Exception:  # noqa: BLE001 -- context shut down under us: nothing more to receive
            pass

    def _on(self, msg: JointState) -> None:
        names = tuple(msg.name)
        if names == self.names:
            values = msg.position
        else:
            index = {n: i for i, n in enumerate(names)}
            if not all(n in index for n in self.names) or len(msg.position) != len(names):
                self.mismatched += 1
                return
            values = [msg.position[index[n]] for n in self.names]
        self.log.append(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec, values)

    def publisher_count(self) -> int:
        """Publishers matched with this subscription of ``measurements``."""
        return self._sub.get_publisher_count()

    def close(self) -> None:
        self._executor.shutdown(timeout_sec=1.0)
        self._thread.join(timeout=2.0)
        self._node.destroy_node()


__all__ = ["MeasurementListener"]
