"""Several inputs over ROS (issue 12): a two-axis gantry planned, streamed (m values per sample) and simulated.

Real planner and plant nodes, lockstep: goals by ``~/goals`` and by ``~/move``
end at the target, at rest, with every residual below 1e-6 of the move;
``~/goal`` is refused for two rigid bodies; a goal and a stop mid-move are
spliced at the predicted moving, swaying state; a partial
``~/joint_trajectory`` keeps the other axis's target.
"""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest
from std_msgs.msg import Float64, Float64MultiArray
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from flexmotion_ros.core.multi_input.dispatch import state_at_rest
from flexmotion_ros.core.parameter_file import read_parameter_file
from flexmotion_ros.nodes import messages
from flexmotion_ros.nodes.planner_node import COMMAND_QOS

from .conftest import goal_request, wait_for
from .test_goals import finished_move

ROOT = Path(__file__).resolve().parents[2]
#: The shipped gantry (trolley 300 N on x, bridge 500 N on y, one sway mode per axis) at 100 Hz.
GANTRY = {**read_parameter_file(ROOT / "config" / "gantry.yaml"), "rate_hz": 100.0}
U_MAX = np.array(GANTRY["u_max"])


class Recorder:
    """Every ``commands`` message as a row of m values (the conftest probe keeps the first value only)."""

    def __init__(self, ros) -> None:
        self.rows: list[list[float]] = []
        self.lock = threading.Lock()
        ros.probe.create_subscription(Float64MultiArray, "commands", self._on, COMMAND_QOS)
        self.goals = ros.probe.create_publisher(Float64MultiArray, "flexmotion_planner/goals", 10)

    def _on(self, msg: Float64MultiArray) -> None:
        with self.lock:
            self.rows.append(list(msg.data))

    def commands(self) -> np.ndarray:
        with self.lock:
            return np.array(self.rows)


def start(ros, **extra):
    planner = ros.planner(**{**GANTRY, **extra})
    plant = ros.plant(**GANTRY)
    rec = Recorder(ros)
    ros.connected(planner, subscribers=3)  # the plant, the probe and the recorder
    wait_for(lambda: rec.goals.get_subscription_count() >= 1, 10.0, "~/goals subscription")
    return planner, plant, rec


def assert_at(model, x, targets, move: float, tol: float = 1e-6) -> None:
    """Every rigid body at its target and still, every sway amplitude below ``tol * move``."""
    np.testing.assert_allclose(x[0 : 2 * model.k : 2], targets, rtol=0, atol=tol * move)
    assert state_at_rest(model, x, tol * move), x


@pytest.mark.parametrize("how", ["goals_topic", "move_service"])
def test_two_axis_gantry_goal_ends_at_the_target_at_rest(ros, how):
    planner, plant, rec = start(ros)
    assert plant.joint_names == ["x", "y", "sway_x", "sway_y"]
    if how == "goals_topic":
        rec.goals.publish(Float64MultiArray(data=[3.0, 2.0]))
    else:
        resp = ros.call(ros.probe.move, goal_request_xy(3.0, 2.0))
        assert messages.path_error(resp.plan) is None
        last = resp.plan.poses[-1].pose.position
        assert abs(last.x - 3.0) < 1e-12 and abs(last.y - 2.0) < 1e-12
    (seg,), total = finished_move(ros, planner)
    K = seg.samples
    assert seg.commands.shape == (K, 2)
    X = ros.probe.states()
    assert len(X) == total == K + 1
    np.testing.assert_allclose(X[:K], seg.states[1:], rtol=0, atol=1e-9)  # the plant follows the plan exactly
    assert_at(plant.cfg.model, X[K - 1], [3.0, 2.0], 3.0)  # at sample K: both axes, no sway
    assert_at(plant.cfg.model, X[K], [3.0, 2.0], 3.0)
    assert not state_at_rest(plant.cfg.model, X[K - 2], 1e-6 * 3.0)  # still moving one sample before
    # the stream: m values per sample in joint order, the plan then one hold of zeros, never above a bound
    u = rec.commands()
    np.testing.assert_array_equal(u, np.vstack([seg.commands, np.zeros((1, 2))]))
    assert np.all(np.max(np.abs(u), axis=0) <= U_MAX)
    # both axes really move, and they arrive together (the time-optimal T* of the slower axis)
    assert np.all(np.max(np.abs(seg.commands), axis=0) > 0.1 * U_MAX)
    wait_for(lambda: ros.probe.trajectories, 5.0, "planned trajectory")
    traj = ros.probe.trajectories[-1]
    assert traj.joint_names == ["x", "y", "sway_x", "sway_y"] and len(traj.points) == K + 1
    np.testing.assert_allclose(traj.points[-1].positions[:2], [3.0, 2.0], atol=1e-9)
    wait_for(lambda: (ros.probe.planner_status() or (0, "", {}))[1] == "idle", 5.0, "idle status")
    _, _, values = ros.probe.planner_status()
    assert values["last_plan.certified"] == "true" and values["last_plan.samples"] == str(K)


def goal_request_xy(x: float, y: float):
    req = goal_request(x)
    req.goal.pose.position.y = float(y)
    return req


def test_one_target_on_goal_is_refused_for_two_rigid_bodies(ros):
    planner, _, rec = start(ros)
    ros.probe.goal_pub.publish(Float64(data=1.0))
    wait_for(
        lambda: "~/goals" in (ros.probe.planner_status() or (0, "", {}))[2].get("last_error", ""),
        5.0,
        "the refusal on /diagnostics",
    )
    level, _, values = ros.probe.planner_status()
    assert level == 2 and "2 rigid bodies ['x', 'y']" in values["last_error"], values
    rec.goals.publish(Float64MultiArray(data=[1.0]))  # one target for two rigid bodies: refused too
    wait_for(
        lambda: "needs one target per rigid body" in (ros.probe.planner_status() or (0, "", {}))[2]["last_error"],
        5.0,
        "the ~/goals refusal",
    )
    assert not planner.installed and not rec.commands().size


def test_goal_and_stop_mid_move_are_spliced_for_both_axes(ros):
    planner, plant, rec = start(ros, replan_lead_s=0.5)
    rec.goals.publish(Float64MultiArray(data=[3.0, 2.0]))
    wait_for(lambda: len(rec.commands()) >= 40, 10.0, "40 commands")  # 0.4 s into a 4.1 s move
    rec.goals.publish(Float64MultiArray(data=[-1.0, 1.0]))  # preempt: a new goal for both axes
    wait_for(lambda: len(planner.installed) >= 2, 10.0, "the preemption")
    wait_for(lambda: len(rec.commands()) >= planner.installed[-1].start + 30, 10.0, "30 commands of the new plan")
    resp = ros.call(ros.probe.stop, Trigger.Request())  # then stop everything
    assert resp.success and resp.message.startswith("stopping"), resp.message
    (seg1, seg2, seg3), total = finished_move(ros, planner, 3)
    X = ros.probe.states()
    u = rec.commands()
    assert len(X) == total == len(u)
    s2, s3 = seg2.start - seg1.start, seg3.start - seg1.start
    assert 0 < s2 < seg1.samples and s2 < s3 < s2 + seg2.samples
    # the plant reached each predicted splice state, moving and swaying
    np.testing.assert_allclose(X[s2 - 1], seg2.states[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(X[s3 - 1], seg3.states[0], rtol=0, atol=1e-9)
    assert np.all(np.abs(X[s2 - 1][[1, 3]]) > 1e-3) and not state_at_rest(plant.cfg.model, X[s3 - 1], 1e-3)
    # the commands are the three plans joined, then the hold (zeros) for every axis
    np.testing.assert_array_equal(
        u, np.vstack([seg1.commands[:s2], seg2.commands[: s3 - s2], seg3.commands, np.zeros((1, 2))])
    )
    assert np.all(np.max(np.abs(u), axis=0) <= U_MAX)
    end = X[-1]
    assert state_at_rest(plant.cfg.model, end, 1e-6 * 3.0), end  # stopped: still, no sway, wherever it is


def test_partial_joint_trajectory_keeps_the_other_axis(ros):
    planner, plant, rec = start(ros)
    msg = JointTrajectory(joint_names=["y"])
    msg.points = [JointTrajectoryPoint(positions=[0.5])]
    ros.probe.jt_pub.publish(msg)
    (seg,), total = finished_move(ros, planner)
    X = ros.probe.states()
    assert_at(plant.cfg.model, X[seg.samples - 1], [0.0, 0.5], 0.5)
    assert np.all(rec.commands()[:, 0] == 0.0)  # x kept at its target: the trolley never pushes
    bad = JointTrajectory(joint_names=["z"])
    bad.points = [JointTrajectoryPoint(positions=[1.0])]
    ros.probe.jt_pub.publish(bad)
    wait_for(
        lambda: "unknown joint 'z'" in (ros.probe.planner_status() or (0, "", {}))[2].get("last_error", ""),
        5.0,
        "the refusal",
    )


#: Multi-input files, good and bad: ``flexmotion plan`` and the node must give the same verdict, word for word.
VERDICT_EDITS = [
    ("", ""),  # the shipped gantry: accepted by both
    ("rigid_bodies:", "rigid_bodys:"),
    ("u_max: [300.0, 500.0]", "u_max: [300, 500]"),
    ("u_max: [300.0, 500.0]", "u_max: [300.0, 500.0, 1.0]"),
    ("u_max: [300.0, 500.0]", "u_max: 400.0"),  # one bound for both inputs: accepted
    ("b: [-0.005, 0.0, 0.0, -0.0014285714285714286]", "b: [-0.005, 0.0, 0.0, 0.0]"),
    ("sync: time", "sync: tme"),
    ("sync: time", "sync: none"),
    ("method: time_optimal", "method: limited"),
    ("method: time_optimal", "method: zvd"),
    ("rate_hz: 1000.0", "rate_hz: 0.5"),  # sway above the Nyquist frequency: refused
    ("sync: time", "sync: time\n    joint_names: [a, b, c]"),  # a node parameter, judged alike
    ("sync: time", "sync: time\n    joint_names: [a, a]"),
    ("sync: time", "sync: time\n    joint_names: [gantry_x, gantry_y]"),  # renamed joints: accepted
]


@pytest.mark.parametrize("old, new", VERDICT_EDITS)
def test_the_cli_and_the_node_give_the_same_verdict_on_a_multi_input_file(ros, tmp_path, old, new):
    from flexmotion_ros.core.errors import FlexmotionError
    from flexmotion_ros.core.multi_input.dispatch import load_any_config
    from flexmotion_ros.nodes.planner_node import PlannerNode

    from .conftest import NAMESPACE

    path = tmp_path / "gantry.yaml"
    path.write_text((ROOT / "config" / "gantry.yaml").read_text().replace(old, new))
    try:
        cli = ("ok", load_any_config(path))
    except FlexmotionError as exc:
        cli = ("refused", str(exc))
    try:
        args = ["--ros-args", "--params-file", str(path)]
        node = ros.add(PlannerNode(context=ros.context, namespace=NAMESPACE, cli_args=args))
        verdict = ("ok", node.config)
    except FlexmotionError as exc:
        verdict = ("refused", str(exc))
    assert verdict == cli
    accepted = ("", "u_max: 400.0", "sync: none", "method: zvd", "sync: time\n    joint_names: [gantry_x, gantry_y]")
    assert (cli[0] == "ok") == (new in accepted), cli


def test_demo_moves_the_gantry_on_both_axes(tmp_path, capsys):
    """``flexmotion demo --config config/gantry.yaml --goal 3,2``, shortened: planner and plant processes, real DDS."""
    from flexmotion_ros.cli.main import main

    png = tmp_path / "demo.png"
    status = main(
        [
            "demo",
            "--config",
            str(ROOT / "config" / "gantry.yaml"),
            "--goal",
            "0.6,0.3",
            "--rate",
            "100.0",
            "--plot",
            str(png),
        ]
    )
    out = capsys.readouterr().out
    assert status == 0, out
    assert "measured arrival" in out and "every axis together" in out, out
    assert "trolley" in out and "bridge" in out and png.stat().st_size > 10_000


def test_deactivating_mid_move_ends_with_a_hold_of_zeros_on_every_input(ros):
    from lifecycle_msgs.msg import Transition

    from .test_safety import lifecycle

    planner, _, rec = start(ros)
    rec.goals.publish(Float64MultiArray(data=[3.0, 2.0]))
    wait_for(lambda: len(rec.commands()) >= 40, 10.0, "the move under way")
    assert lifecycle(ros, Transition.TRANSITION_DEACTIVATE)
    wait_for(lambda: planner.stream.halted is not None, 5.0, "the halt")
    import time

    time.sleep(0.3)
    u = rec.commands()
    assert planner.stream.halted.interrupted and planner.stream.halted.held
    assert len(u) < planner.installed[-1].samples + 1
    np.testing.assert_array_equal(u[-1], [0.0, 0.0])  # the hold: zero on both drives
    assert np.all(np.any(u[:-1] != 0.0, axis=1))  # cut off mid-move: no hold before
    assert "hold (0) sent" in planner.stream.halted.describe()


def test_a_missing_or_incomplete_measured_state_refuses_a_multi_axis_goal(ros):
    from sensor_msgs.msg import JointState

    from flexmotion_ros.nodes.plant_node import PLANT_QOS

    planner = ros.planner(**{**GANTRY, "state.timeout_s": 0.3})
    ros.connected(planner, subscribers=1)
    out = planner.request(np.array([1.0, 1.0]), execute=True, source="test")  # nothing publishes joint_states
    assert not out.ok and out.reason.startswith("state.source: no measured state"), out.reason
    pub = ros.probe.create_publisher(JointState, "joint_states", PLANT_QOS)
    wait_for(lambda: pub.get_subscription_count() >= 2, 10.0, "the planner's state subscription")
    x = planner.config.model.rest_state([0.5, -0.5])
    stamp = ros.probe.get_clock().now().to_msg()
    pub.publish(messages.joint_state(["x", "sway_x", "sway_y"], np.delete(x, [2, 3]), 0.0, stamp))  # no 'y'
    wait_for(lambda: planner._listener.store.received >= 1, 5.0, "the state")
    out = planner.request(np.array([1.0, 1.0]), execute=True, source="test")
    assert not out.ok and "joint 'y' missing from the measured joint_states" in out.reason, out.reason
    pub.publish(messages.joint_state(["x", "y", "sway_x", "sway_y"], x, 0.0, ros.probe.get_clock().now().to_msg()))
    wait_for(lambda: planner._listener.store.received >= 2, 5.0, "the whole state")
    out = planner.request(np.array([1.0, 1.0]), execute=False, source="test")  # fresh: planned from there
    assert out.ok and np.array_equal(out.segment.states[0], x), out
