"""Goals per rigid body from each interface (:mod:`flexmotion_ros.nodes.multi_axis`), without DDS."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Point
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from flexmotion_ros.core.config import config_from_parameters
from flexmotion_ros.core.errors import ConfigError, GoalError
from flexmotion_ros.core.multi_input.dispatch import load_any_config
from flexmotion_ros.execution.measured_state import state_settings
from flexmotion_ros.nodes import multi_axis

ROOT = Path(__file__).resolve().parents[2]
GANTRY = load_any_config(ROOT / "config" / "gantry.yaml")
CHAIN = load_any_config(ROOT / "config" / "chain_two_drives.yaml")  # two inputs, one rigid body
SINGLE = config_from_parameters({"model.omega": [2.0], "model.zeta": [0.0], "model.b": [1.0]})


def jt(names, positions, velocities=(), t=0.0) -> JointTrajectory:
    msg = JointTrajectory(joint_names=list(names))
    msg.points = [
        JointTrajectoryPoint(
            positions=list(positions), velocities=list(velocities), time_from_start=Duration(sec=int(t))
        )
    ]
    return msg


def test_goal_is_one_target_for_one_rigid_body_and_refused_for_two():
    assert multi_axis.goal_target(SINGLE, 1.5) == 1.5
    np.testing.assert_array_equal(multi_axis.goal_target(CHAIN, 1.5), [1.5])
    with pytest.raises(GoalError, match=r"~/goal: carries one target but the model has 2 rigid bodies \['x', 'y'\]"):
        multi_axis.goal_target(GANTRY, 1.5)


def test_goals_one_per_rigid_body():
    np.testing.assert_array_equal(multi_axis.goals_target(GANTRY, [3.0, 2.0]), [3.0, 2.0])
    assert multi_axis.goals_target(SINGLE, [0.5]) == 0.5
    with pytest.raises(GoalError, match=r"needs one target per rigid body \['x', 'y'\] \(2\), got 3"):
        multi_axis.goals_target(GANTRY, [1.0, 2.0, 3.0])
    with pytest.raises(GoalError, match=r"~/goals\[1\]: must be a finite position \(y\)"):
        multi_axis.goals_target(GANTRY, [1.0, math.inf])


def test_pose_xyz_maps_to_the_first_three_rigid_bodies():
    p = Point(x=1.0, y=2.0, z=3.0)
    assert multi_axis.pose_target(SINGLE, p) == 1.0
    np.testing.assert_array_equal(multi_axis.pose_target(GANTRY, p), [1.0, 2.0])
    np.testing.assert_array_equal(multi_axis.pose_target(CHAIN, p), [1.0])


def test_joint_trajectory_per_rigid_body_partial_goals_keep_the_others():
    goal = multi_axis.trajectory_target(GANTRY, jt(["y"], [0.5], t=2.0), "rigid_body")
    assert np.isnan(goal.target[0]) and goal.target[1] == 0.5 and goal.arrival_time == 2.0
    kept = multi_axis.resolve_target(GANTRY, goal.target, GANTRY.model.rest_state([1.25, -3.0]))
    np.testing.assert_array_equal(kept, [1.25, 0.5])
    assert multi_axis.trajectory_target(GANTRY, JointTrajectory(joint_names=["x"]), "rigid_body").target is None
    with pytest.raises(GoalError, match=r"unknown joint 'trolley'"):
        multi_axis.trajectory_target(GANTRY, jt(["trolley"], [1.0]), "rigid_body")
    with pytest.raises(GoalError, match="names a joint twice"):
        multi_axis.trajectory_target(GANTRY, jt(["x", "x"], [1.0, 2.0]), "rigid_body")
    with pytest.raises(GoalError, match=r"needs one position per joint name \(2\), got 1"):
        multi_axis.trajectory_target(GANTRY, jt(["x", "y"], [1.0]), "rigid_body")
    with pytest.raises(GoalError, match="must be 0"):
        multi_axis.trajectory_target(GANTRY, jt(["x"], [1.0], [0.1]), "rigid_body")
    assert multi_axis.trajectory_target(SINGLE, jt(["rigid_body"], [0.4]), "rigid_body").target == 0.4


def test_joints_of_commands_and_of_the_measured_state():
    assert multi_axis.command_joint_names(GANTRY, {}) == ("trolley", "bridge")
    assert multi_axis.command_joint_names(GANTRY, {"joint_names": ["a", "b"]}) == ("a", "b")
    assert multi_axis.command_joint_names(SINGLE, {"joint_name": "cart"}) == ("cart",)
    with pytest.raises(ConfigError, match=r"joint_names: needs one joint per input \['trolley', 'bridge'\] \(2\)"):
        multi_axis.command_joint_names(GANTRY, {"joint_names": ["a"]})
    assert multi_axis.state_joints(state_settings({}), GANTRY) == ["x", "y", "sway_x", "sway_y"]
    assert multi_axis.state_joints(state_settings({"state.mode_joint_names": ["p", "q"]}), GANTRY)[2:] == ["p", "q"]
    assert multi_axis.state_joints(state_settings({}), SINGLE) == ["rigid_body", "mode_1"]
    np.testing.assert_array_equal(multi_axis.initial_position(GANTRY, 0.5), [0.5, 0.5])
    np.testing.assert_array_equal(multi_axis.initial_position(GANTRY, [0.5, -1.0]), [0.5, -1.0])
    with pytest.raises(ConfigError, match="initial_position: needs one finite position per rigid body"):
        multi_axis.initial_position(GANTRY, [0.5, 1.0, 2.0])
    with pytest.raises(ConfigError, match="a single-input model takes one position"):
        multi_axis.initial_position(SINGLE, [0.5, 1.0])
