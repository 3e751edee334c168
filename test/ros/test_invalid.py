"""Bad goals and bad parameters are refused with a reason; nothing moves; the node keeps serving."""

from __future__ import annotations

import math
import time

import pytest
from rcl_interfaces.srv import SetParameters, SetParametersAtomically
from rclpy.parameter import Parameter
from std_msgs.msg import Float64

from flexmotion_ros.core.errors import FlexmotionError
from flexmotion_ros.nodes import messages
from flexmotion_ros.nodes.planner_node import PlannerNode
from flexmotion_ros.nodes.plant_node import PlantNode

from .conftest import FAST, NAMESPACE, goal_request, overrides, wait_for
from .test_goals import assert_at_rest, finished_move

LIMITS = {"limits.position_min": -2.0, "limits.position_max": 2.0}


def error_status(ros) -> str:
    st = ros.probe.planner_status()
    return st[1] if st is not None and st[0] == 2 else ""


@pytest.mark.parametrize(
    "goal, words",
    [
        (math.nan, "finite"),
        (math.inf, "finite"),
        (-math.inf, "finite"),
        (3.0, "outside the position limits [-2.0, 2.0]"),
    ],
)
def test_bad_goal_is_refused_nothing_moves_node_keeps_serving(ros, goal, words):
    planner = ros.planner(**LIMITS)
    plant = ros.plant()
    ros.connected(planner)
    # by topic: logged, ERROR on /diagnostics, nothing streamed
    ros.probe.goal_pub.publish(Float64(data=goal))
    wait_for(lambda: words in error_status(ros), 5.0, "ERROR status")
    assert error_status(ros).startswith("error: goal: ")
    # by service: an empty path whose frame_id carries the reason
    resp = ros.call(ros.probe.move, goal_request(goal))
    assert not resp.plan.poses
    assert resp.plan.header.frame_id.startswith("error: goal: ") and words in messages.path_error(resp.plan)
    resp = ros.call(ros.probe.plan, goal_request(goal))
    assert not resp.plan.poses and words in messages.path_error(resp.plan)
    time.sleep(0.3)
    assert not ros.probe.commands and not ros.probe.joint_states and not planner.installed
    # still serving: a good goal moves, and the status is OK again
    resp = ros.call(ros.probe.move, goal_request(1.5))
    assert messages.path_error(resp.plan) is None
    (seg,), _ = finished_move(ros, planner)
    assert_at_rest(plant.cfg.model, ros.probe.states()[seg.samples - 1], 1.5, 1.5)
    wait_for(lambda: ros.probe.planner_status()[0] == 0, 5.0, "OK status")


def test_goal_the_planner_cannot_serve_is_refused(ros):
    """A move needing over 5e6 samples at the rate: refused by the core with the reason."""
    planner = ros.planner(rate_hz=2e5)
    ros.connected(planner, subscribers=1)
    resp = ros.call(ros.probe.move, goal_request(2000.0))  # 28 s at 200 kHz
    assert not resp.plan.poses and "rate_hz" in messages.path_error(resp.plan), resp.plan.header.frame_id
    assert "rate_hz" in error_status(ros) or wait_for(lambda: "rate_hz" in error_status(ros), 5.0) is None
    resp = ros.call(ros.probe.plan, goal_request(1e-4))
    assert resp.plan.poses and not planner.installed and not ros.probe.commands


def _set(ros, params: dict, atomically: bool = False):
    if atomically:
        req = SetParametersAtomically.Request(parameters=[p.to_parameter_msg() for p in overrides(params)])
        return [ros.call(ros.probe.set_params_atomically, req).result]
    req = SetParameters.Request(parameters=[p.to_parameter_msg() for p in overrides(params)])
    return ros.call(ros.probe.set_params, req).results


@pytest.mark.parametrize(
    "params, words",
    [
        ({"model.zeta": [1.5, 0.02]}, "model.zeta[0]: must be in [0, 1)"),
        ({"model.omega": [5.0]}, "same length"),
        ({"model.omega": [5.0, 5.0]}, "repeats"),
        ({"model.b": [1.0, 0.0]}, "uncontrollable"),
        ({"model.b0": 0.0}, "model.b0"),
        ({"u_max": -1.0}, "u_max"),
        ({"method": "bogus"}, "method: must be one of"),
        ({"limits.position_min": 3.0, "limits.position_max": 2.0}, "position_min < position_max"),
        ({"rate_hz": 100.0}, "read-only"),
        ({"u_max": "ten"}, "type"),
    ],
)
def test_invalid_parameters_refused_with_reason_and_nothing_changes(ros, params, words):
    planner = ros.planner()
    ros.connected(planner, subscribers=1)
    before = {name: planner.get_parameter(name).value for name in ("u_max", "method", "rate_hz", "model.b0")}
    before_cfg = planner.config
    results = _set(ros, params, atomically=len(params) > 1)
    assert not all(r.successful for r in results)
    reasons = " | ".join(r.reason for r in results)
    assert words in reasons, reasons
    assert planner.config == before_cfg
    assert {name: planner.get_parameter(name).value for name in before} == before
    resp = ros.call(ros.probe.plan, goal_request(0.5))  # still serving
    assert resp.plan.poses


def test_valid_model_change_applies_to_the_next_goal(ros):
    planner = ros.planner()
    ros.connected(planner, subscribers=1)
    n0 = len(ros.call(ros.probe.plan, goal_request(1.0)).plan.poses)
    (res,) = _set(ros, {"u_max": 5.0})
    assert res.successful
    n1 = len(ros.call(ros.probe.plan, goal_request(1.0)).plan.poses)
    assert n1 > n0  # half the force: a longer move
    # the number of modes changes in one atomic set
    (res,) = _set(ros, {"model.omega": [7.0], "model.zeta": [0.0], "model.b": [1.0]}, atomically=True)
    assert res.successful, res.reason
    assert planner.config.model.n_modes == 1 and planner.config.u_max == 5.0
    resp = ros.call(ros.probe.plan, goal_request(1.0))
    assert resp.plan.poses and len(resp.plan.poses) != n1


def test_invalid_start_up_parameters_raise_with_the_name(ros):
    def planner(**p):
        return PlannerNode(context=ros.context, namespace=NAMESPACE, parameter_overrides=overrides({**FAST, **p}))

    def plant(**p):
        return PlantNode(context=ros.context, namespace=NAMESPACE, parameter_overrides=overrides({**FAST, **p}))

    with pytest.raises(FlexmotionError, match=r"model\.zeta\[1\]"):
        planner(**{"model.zeta": [0.01, 2.0]})
    with pytest.raises(FlexmotionError, match=r"u_max: wrong type \(write doubles as 2.0"):
        planner(u_max=2)
    with pytest.raises(FlexmotionError, match=r"plant\.omega_scale: needs one factor per mode \(2\)"):
        plant(**{"plant.omega_scale": [1.1]})
    with pytest.raises(FlexmotionError, match=r"plant\.extra_zeta\[0\]"):
        plant(**{"plant.extra_zeta": [-0.1, 0.0]})
    node = plant(**{"plant.coulomb_force": 1.0})
    assert node.cfg.coulomb_force == 1.0
    node.destroy_node()


def test_plant_refuses_invalid_live_changes(ros):
    plant = ros.plant()
    res = plant.set_parameters([Parameter("plant.omega_scale", value=[0.0, 1.0])])[0]
    assert not res.successful and "plant.omega_scale[0]" in res.reason
    res = plant.set_parameters([Parameter("lockstep", value=False)])[0]
    assert not res.successful
    res = plant.set_parameters([Parameter("plant.omega_scale", value=[1.2, 1.0])])[0]
    assert res.successful and plant.cfg.model.omega == (6.0, 13.0)
