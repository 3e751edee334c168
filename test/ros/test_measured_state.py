"""Goals from idle start from the machine's measured joint_states, never from a guess.

Old main planned every goal from rest at ``initial_position`` (then from the
end of its own last plan): a restarted planner moved the machine a second
time, or planned "from rest" while it was moving.
"""

from __future__ import annotations

import time

import numpy as np
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from flexmotion_ros.core.simulation.exact import modal_amplitudes
from flexmotion_ros.nodes import messages
from flexmotion_ros.nodes.plant_node import PLANT_QOS

from .conftest import FAST, goal_request, wait_for
from .test_goals import assert_at_rest


def kill(ros, node) -> None:
    """End a planner mid-test (as a crash would): its stream stops at once, then its executor; the node is destroyed."""
    node.stream.stop()
    i = ros.nodes.index(node)
    ros.executors[i].shutdown(timeout_sec=2.0)
    node.destroy_node()


def settled_count(plant, quiet: float = 0.3, timeout: float = 10.0) -> int:
    """Commands the plant applied, once none has arrived for ``quiet`` s."""
    end = time.monotonic() + timeout
    n = plant.applied
    while time.monotonic() < end:
        time.sleep(quiet)
        if plant.applied == n:
            return n
        n = plant.applied
    raise AssertionError("the plant kept receiving commands")


def move_and_wait(ros, planner, plant, target: float, applied_before: int):
    """Send ``target`` on ~/goal; wait until the plant has applied the whole plan and its hold."""
    n_seg = len(planner.installed)
    ros.probe.goal_pub.publish(Float64(data=target))
    wait_for(lambda: len(planner.installed) > n_seg, 15.0, "the plan")
    seg = planner.installed[-1]
    wait_for(lambda: plant.applied >= applied_before + seg.samples + 1, 15.0, "the plant to apply the move")
    wait_for(lambda: planner.stream.idle, 5.0, "the end of the move")
    return seg


def test_planner_started_after_the_plant_moved_plans_from_the_measured_state(ros):
    """Old main: the second planner assumed the machine at 0 and moved it +1.0 to 1.6."""
    first = ros.planner()
    plant = ros.plant()
    ros.connected(first)
    move_and_wait(ros, first, plant, 0.6, 0)
    n = settled_count(plant)
    assert abs(plant.state()[0] - 0.6) < 1e-6
    kill(ros, first)
    second = ros.planner()  # initial_position 0.0: the planner's belief is wrong
    ros.connected(second)
    seg = move_and_wait(ros, second, plant, 1.0, n)
    assert abs(seg.states[0, 0] - 0.6) < 1e-6, seg.states[0]  # planned from where the machine is
    wait_for(lambda: plant.applied == n + seg.samples + 1, 5.0, "every command")
    assert_at_rest(plant.cfg.model, plant.state(), 1.0, 0.4)


def test_restarted_planner_stops_a_moving_machine_at_the_goal(ros):
    """The planner dies mid-move; the machine is moving and swinging; a new planner brings it to the goal, at rest.

    Old main: the new planner planned "from rest at 0 to 0.5" and the machine
    ended far from 0.5, moving.
    """
    first = ros.planner()
    plant = ros.plant()
    ros.connected(first)
    ros.probe.goal_pub.publish(Float64(data=2.0))
    wait_for(lambda: plant.applied >= 120, 10.0, "120 samples into the move")
    kill(ros, first)
    n = settled_count(plant)
    x = plant.state()
    assert 0.3 < x[0] < 1.99 and abs(x[1]) > 0.5, x  # mid-move, moving fast
    assert np.max(modal_amplitudes(plant.cfg.model, x)) > 1e-4, x  # and swinging
    second = ros.planner()
    ros.connected(second)
    seg = move_and_wait(ros, second, plant, 0.5, n)
    np.testing.assert_allclose(seg.states[0], x, rtol=0, atol=1e-12)  # planned from the measured moving state
    wait_for(lambda: plant.applied == n + seg.samples + 1, 5.0, "every command")
    assert_at_rest(plant.cfg.model, plant.state(), 0.5, 1.0)
    assert np.max(np.abs(ros.probe.command_values())) <= FAST["u_max"]


def test_restarted_planner_stop_brings_a_moving_machine_to_rest(ros):
    """``~/stop`` on an idle planner whose machine is moving (it was restarted mid-move): a time-optimal stop.

    Old main answered "already at rest" and sent nothing while the machine moved on.
    """
    first = ros.planner()
    plant = ros.plant()
    ros.connected(first)
    ros.probe.goal_pub.publish(Float64(data=2.0))
    wait_for(lambda: plant.applied >= 120, 10.0, "120 samples into the move")
    kill(ros, first)
    n = settled_count(plant)
    x = plant.state()
    assert abs(x[1]) > 0.5, x
    second = ros.planner()
    ros.connected(second)
    resp = ros.call(ros.probe.stop, Trigger.Request())
    assert resp.success and resp.message.startswith("stopping: "), resp.message
    seg = second.installed[-1]
    np.testing.assert_allclose(seg.states[0], x, rtol=0, atol=1e-12)
    wait_for(lambda: plant.applied == n + seg.samples + 1, 10.0, "every command")
    xf = plant.state()
    assert abs(xf[1]) < 1e-6 and np.all(modal_amplitudes(plant.cfg.model, xf) < 1e-6), xf
    assert abs(xf[0] - seg.states[-1, 0]) < 1e-6
    # idle and at rest now: a second stop has nothing to do
    resp = ros.call(ros.probe.stop, Trigger.Request())
    assert resp.success and "already at rest" in resp.message, resp.message


def error_status(ros) -> str:
    st = ros.probe.planner_status()
    return st[1] if st is not None and st[0] == 2 else ""


def test_missing_measured_state_refuses_the_goal_with_the_reason(ros):
    """No machine publishes joint_states: refused after waiting state.timeout_s; nothing moves.

    Old main: it planned from rest at initial_position and streamed the move.
    """
    planner = ros.planner(**{"state.timeout_s": 0.3})
    ros.connected(planner, subscribers=1)
    t0 = time.monotonic()
    resp = ros.call(ros.probe.move, goal_request(0.5))
    reason = messages.path_error(resp.plan)
    assert not resp.plan.poses and reason is not None
    assert reason.startswith("state.source: no measured state: nothing received on "), reason
    assert "joint_states" in reason and "refusing rather than guessing" in reason, reason
    assert time.monotonic() - t0 >= 0.3  # it waited for one
    ros.probe.goal_pub.publish(Float64(data=0.5))
    wait_for(lambda: "no measured state" in error_status(ros), 5.0, "the refusal on /diagnostics")
    time.sleep(0.3)
    assert not planner.installed and not ros.probe.commands
    # plan only (nothing moves) still answers, from the believed state
    resp = ros.call(ros.probe.plan, goal_request(0.5))
    assert resp.plan.poses and resp.plan.poses[0].pose.position.x == 0.0
    # 'assumed' is the old open loop, on request
    assumed = ros.planner(**{"state.source": "assumed", "initial_position": 0.25})
    assert assumed.request(0.5, execute=False, source="test").ok


def test_stale_or_incomplete_measured_state_refuses_the_goal(ros):
    planner = ros.planner(**{"state.timeout_s": 0.3})
    ros.connected(planner, subscribers=1)
    pub = ros.probe.create_publisher(JointState, "joint_states", PLANT_QOS)
    wait_for(lambda: pub.get_subscription_count() >= 2, 10.0, "the planner's state subscription")
    x = planner.config.model.rest_state(0.3)
    names = ["rigid_body", "mode_1", "mode_2"]
    pub.publish(messages.joint_state(names, x, 0.0, ros.probe.get_clock().now().to_msg()))
    out = planner.request(0.5, execute=True, source="test")  # fresh: planned from 0.3
    assert out.ok and out.segment.states[0, 0] == 0.3, out
    wait_for(lambda: planner.stream.idle, 10.0, "the end of the move")
    time.sleep(0.4)  # older than state.timeout_s now, and nothing new comes
    out = planner.request(0.6, execute=True, source="test")
    assert not out.ok and out.reason.startswith("state.timeout_s: measured state on "), out.reason
    assert "is stale: last received" in out.reason and "allowed 0.3 s" in out.reason, out.reason
    # a state without the modal joints: refused, naming the missing one
    pub.publish(messages.joint_state(["rigid_body"], x[:2], 0.0, ros.probe.get_clock().now().to_msg()))
    out = planner.request(0.6, execute=True, source="test")
    assert not out.ok and "joint 'mode_1' missing from the measured joint_states" in out.reason, out.reason
    assert len(planner.installed) == 1
