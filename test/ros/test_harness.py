"""The ROS test harness itself: a callback that raises is reported at once, with its traceback."""

from __future__ import annotations

import pytest
from rclpy.node import Node
from std_msgs.msg import Float64

from .conftest import NAMESPACE, wait_for


def test_a_raising_callback_fails_the_wait_with_its_traceback(ros):
    def broken(msg):
        raise ValueError(f"broken callback got {msg.data}")

    node = ros.add(Node("broken", namespace=NAMESPACE, context=ros.context))
    node.create_subscription(Float64, "harness_topic", broken, 10)
    pub = ros.probe.create_publisher(Float64, "harness_topic", 10)
    wait_for(lambda: pub.get_subscription_count() >= 1, 5.0, "the broken subscriber")
    pub.publish(Float64(data=1.5))
    with pytest.raises(AssertionError, match="broken callback got 1.5"):
        wait_for(lambda: False, 5.0, "nothing")
    ros.errors.clear()  # seen: the teardown would fail on it otherwise
