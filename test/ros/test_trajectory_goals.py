"""``~/joint_trajectory``: the joint names are checked and the last ``time_from_start`` is the arrival."""

from __future__ import annotations

import time

import numpy as np
import pytest
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from flexmotion_ros.core.errors import ConfigError
from flexmotion_ros.nodes import messages

from .conftest import FAST, wait_for
from .test_goals import assert_at_rest, finished_move


def trajectory(names: list[str], target: float, t: float = 0.0) -> JointTrajectory:
    msg = JointTrajectory(joint_names=names)
    msg.points = [
        JointTrajectoryPoint(positions=[target / 2] * len(names), time_from_start=messages.to_duration(t / 2)),
        JointTrajectoryPoint(positions=[target] * len(names), time_from_start=messages.to_duration(t)),
    ]
    return msg


def error_status(ros) -> str:
    st = ros.probe.planner_status()
    return st[1] if st is not None and st[0] == 2 else ""


@pytest.mark.parametrize(
    "names, words",
    [
        (
            ["rigid_bdy"],
            "unknown joint 'rigid_bdy': this planner moves only 'rigid_body' (parameter joint_name) (closest: 'rigid_body')",
        ),
        (["rigid_body", "gripper"], "unknown joint 'gripper'"),
        ([], "joint_names: is empty"),
    ],
)
def test_trajectory_naming_another_joint_is_refused_and_nothing_moves(ros, names, words):
    """Old main: positions[0] of any trajectory was the target, whatever the joint names (it moved)."""
    planner = ros.planner()
    ros.plant()
    ros.connected(planner)
    ros.probe.jt_pub.publish(trajectory(names, 0.4))
    wait_for(lambda: words in error_status(ros), 10.0, f"the refusal {words!r}")
    assert error_status(ros).startswith("error: joint_trajectory.joint_names: "), error_status(ros)
    time.sleep(0.3)
    assert not planner.installed and not ros.probe.commands


def test_trajectory_with_the_configured_joint_name_is_accepted(ros):
    planner = ros.planner(joint_name="axis_x", **{"state.mode_joint_names": ["mode_1", "mode_2"]})
    ros.plant()
    ros.connected(planner)
    ros.probe.jt_pub.publish(trajectory(["rigid_body"], 0.4))  # not this planner's joint
    wait_for(lambda: "unknown joint 'rigid_body'" in error_status(ros), 10.0, "the refusal")
    assert not planner.installed
    # the plant names its rigid body 'rigid_body': the measured state needs it under joint_name
    ros.probe.jt_pub.publish(trajectory(["axis_x"], 0.4))
    wait_for(lambda: "joint 'axis_x' missing from the measured joint_states" in error_status(ros), 10.0, "refusal")
    assert not planner.installed and not ros.probe.commands


def test_time_from_start_is_the_arrival_time_at_rest(ros):
    """A 1.0 move takes T* = 1.11 s (222 samples at 200 Hz); asked for 2.0 s it arrives at rest at sample 400.

    Old main: time_from_start was ignored, the move took the 222-sample optimum.
    """
    planner = ros.planner()
    plant = ros.plant()
    ros.connected(planner)
    ros.probe.jt_pub.publish(trajectory(["rigid_body"], 1.0, 2.0))
    (seg,), total = finished_move(ros, planner)
    K = round(2.0 * FAST["rate_hz"])
    assert seg.samples == K, seg.samples
    assert seg.info.result.method == "fixed_time"
    X = ros.probe.states()
    assert len(X) == total == K + 1
    np.testing.assert_allclose(X[:K], seg.states[1:], rtol=0, atol=1e-9)
    assert_at_rest(plant.cfg.model, X[K - 1], 1.0, 1.0)  # after command K: there, at rest
    assert not np.allclose(X[K - 2], X[K - 1])  # still moving one sample before
    assert np.max(np.abs(ros.probe.command_values())) <= FAST["u_max"]


def test_time_from_start_zero_means_as_fast_as_possible(ros):
    planner = ros.planner()
    plant = ros.plant()
    ros.connected(planner)
    ros.probe.jt_pub.publish(trajectory(["rigid_body"], 1.0, 0.0))
    (seg,), _ = finished_move(ros, planner)
    assert seg.samples == 222 and seg.info.result.method == "time_optimal"
    assert_at_rest(plant.cfg.model, ros.probe.states()[seg.samples - 1], 1.0, 1.0)


def test_time_from_start_before_the_optimum_is_refused_by_default(ros):
    planner = ros.planner()
    ros.plant()
    ros.connected(planner)
    ros.probe.jt_pub.publish(trajectory(["rigid_body"], 1.0, 0.5))
    wait_for(lambda: "before the fastest arrival" in error_status(ros), 10.0, "the refusal")
    reason = error_status(ros)
    assert "joint_trajectory.points[-1].time_from_start: 0.5 s" in reason, reason
    assert "trajectory.early_arrival" in reason and "T*" in reason, reason
    time.sleep(0.3)
    assert not planner.installed and not ros.probe.commands


def test_time_from_start_before_the_optimum_takes_the_optimum_when_the_parameter_says_so(ros):
    planner = ros.planner(**{"trajectory.early_arrival": "optimum"})
    plant = ros.plant()
    ros.connected(planner)
    ros.probe.jt_pub.publish(trajectory(["rigid_body"], 1.0, 0.5))
    (seg,), _ = finished_move(ros, planner)
    assert seg.samples == 222  # the optimum, not 100 samples
    assert_at_rest(plant.cfg.model, ros.probe.states()[seg.samples - 1], 1.0, 1.0)


def test_bad_trajectory_parameters_are_refused_at_start_up(ros):
    with pytest.raises(
        ConfigError,
        match=r"trajectory.early_arrival: must be one of \['refuse', 'optimum'\], got 'optimun' \(closest: 'optimum'\)",
    ):
        ros.planner(**{"trajectory.early_arrival": "optimun"})
    with pytest.raises(
        ConfigError,
        match=r"state.source: must be one of \['measured', 'assumed'\], got 'measure' \(closest: 'measured'\)",
    ):
        ros.planner(**{"state.source": "measure"})
