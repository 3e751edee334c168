"""Command interfaces and trajectory output with real nodes (issue 14).

Lockstep: each command interface (the plant's servo ideal) ends at rest at
the target; trajectory output played by a lockstep plant is exact, also
through a preemption (the replacement from the sample being played).
"""

from __future__ import annotations

import subprocess
import sys
import time

import numpy as np
import pytest
from rclpy.duration import Duration
from rclpy.time import Time
from std_msgs.msg import Float64
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from flexmotion_ros.core.simulation.exact import modal_amplitudes
from flexmotion_ros.nodes.planner_node import PlannerNode
from flexmotion_ros.nodes.planner_output import TRAJECTORY_QOS
from flexmotion_ros.nodes.plant_node import PlantNode

from .conftest import NAMESPACE, overrides, wait_for


def residual(model, x, target: float, move: float) -> float:
    """Position error, velocity and every mode's amplitude, the largest, as a fraction of the move."""
    return max(abs(x[0] - target), abs(x[1]), float(np.max(modal_amplitudes(model, x), initial=0.0))) / move


def settled(ros, planner, plant, n_segments: int, timeout: float = 20.0) -> np.ndarray:
    """Wait for the plans, the end of the timeline, and the plant's last sample; the plant's state."""
    wait_for(lambda: len(planner.installed) >= n_segments, timeout, "the plans")
    wait_for(lambda: planner.stream.idle, timeout, "the end of the move")
    time.sleep(0.3)
    return plant.state()


@pytest.mark.parametrize("iface", ["effort", "velocity", "position"])
def test_lockstep_loop_ends_at_rest_for_each_command_interface(ros, iface):
    """The planner sends force, velocity or position references; the plant's ideal servo tracks them exactly."""
    planner = ros.planner(command_interface=iface)
    plant = ros.plant(command_interface=iface)
    ros.connected(planner)
    ros.probe.goal_pub.publish(Float64(data=1.0))
    x = settled(ros, planner, plant, 1)
    assert residual(plant.cfg.model, x, 1.0, 1.0) < 1e-6, x
    seg = planner.installed[0]
    sent = ros.probe.command_values()
    assert sent.size == seg.samples + 1  # the move, then the hold
    hold = {"effort": 0.0, "velocity": 0.0, "position": seg.states[-1, 0]}[iface]
    assert sent[-1] == pytest.approx(hold, abs=1e-12)  # the hold of a position joint is where it ended, not 0
    if iface == "velocity":
        np.testing.assert_allclose(sent[:-1], seg.states[1:, 1], atol=1e-9)  # v_{k+1}, due at the end of sample k
    if iface == "position":
        np.testing.assert_allclose(sent[:-1], seg.states[1:, 0], atol=1e-9)  # p_{k+1}


def trajectory_probe(ros, topic: str = "joint_trajectory") -> list:
    """The probe records the planner's trajectories (and matches the planner's publisher)."""
    got: list = []
    ros.probe.create_subscription(JointTrajectory, topic, got.append, TRAJECTORY_QOS)
    return got


def test_trajectory_output_played_by_a_lockstep_plant_is_exact_through_a_preemption(ros):
    """One trajectory per plan; the replacement starts at the sample being played; the plant ends exactly at rest."""
    common = {"output": "trajectory", "trajectory.start_delay_s": 0.1}
    planner = ros.planner(**common)
    plant = ros.plant(**{"plant.input": "trajectory"})
    got = trajectory_probe(ros)
    wait_for(lambda: planner.commands_publisher.get_subscription_count() >= 2, 10.0, "trajectory subscribers")
    wait_for(lambda: ros.probe.goal_pub.get_subscription_count() >= 1, 10.0, "goal topic")
    ros.probe.goal_pub.publish(Float64(data=1.0))
    wait_for(lambda: len(planner.installed) >= 1, 10.0, "the first plan")
    time.sleep(0.5)  # mid-move (1.1 s)
    ros.probe.goal_pub.publish(Float64(data=-0.5))
    x = settled(ros, planner, plant, 2)
    print(
        "TRAJ residual",
        residual(plant.cfg.model, x, -0.5, 1.5),
        x,
        [s.start for s in planner.installed],
        plant.playback_rewinds(),
    )
    assert residual(plant.cfg.model, x, -0.5, 1.5) < 1e-9, x
    wait_for(lambda: len(got) >= 2, 5.0, "both trajectories")
    first, second = got[0], got[1]
    dt_ns = round(1e9 / 200.0)
    stamp = lambda m: m.header.stamp.sec * 10**9 + m.header.stamp.nanosec  # noqa: E731
    # the replacement: from the sample being played, on the same sample instants, repeating the old commands
    assert stamp(second) > stamp(first) and (stamp(second) - stamp(first)) % dt_ns == 0
    k = (stamp(second) - stamp(first)) // dt_ns
    old = [p.effort[0] for p in first.points[k + 1 : k + 4]]
    new = [p.effort[0] for p in second.points[1:4]]
    assert old == new
    assert second.points[-1].effort[0] == 0.0 and second.points[-1].velocities[0] == 0.0  # ends with the hold
    assert plant.playback_rewinds() >= 1  # the lockstep plant had played the first one to its end


#: Wie-Bernstein (the demo's machine) at 500 Hz, |u| <= 1 N.
WB = {"model.b0": 0.5, "model.omega": [2**0.5], "model.zeta": [0.0], "model.b": [1.0], "u_max": 1.0, "rate_hz": 500.0}


def test_real_time_trajectory_is_exact_beside_cpu_burners_where_the_stream_is_not(ros):
    """Two CPU-burning processes load the machine; the real-time plant plays the trajectory by its own clock.

    The same move, same load, same test: output trajectory ends within 1e-6 of the move (exact up to
    rounding: the plant integrates every piece from the trajectory's own instants), the stream's residual
    is what its timing jitter leaves (printed: the comparison bench/ros_streaming.py records).
    """
    burners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    try:
        # 1 s of lead: at load 24 with the burners, 0.2 s was once not enough for the trajectory to arrive
        # before its start (residual 1.5e-3); a late start is counted by the plant and asserted below
        planner = ros.planner(**WB, output="trajectory", **{"trajectory.start_delay_s": 1.0})
        plant = ros.plant(**WB, lockstep=False, publish_rate_hz=100.0, **{"plant.input": "trajectory"})
        wait_for(lambda: planner.commands_publisher.get_subscription_count() >= 1, 10.0, "the plant's subscription")
        wait_for(lambda: ros.probe.goal_pub.get_subscription_count() >= 1, 10.0, "goal topic")
        ros.probe.goal_pub.publish(Float64(data=0.5))
        x_traj = settled(ros, planner, plant, 1)
        traj = residual(plant.cfg.model, x_traj, 0.5, 0.5)

        ns = NAMESPACE + "/stream"
        s_planner = ros.add(
            PlannerNode(
                context=ros.context,
                namespace=ns,
                parameter_overrides=overrides({**WB, "publish_hold_when_idle": False}),
            )
        )
        s_plant = ros.add(
            PlantNode(
                context=ros.context,
                namespace=ns,
                parameter_overrides=overrides({k: v for k, v in WB.items() if k != "u_max"} | {"lockstep": False}),
            )
        )
        goal = ros.probe.create_publisher(Float64, ns + "/flexmotion_planner/goal", 10)
        wait_for(lambda: s_planner.commands_publisher.get_subscription_count() >= 1, 10.0, "the stream plant")
        wait_for(lambda: goal.get_subscription_count() >= 1, 10.0, "the stream planner's goal")
        goal.publish(Float64(data=0.5))
        settled(ros, s_planner, s_plant, 1)
        n = s_planner.installed[0].samples + 1  # every command and the hold, handed over to the plant
        wait_for(lambda: s_plant.received >= n, 20.0, "every command at the stream plant")
        x_stream = s_plant.state()
        stream = residual(s_plant.cfg.model, x_stream, 0.5, 0.5)
    finally:
        for b in burners:
            b.kill()
            b.wait()
    print(f"\nreal time beside 2 CPU burners: residual / move  trajectory {traj:.1e}   stream {stream:.1e}")
    assert plant.trajectories_late == 0, f"the trajectory arrived {plant.trajectory_late_max_ms:.1f} ms late"
    assert traj < 1e-6, x_traj


def test_real_time_plant_counts_a_trajectory_that_arrives_after_its_start(ros):
    """A trajectory stamped 1 s in the past cannot start on time: the plant says so (count, max lateness)."""
    plant = ros.plant(**WB, lockstep=False, publish_rate_hz=100.0, **{"plant.input": "trajectory"})
    pub = ros.probe.create_publisher(JointTrajectory, NAMESPACE + "/joint_trajectory", TRAJECTORY_QOS)
    wait_for(lambda: pub.get_subscription_count() >= 1, 10.0, "the plant's trajectory subscription")
    msg = JointTrajectory(joint_names=["rigid_body"])
    msg.header.stamp = Time(nanoseconds=time.time_ns() - 1_000_000_000).to_msg()
    msg.points = [
        JointTrajectoryPoint(effort=[0.0], time_from_start=Duration(nanoseconds=1_000_000).to_msg()),
        JointTrajectoryPoint(effort=[0.0], time_from_start=Duration(nanoseconds=2_000_000).to_msg()),
    ]
    pub.publish(msg)
    wait_for(lambda: plant.trajectories_late >= 1, 10.0, "the late start counted")
    assert plant.trajectories_late == 1 and 900.0 <= plant.trajectory_late_max_ms <= 10_000.0
    assert plant.trajectory_errors == 0  # played (late), not refused


def test_trajectory_output_ends_a_deactivation_with_a_hold_trajectory(ros):
    """Cut off mid-move: the last trajectory is one point, now (stamp 0), at the reference's position, at rest."""
    planner = ros.planner(output="trajectory", command_interface="position", **{"trajectory.start_delay_s": 0.1})
    plant = ros.plant(command_interface="position", **{"plant.input": "trajectory"})
    got = trajectory_probe(ros)
    wait_for(lambda: planner.commands_publisher.get_subscription_count() >= 2, 10.0, "trajectory subscribers")
    wait_for(lambda: ros.probe.goal_pub.get_subscription_count() >= 1, 10.0, "goal topic")
    ros.probe.goal_pub.publish(Float64(data=1.0))
    wait_for(lambda: len(planner.installed) >= 1, 10.0, "the plan")
    time.sleep(0.5)
    planner.trigger_deactivate()
    wait_for(lambda: len(got) >= 2, 5.0, "the hold trajectory")
    hold = got[-1]
    assert hold.header.stamp.sec == 0 and hold.header.stamp.nanosec == 0 and len(hold.points) == 1
    p = hold.points[0]
    assert p.velocities[0] == 0.0 and p.accelerations[0] == 0.0 and 0.0 < p.positions[0] < 1.0
    time.sleep(0.3)
    x = plant.state()
    assert abs(x[0] - p.positions[0]) < 0.05 and abs(x[1]) < 1e-12  # the position servo came to rest there
