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

from rclpy.node import Node
from sensor_msgs.msg import JointState

from ..execution.records import SignalLog
from .plant_measurements import MEASUREMENT_QOS, TOPIC
from .side_subscription import SideSubscription


class MeasurementListener(SideSubscription):
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
        super().__init__(owner, "measurements", TOPIC, MEASUREMENT_QOS)

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


__all__ = ["MeasurementListener"]
