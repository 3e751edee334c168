"""The ROS test harness itself: a callback that raises is reported at once; closing releases every participant."""

from __future__ import annotations

import pytest
from rclpy.node import Node
from std_msgs.msg import Float64

from .conftest import NAMESPACE, Ros, participant_ids, wait_for


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


def test_closing_the_harness_releases_the_dds_participant_of_planner_and_plant():
    # old main: the planner (a LifecycleNode) kept its rcl node alive through the lifecycle state machine, and
    # gc.freeze() froze the cycle: one participant leaked per test, 41 in the suite; a subprocess planner then
    # got participant id 41, past rmw_fastrtps's 32 localhost discovery ports, and was never discovered
    before = participant_ids()
    r = Ros()
    r.planner(**{"state.source": "assumed"})
    r.plant()
    assert len(participant_ids()) == len(before) + 1  # one context, one participant
    r.close()  # raises on a leaked participant
    assert participant_ids() == before
