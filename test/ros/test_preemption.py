"""A new goal or a stop during a move: replanned from the predicted moving, vibrating state."""

from __future__ import annotations

import numpy as np
import pytest
from std_msgs.msg import Float64
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from flexmotion_ros.core.simulation.exact import modal_amplitudes

from .conftest import goal_request, wait_for
from .test_goals import assert_at_rest, finished_move

#: Wie-Bernstein at 100 Hz: a 1.0 move takes 4.22 s.  Replanning from a moving
#: state can take over a second on a loaded machine, so the splice is planned
#: 1 s ahead and lands in the middle of the move.
WB = {
    "model.b0": 0.5,
    "model.omega": [2**0.5],
    "model.zeta": [0.0],
    "model.b": [1.0],
    "u_max": 1.0,
    "rate_hz": 100.0,
    "replan_lead_s": 1.0,
}


def start_move_and_wait(ros, planner, target: float, samples: int) -> None:
    ros.connected(planner)
    ros.probe.goal_pub.publish(Float64(data=target))
    wait_for(lambda: len(ros.probe.commands) >= samples, 10.0, f"{samples} commands")


def check_splice(ros, plant, seg1, seg2, total):
    """The plant reached the predicted splice state, and the commands are the two plans joined."""
    s = seg2.start - seg1.start  # commands of the first plan actually sent
    assert 0 < s < seg1.samples, (s, seg1.samples)
    X = ros.probe.states()
    assert len(X) == total == s + seg2.samples + 1
    np.testing.assert_allclose(X[s - 1], seg2.states[0], rtol=0, atol=1e-9)
    # it really was moving and vibrating there
    assert abs(X[s - 1][1]) > 0.1
    assert np.max(modal_amplitudes(plant.cfg.model, X[s - 1])) > 1e-4
    u = ros.probe.command_values()
    np.testing.assert_array_equal(u, np.concatenate([seg1.commands[:s], seg2.commands, [0.0]]))
    assert np.max(np.abs(u)) <= WB["u_max"]
    return X, s


@pytest.mark.parametrize("how", ["topic", "service"])
def test_new_goal_mid_move_replans_from_predicted_state(ros, how):
    planner = ros.planner(**WB)
    plant = ros.plant(**WB)
    start_move_and_wait(ros, planner, 1.0, 10)  # 0.2 s into a 1.11 s move
    if how == "topic":
        ros.probe.goal_pub.publish(Float64(data=-0.5))
    else:
        resp = ros.call(ros.probe.move, goal_request(-0.5))
        assert resp.plan.header.frame_id == "world" and len(resp.plan.poses) > 1
    (seg1, seg2), total = finished_move(ros, planner, 2)
    X, s = check_splice(ros, plant, seg1, seg2, total)
    assert_at_rest(plant.cfg.model, X[s + seg2.samples - 1], -0.5, 1.5)
    assert_at_rest(plant.cfg.model, X[-1], -0.5, 1.5)


@pytest.mark.parametrize("how", ["service", "empty_joint_trajectory"])
def test_stop_mid_move_is_a_time_optimal_stop_to_rest(ros, how):
    # a shorter look-ahead: stopped in the acceleration phase, the machine comes
    # to rest well short of the goal (stopped after the first switch, the
    # fastest stop is the rest of the optimal move itself)
    planner = ros.planner(**{**WB, "replan_lead_s": 0.4})
    plant = ros.plant(**WB)
    # 0.3 s in (v = 0.15 m/s): a ready stop takes effect within a few samples, still well before the first switch
    start_move_and_wait(ros, planner, 1.0, 30)
    if how == "service":
        resp = ros.call(ros.probe.stop, Trigger.Request())
        assert resp.success and resp.message.startswith("stopping"), resp.message
    else:
        ros.probe.jt_pub.publish(JointTrajectory(joint_names=["rigid_body"]))
    (seg1, seg2), total = finished_move(ros, planner, 2)
    X, s = check_splice(ros, plant, seg1, seg2, total)
    stop_at = seg2.states[-1, 0]
    assert 0.0 < stop_at < 1.0 + 1e-9  # where the stop put it, not beyond the goal
    assert_at_rest(plant.cfg.model, X[s + seg2.samples - 1], stop_at, 1.0)
    assert s + seg2.samples <= seg1.samples  # never slower than finishing the move
    assert seg2.info.result.continuous.certified
    # a stop when idle is a no-op that succeeds
    resp = ros.call(ros.probe.stop, Trigger.Request())
    assert resp.success and "already at rest" in resp.message
    assert len(planner.installed) == 2
