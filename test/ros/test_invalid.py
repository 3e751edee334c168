"""Bad goals and bad parameters are refused with a reason; nothing moves; the node keeps serving."""

from __future__ import annotations

import math
import subprocess
import sys
import time
from pathlib import Path

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
    """A move needing over 5e6 samples at the rate: refused by the sample budget, or beyond it by the core."""
    planner = ros.planner(rate_hz=2e5, **{"state.source": "assumed"})  # no plant: plan from the assumed state
    ros.connected(planner, subscribers=1)
    resp = ros.call(ros.probe.move, goal_request(2000.0))  # 28 s at 200 kHz
    assert not resp.plan.poses and "max_move_samples = 100000" in messages.path_error(resp.plan)
    (res,) = _set(ros, {"max_move_samples": 10_000_000})  # past the budget: the core's own refusal
    assert res.successful, res.reason
    resp = ros.call(ros.probe.move, goal_request(2000.0))
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
    with pytest.raises(FlexmotionError, match=r"u_max: must be a double .*, got the integer 2: write 2.0"):
        planner(u_max=2)  # the same line as `flexmotion plan` on a file with `u_max: 2`
    with pytest.raises(FlexmotionError, match=r"u_mx: unknown parameter; did you mean u_max\?"):
        planner(u_mx=5.0)  # old main: ignored, planned with u_max 10
    with pytest.raises(FlexmotionError, match=r"colomb_force: unknown parameter; did you mean coulomb_force\?"):
        planner(method="time_optimal_friction", colomb_force=0.1)
    with pytest.raises(FlexmotionError, match=r"coulomb_force: required by method time_optimal_friction"):
        planner(method="time_optimal_friction")
    with pytest.raises(FlexmotionError, match=r"lockstepp: unknown parameter; did you mean lockstep\?"):
        plant(lockstepp=True)  # the plant judges the shared file the same way
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


# ------------------------------------------------------------ strict configuration (issue 11)
def test_a_method_change_without_its_required_option_is_refused_and_changes_nothing(ros):
    """Old main: ``ros2 param set method time_optimal_friction`` succeeded, then every goal was refused."""
    planner = ros.planner(**{"state.source": "assumed"})
    ros.connected(planner, subscribers=1)
    before = planner.config
    (res,) = _set(ros, {"method": "time_optimal_friction"})
    assert not res.successful
    assert "coulomb_force: required by method time_optimal_friction" in res.reason, res.reason
    assert planner.config == before and planner.get_parameter("method").value == "time_optimal"
    # every option is declared up front with a descriptor: method and option in one atomic set
    d = planner.describe_parameter("coulomb_force")
    assert "required by time_optimal_friction" in d.description and "N, in [0, u_max)" in d.description
    (res,) = _set(ros, {"method": "time_optimal_friction", "coulomb_force": 0.1}, atomically=True)
    assert res.successful, res.reason
    assert planner.config.method == "time_optimal_friction" and planner.config.options == {"coulomb_force": 0.1}
    resp = ros.call(ros.probe.plan, goal_request(0.5))
    assert resp.plan.poses, resp.plan.header.frame_id
    (res,) = _set(ros, {"coulomb_force": 1})  # an integer where a double is declared: rclpy refuses it too
    assert not res.successful and planner.config.options == {"coulomb_force": 0.1}


def test_a_goal_beyond_the_move_budget_is_refused_up_front(ros):
    """Old main: ``goal 1e300`` failed deep in numpy (Maximum allowed size exceeded)."""
    planner = ros.planner(**{"state.source": "assumed"})
    ros.connected(planner, subscribers=1)
    resp = ros.call(ros.probe.plan, goal_request(1e300))
    reason = messages.path_error(resp.plan) or ""
    assert not resp.plan.poses and "goal: the move needs at least" in reason and "max_move_duration_s" in reason
    (res,) = _set(ros, {"max_move_duration_s": 0.5})  # the budget is a parameter: 1.0 needs >= 0.63 s
    assert res.successful, res.reason
    assert "max_move_duration_s = 0.5 s" in (
        messages.path_error(ros.call(ros.probe.plan, goal_request(1.0)).plan) or ""
    )
    assert ros.call(ros.probe.plan, goal_request(0.1)).plan.poses
    assert not planner.installed and not ros.probe.commands


def test_a_goal_over_the_sample_budget_is_refused_in_microseconds_naming_it(ros):
    # issue 16: a goal of 1e6 was accepted as a 47-minute move planned in 8.6 s (1e9 blocked the executor 23.8 s)
    planner = ros.planner(**{"state.source": "assumed"})
    ros.connected(planner, subscribers=1)
    t0 = time.monotonic()
    resp = ros.call(ros.probe.plan, goal_request(1e6))
    answered_s = time.monotonic() - t0
    reason = messages.path_error(resp.plan) or ""
    assert not resp.plan.poses and "max_move_samples = 100000" in reason, reason
    assert answered_s < 0.5, answered_s  # the refusal itself costs ~60 us; the rest is DDS
    (res,) = _set(ros, {"max_move_samples": 50})  # the budget is a parameter: a 1.0 move needs >= 126 at 200 Hz
    assert res.successful, res.reason
    reason = messages.path_error(ros.call(ros.probe.move, goal_request(1.0)).plan) or ""
    assert "max_move_samples = 50" in reason and "samples at 200 Hz" in reason, reason
    assert ros.call(ros.probe.plan, goal_request(0.01)).plan.poses
    assert not planner.installed and not ros.probe.commands


@pytest.mark.parametrize(
    "params, words",
    [
        ({"model.omega": [5.0, 1e5]}, "model.omega[1]: 100000 rad/s is at or above the Nyquist frequency"),
        ({"model.omega": [5.0, 700.0]}, "700 rad/s is at or above the Nyquist frequency pi x rate_hz = 628.319"),
    ],
)
def test_a_value_that_cannot_be_planned_is_refused_when_set_with_the_physical_reason(ros, params, words):
    # issue 16: omega 1e5 rad/s at 1 kHz was accepted, then the next plan took 36.9 s
    planner = ros.planner(**{"state.source": "assumed"})
    ros.connected(planner, subscribers=1)
    before = planner.config
    (res,) = _set(ros, params)
    assert not res.successful and words in res.reason, res.reason
    assert planner.config == before  # nothing changed
    assert ros.call(ros.probe.plan, goal_request(0.5)).plan.poses  # still plans with the old values


def _start_planner(params_file: Path, timeout: float = 60.0) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "flexmotion_ros.nodes.planner_node", "--ros-args", "--params-file", str(params_file)]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)


@pytest.mark.parametrize(
    "body, fragments",
    [
        ("    u_max: 1.0\n   rate_hz: [1.0\n", ["--params-file:", "is not valid YAML at line 4, column 4"]),
        ("    model:\n      omega: [1, 2.0]\n", ["model.omega:", "list items must all have one type"]),
        ("    u_mx: 5.0\n", ["u_mx: unknown parameter; did you mean u_max?"]),
        ("    u_max: 1\n", ["u_max: must be a double", "write 1.0"]),
    ],
)
def test_the_executable_refuses_a_bad_parameter_file_in_one_line(tmp_path, body, fragments):
    """Old main: a YAML syntax error was an rcl traceback (exit 1); a typo or ``u_max: 1`` in a key was
    started with the default (the node kept running: the time-out below)."""
    path = tmp_path / "bad.yaml"
    path.write_text("/**:\n  ros__parameters:\n" + body)
    done = _start_planner(path)
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith("flexmotion_planner: error: ") and done.stderr.count("\n") == 1, done.stderr
    assert "Traceback" not in done.stderr and done.stdout == ""
    for f in fragments:
        assert f in done.stderr, done.stderr
    assert str(path) in done.stderr or "unknown" in done.stderr or "must be" in done.stderr
