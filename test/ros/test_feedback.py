"""Closed-loop replanning with real nodes (issue 14): a lockstep plant whose model is wrong and which is hit.

The plant's frequencies are 5 % above the planner's model and a force impulse
hits it mid-move; the planner's Kalman filter reads both masses' positions on
the plant's ``measurements`` topic.  The same goal, the same plant, in the same test: open loop
(``feedback.replan_period_s: 0``) and closed loop (every 0.1 s, from the
Kalman filter's estimate); after arrival the closed loop's residual vibration
and position error are at least 10x smaller.  With an exact model and no
disturbance, the closed loop is the open-loop plan, sample for sample.
"""

from __future__ import annotations

import time

import numpy as np
from std_msgs.msg import Float64

from flexmotion_ros.core.simulation.exact import modal_amplitudes
from flexmotion_ros.nodes.planner_node import PlannerNode
from flexmotion_ros.nodes.plant_node import PlantNode

from .conftest import NAMESPACE, PLANNING, PLANNING_UNAVAILABLE, overrides, wait_for

#: Wie-Bernstein at 100 Hz (a 0.5 move takes 3.0 s); both masses measured: x1 = p + q / 2, x2 = p - q / 2.
WB = {
    "model.b0": 0.5,
    "model.omega": [2**0.5],
    "model.zeta": [0.0],
    "model.b": [1.0],
    "u_max": 1.0,
    "rate_hz": 100.0,
    "measurement.names": ["mass_1", "mass_2"],
    "measurement.map": [1.0, 0.5, 1.0, -0.5],
}
PLANT = {k: v for k, v in WB.items() if k != "u_max"}
#: 5 % frequency error, and an impulse of 0.1 N s 1.5 s into the move (the rigid body's speed jumps by 0.05 m/s).
HIT = {
    "plant.omega_scale": [1.05],
    "plant.disturbance.type": "impulse",
    "plant.disturbance.time_s": 1.5,
    "plant.disturbance.value": 0.1,
}
#: Replanning every 0.1 s until the estimate is within 1e-3 of the move (the residual the loop settles for).
FEEDBACK = {"publish_hold_when_idle": True, "feedback.replan_period_s": 0.1, "feedback.min_deviation": 1e-3}
GOAL = 0.5


def pair(ros, ns: str, planner: dict, plant: dict):
    """A planner and a lockstep plant in namespace ``ns``, matched; the goal publisher."""
    # planning in child processes, as under ros2 run: in a thread of this process (its interpreter lock shared with
    # four nodes' threads) a 15 ms replan took 0.5-1.2 s under load and overran its look-ahead
    assert PLANNING is not None, PLANNING_UNAVAILABLE
    p = ros.add(
        PlannerNode(
            context=ros.context, namespace=ns, parameter_overrides=overrides({**WB, **planner}), planning=PLANNING
        )
    )
    q = ros.add(
        PlantNode(
            context=ros.context, namespace=ns, parameter_overrides=overrides({**PLANT, "lockstep": True, **plant})
        )
    )
    goal = ros.probe.create_publisher(Float64, ns + "/flexmotion_planner/goal", 10)
    wait_for(lambda: p.commands_publisher.get_subscription_count() >= 1, 10.0, "the plant's commands")
    wait_for(lambda: goal.get_subscription_count() >= 1, 10.0, "the goal topic")
    if p._estimator is not None:
        wait_for(p.feedback_subscribed, 10.0, "the feedback's measurements")
    return p, q, goal


def arrive(planner, plant, timeout: float = 60.0) -> np.ndarray:
    """The plant's state once the timeline has ended and the plant has applied its end."""
    wait_for(lambda: len(planner.installed) >= 1, timeout, "the plan")
    wait_for(lambda: planner.stream.idle, timeout, "the end of the timeline")
    time.sleep(0.3)
    return plant.state()


def figures(plant, x, target: float) -> tuple[float, float]:
    """(residual vibration: the largest modal amplitude and |v|, position error), as fractions of the move from 0."""
    model = plant.cfg.model  # the true (perturbed) plant
    return max(float(np.max(modal_amplitudes(model, x))), abs(x[1])) / target, abs(x[0] - target) / target


def test_replanning_every_0_1_s_corrects_a_model_error_and_an_impulse(ros):
    # one after the other: the nodes of a test share one interpreter, and two moves at once made the replans
    # (planned in a thread here, in a child process under ros2 run) overrun their look-ahead under load
    open_p, open_q, open_goal = pair(ros, NAMESPACE + "/open", {"publish_hold_when_idle": False}, HIT)
    open_goal.publish(Float64(data=GOAL))
    x_open = arrive(open_p, open_q)
    closed_p, closed_q, closed_goal = pair(ros, NAMESPACE + "/closed", FEEDBACK, HIT)
    closed_goal.publish(Float64(data=GOAL))
    x_closed = arrive(closed_p, closed_q)
    vib_open, pos_open = figures(open_q, x_open, GOAL)
    vib_closed, pos_closed = figures(closed_q, x_closed, GOAL)
    status = closed_p.status()[2]
    print(
        f"\nopen loop: vibration {vib_open:.2e}, position error {pos_open:.2e}; closed loop (0.1 s): vibration "
        f"{vib_closed:.2e}, position error {pos_closed:.2e}; {status['feedback.replanned']} replans, "
        f"{status['feedback.on_plan']} on plan, {status['feedback.failed']} failed ({status['feedback.last_failure']})"
    )
    assert status["feedback.replanned"] >= 3
    assert vib_open > 1e-3 and pos_open > 1e-3  # the disturbance and the model error do show in the open loop
    assert vib_closed < vib_open / 10.0 and pos_closed < pos_open / 10.0


def test_with_an_exact_model_the_closed_loop_is_the_open_loop_plan(ros):
    planner, plant, goal = pair(ros, NAMESPACE + "/exact", FEEDBACK, {})
    goal.publish(Float64(data=1.0))
    x = arrive(planner, plant)
    status = planner.status()[2]
    assert len(planner.installed) == 1, [s.info.source for s in planner.installed]  # never replanned
    assert status["feedback.on_plan"] >= 5 and status["feedback.replanned"] == 0, status
    seg = planner.installed[0]
    assert abs(x[0] - 1.0) < 1e-9 and np.all(modal_amplitudes(plant.cfg.model, x) < 1e-9)
    assert abs(x[1]) < 1e-9 and seg.states[-1, 0] == 1.0 or abs(seg.states[-1, 0] - 1.0) < 1e-12
