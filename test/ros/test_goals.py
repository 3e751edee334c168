"""Goals by topic and by service drive the lockstep plant exactly to the target."""

from __future__ import annotations

import time

import numpy as np
from rclpy.parameter import Parameter
from std_msgs.msg import Float64
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from flexmotion_ros.core.simulation.exact import modal_amplitudes
from flexmotion_ros.nodes import messages

from .conftest import FAST, goal_request, wait_for


def finished_move(ros, planner, n_segments: int = 1, timeout: float = 15.0):
    """Wait for the plan(s) and for the plant to have applied every command and the hold."""
    wait_for(lambda: len(planner.installed) >= n_segments, timeout, "the plan")
    wait_for(lambda: planner.stream.idle, timeout, "the end of the move")
    segs = list(planner.installed)
    total = segs[-1].end - segs[0].start + 1  # every command plus the explicit hold
    wait_for(lambda: len(ros.probe.joint_states) >= total, timeout, f"{total} plant samples")
    time.sleep(0.2)  # the stream is silent when idle: nothing may follow
    return segs, total


def assert_at_rest(model, x, target: float, move: float, tol: float = 1e-6) -> None:
    """Rigid body at ``target`` and still, every mode's residual amplitude below ``tol * move``."""
    assert abs(x[0] - target) < tol * move, (x[0], target)
    assert abs(x[1]) < tol * move, x[1]
    amps = modal_amplitudes(model, x)
    assert np.all(amps < tol * move), amps


def test_goal_topic_brings_lockstep_plant_to_target_at_planned_sample(ros):
    planner = ros.planner()
    plant = ros.plant()
    ros.connected(planner)
    ros.probe.goal_pub.publish(Float64(data=1.0))
    (seg,), total = finished_move(ros, planner)
    K = seg.samples
    X = ros.probe.states()
    assert len(X) == total == K + 1
    # the plant follows the prediction sample by sample, and arrives exactly at sample K
    np.testing.assert_allclose(X[:K], seg.states[1:], rtol=0, atol=1e-9)
    assert_at_rest(plant.cfg.model, X[K - 1], 1.0, 1.0)
    assert_at_rest(plant.cfg.model, X[K], 1.0, 1.0)  # after the explicit hold sample
    assert not np.allclose(X[K - 2], X[K - 1])  # still moving one sample before: arrival is at K
    # the stream: the plan's commands, then one explicit hold, never above the bound
    u = ros.probe.command_values()
    np.testing.assert_array_equal(u, np.append(seg.commands, 0.0))
    assert np.max(np.abs(u)) <= FAST["u_max"]
    # planned trajectory (transient local) and diagnostics
    wait_for(lambda: ros.probe.trajectories, 5.0, "planned trajectory")
    traj = ros.probe.trajectories[-1]
    assert len(traj.points) == K + 1 and traj.joint_names == ["rigid_body"]
    assert traj.points[-1].positions[0] == seg.states[-1, 0]
    assert messages.from_time(traj.points[-1].time_from_start) == np.float64(K / FAST["rate_hz"]).round(9)
    np.testing.assert_array_equal([p.effort[0] for p in traj.points], np.append(seg.commands, 0.0))
    wait_for(lambda: (ros.probe.planner_status() or (0, "", {}))[1] == "idle", 5.0, "idle status")
    level, _, values = ros.probe.planner_status()
    assert level == 0 and values["last_plan.samples"] == str(K)
    assert values["last_plan.certified"] == "true" and values["last_plan.method"] == "time_optimal"


def test_move_service_answers_the_path_and_moves(ros):
    planner = ros.planner(initial_position=0.25)  # both start at rest at 0.25
    plant = ros.plant(**{"plant.initial_position": 0.25})
    ros.connected(planner)
    resp = ros.call(ros.probe.move, goal_request(-0.5))
    assert messages.path_error(resp.plan) is None
    poses = resp.plan.poses
    (seg,), total = finished_move(ros, planner)
    assert len(poses) == seg.samples + 1
    assert poses[0].pose.position.x == 0.25 and abs(poses[-1].pose.position.x + 0.5) < 1e-12
    # stamps: one sample period apart, from the first command's time
    t_ns = np.array([p.header.stamp.sec * 10**9 + p.header.stamp.nanosec for p in poses])
    assert np.all(np.abs(np.diff(t_ns) - 10**9 / FAST["rate_hz"]) <= 1)
    X = ros.probe.states()
    assert len(X) == total
    np.testing.assert_allclose(X[:, 0][: seg.samples], [p.pose.position.x for p in poses[1:]], atol=1e-9)
    assert_at_rest(plant.cfg.model, X[seg.samples - 1], -0.5, 0.75)


def test_plan_service_plans_and_nothing_moves(ros):
    planner = ros.planner()
    ros.plant()
    ros.connected(planner)
    resp = ros.call(ros.probe.plan, goal_request(0.7))
    assert messages.path_error(resp.plan) is None
    assert resp.plan.header.frame_id == "world"
    assert len(resp.plan.poses) > 10 and abs(resp.plan.poses[-1].pose.position.x - 0.7) < 1e-12
    time.sleep(0.5)
    assert not ros.probe.commands and not ros.probe.joint_states and not planner.installed


def test_joint_trajectory_goal_targets_last_point(ros):
    planner = ros.planner()
    plant = ros.plant()
    ros.connected(planner)
    msg = JointTrajectory(joint_names=["rigid_body"])
    msg.points = [JointTrajectoryPoint(positions=[0.2]), JointTrajectoryPoint(positions=[0.4])]
    ros.probe.jt_pub.publish(msg)
    (seg,), total = finished_move(ros, planner)
    X = ros.probe.states()
    assert len(X) == total
    assert_at_rest(plant.cfg.model, X[seg.samples - 1], 0.4, 0.4)


def test_mis_modelled_plant_shows_what_a_wrong_model_costs(ros):
    """The same exact plan on a plant whose first mode is 10 % stiffer leaves vibration."""
    planner = ros.planner()
    plant = ros.plant(**{"plant.omega_scale": [1.1, 1.0], "plant.extra_zeta": [0.0, 0.0]})
    ros.connected(planner)
    ros.probe.goal_pub.publish(Float64(data=1.0))
    (seg,), _ = finished_move(ros, planner)
    x = ros.probe.states()[seg.samples - 1]
    assert plant.cfg.model.omega == (5.5, 13.0)
    residual = modal_amplitudes(plant.cfg.model, x)
    assert residual[0] > 1e-3, residual  # the detuned mode rings
    assert residual[1] < 1e-2, residual


def test_coulomb_friction_in_the_plant_costs_position(ros):
    """A plan that ignores 1 N of Coulomb friction (eq. 2.11) misses the target by far.

    Friction adds to the braking: the machine stops early, and the rest of the
    braking command drives it back.  It acts on the rigid body only, so the
    modes are still cancelled.
    """
    planner = ros.planner()
    plant = ros.plant(**{"plant.coulomb_force": 1.0})
    ros.connected(planner)
    ros.probe.goal_pub.publish(Float64(data=1.0))
    _, total = finished_move(ros, planner)
    X = ros.probe.states()
    assert len(X) == total
    assert abs(1.0 - X[-1, 0]) > 0.1 and abs(X[-1, 1]) > 0.1, X[-1]
    assert np.all(modal_amplitudes(plant.cfg.model, X[-1]) < 1e-9)


def test_hold_stream_while_idle_is_a_parameter_and_never_drifts(ros):
    planner = ros.planner(publish_hold_when_idle=True)
    ros.connected(planner, subscribers=1)
    wait_for(lambda: len(planner.stream.sent_times) >= 400, 10.0, "2 s of idle hold stream")
    assert set(ros.probe.command_values()) == {0.0}
    # absolute deadlines: the offset of sample k from k / rate does not grow (a
    # sleep(dt) loop would drift by its per-sample overhead, ~40 ms over 400 samples)
    t = np.array(planner.stream.sent_times)[-400:]
    # (the least-late of 50 samples: load only ever adds lateness, a drift moves the floor)
    offset = t - t[0] - np.arange(t.size) / FAST["rate_hz"]
    assert abs(np.min(offset[-50:]) - np.min(offset[:50])) < 5e-3, offset
    # switched off live: the stream falls silent (counted at the sender: on a loaded
    # machine the probe may still be draining its queue for a while)
    assert planner.set_parameters([Parameter("publish_hold_when_idle", value=False)])[0].successful
    time.sleep(0.2)
    n = planner.stream.samples_sent
    time.sleep(0.3)
    assert planner.stream.samples_sent == n
