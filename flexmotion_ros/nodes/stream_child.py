"""The ROS side of the stream process: its own rclpy context, one tiny node, the ``commands`` publisher.

:func:`open_output` is what :meth:`~flexmotion_ros.execution.stream_process.StreamProcess.fork`
runs in the child at each ``configure``: it initialises rclpy once (without
signal handlers: Ctrl-C is the planner's to handle, the child ignores it),
creates the node ``<planner>_stream`` in the planner's namespace and a
publisher on the planner's resolved ``commands`` topic with the planner's
QoS.  Nothing spins: a publisher needs no executor, and its matched count is
kept by DDS's own threads.
"""

from __future__ import annotations

from collections.abc import Callable

import rclpy
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import Float64MultiArray

from ..execution.stream_process import ChildSettings
from . import messages


def open_output(cfg: ChildSettings) -> tuple[Callable[[list], None], Callable[[], int], Callable[[], None]]:
    """``(publish(values), matched_count(), close())`` for the child's stream (module docstring)."""
    if not rclpy.ok():
        rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(cfg.node_name, namespace=cfg.namespace or "/")
    qos = QoSProfile(
        depth=cfg.qos_depth,
        reliability=ReliabilityPolicy.RELIABLE if cfg.qos_reliable else ReliabilityPolicy.BEST_EFFORT,
        history=HistoryPolicy.KEEP_LAST,
    )
    pub = node.create_publisher(Float64MultiArray, cfg.topic, qos)
    msg = messages.command(0.0, cfg.inputs)

    def publish(values: list) -> None:
        msg.data = values
        pub.publish(msg)

    def close() -> None:
        node.destroy_publisher(pub)
        node.destroy_node()

    return publish, pub.get_subscription_count, close


__all__ = ["open_output"]
