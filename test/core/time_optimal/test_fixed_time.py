"""Fixed arrival time: on time, at rest, under the bound, with the least peak force."""

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from flexmotion_ros.core import (
    ModalModel,
    config_from_parameters,
    motion_to_rest,
    plan_time_optimal,
    plan_time_optimal_zoh,
    rest_to_rest,
    simulate,
    simulate_samples,
)
from flexmotion_ros.core.errors import FlexmotionError
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.sampled.fixed_time import plan_fixed_time_zoh
from flexmotion_ros.core.time_optimal.fixed_time import plan_fixed_time

WB = ModalModel(b0=0.5, c=0.0, omega=[math.sqrt(2.0)], zeta=[0.0], b=[1.0])
ROOT = Path(__file__).resolve().parents[3]


def at_rest_error(problem, prof):
    """Distance from rest at the target at ``prof.duration`` (exact matrix-exponential simulation)."""
    x = simulate(problem.model, problem.x0, prof.input(), times=[prof.duration])[0]
    target = problem.model.rest_state(problem.target if problem.target is not None else x[0])
    return float(np.max(np.abs(x - target)))


@pytest.fixture(scope="module")
def wb5():
    problem = rest_to_rest(WB, 1.0, 1.0)
    return problem, plan_fixed_time(problem, 5.0)


def test_arrives_exactly_on_time_at_rest_under_the_bound(wb5):
    problem, prof = wb5
    assert prof.duration == 5.0
    assert prof.input().duration == 5.0
    assert at_rest_error(problem, prof) < 1e-14
    bound = prof.extra["bound_used"]
    assert 0.0 < bound < problem.u_max
    assert np.all(np.abs(prof.levels) == bound)
    assert prof.certified, prof.certificate.message  # time-optimal for the bound used


def test_scaling_gives_the_same_move_independently(wb5):
    """Rest-to-rest is linear: the move by gamma at u' is u'/u_max times the move by gamma u_max/u' at u_max."""
    _problem, prof = wb5
    bound = prof.extra["bound_used"]
    scaled = plan_time_optimal(rest_to_rest(WB, 1.0, 1.0 / bound))
    assert scaled.duration == pytest.approx(5.0, abs=1e-10)
    assert prof.switch_times == pytest.approx(scaled.switch_times, abs=1e-9)


def test_the_bound_is_the_lowest(wb5):
    _problem, prof = wb5
    bound = prof.extra["bound_used"]
    below = plan_time_optimal(rest_to_rest(WB, bound * (1.0 - 1e-6), 1.0)).duration
    above = plan_time_optimal(rest_to_rest(WB, bound * (1.0 + 1e-6), 1.0)).duration
    assert below > 5.0 > above


def test_requests_below_the_optimum_are_refused():
    problem = rest_to_rest(WB, 1.0, 1.0)
    T_star = plan_time_optimal(problem).duration
    for bad in (T_star - 1e-6, 1.0, -2.0, float("nan"), float("inf"), "soon"):
        with pytest.raises(FlexmotionError) as e:
            plan_fixed_time(problem, bad)
        assert e.value.parameter == "arrival_time"
        assert f"{T_star:.9g}" in str(e.value) and "T*" in str(e.value)


def test_request_at_the_optimum_is_the_time_optimal_move():
    problem = rest_to_rest(WB, 1.0, 1.0)
    best = plan_time_optimal(problem)
    prof = plan_fixed_time(problem, best.duration)
    assert prof.duration == best.duration
    assert prof.extra["bound_used"] == 1.0
    assert np.allclose(prof.switch_times, best.switch_times, atol=1e-12)


def test_already_at_rest_holds_still():
    problem = rest_to_rest(WB, 1.0, 0.0, start=2.0)
    prof = plan_fixed_time(problem, 3.0)
    assert prof.duration == 3.0 and np.all(prof.levels == 0.0)
    assert at_rest_error(problem, prof) == 0.0


def test_stop_from_motion_at_a_given_time():
    problem = motion_to_rest(WB, 1.0, 0.8)
    T_star = plan_time_optimal(problem).duration
    prof = plan_fixed_time(problem, 2.0 * T_star)
    assert prof.duration == 2.0 * T_star
    x = simulate(WB, problem.x0, prof.input(), times=[prof.duration])[0]
    assert np.max(np.abs(x[1:])) < 1e-13
    assert prof.certified, prof.certificate.message


def test_sampled_arrives_at_the_requested_sample(wb5):
    problem, prof = wb5
    sp = plan_fixed_time_zoh(problem, 5.0, 1000.0, prof)
    assert sp.samples == 5000
    states = simulate_samples(WB, problem.x0, sp.commands, sp.dt)
    assert np.max(np.abs(states[-1] - WB.rest_state(1.0))) < 1e-12
    peak = float(np.max(np.abs(sp.commands)))
    assert peak <= problem.u_max
    # a sampled input is a continuous one: its peak cannot beat the continuous least peak
    assert peak >= prof.extra["bound_used"] * (1.0 - 1e-9)
    assert peak == pytest.approx(prof.extra["bound_used"], rel=1e-3)


def test_sampled_request_below_the_sampled_optimum_uses_the_fewest_samples():
    problem = rest_to_rest(WB, 1.0, 1.0)
    best = plan_time_optimal(problem)
    fewest = plan_time_optimal_zoh(problem, 100.0, best)
    sp = plan_fixed_time_zoh(problem, best.duration, 100.0)
    assert sp.samples == max(round(best.duration * 100.0), fewest.samples)
    assert sp.extra["requested_samples"] == round(best.duration * 100.0)
    assert np.max(np.abs(sp.commands)) <= 1.0


def test_method_through_plan_move():
    base = {"model.b0": 0.5, "model.omega": [math.sqrt(2.0)], "model.zeta": [0.0], "model.b": [1.0]}
    cfg = config_from_parameters({**base, "method": "fixed_time", "arrival_time": 6.0})
    res = plan_move(cfg, rest_to_rest(cfg.model, cfg.u_max, 1.0), rate_hz=200.0)
    out = res.summary()
    assert out["method"] == "fixed_time" and out["duration"] == 6.0 and out["samples"] == 1200
    assert out["bound_used"] < 1.0 and out["added_time_s"] == pytest.approx(6.0 - 4.217866510451, abs=1e-9)
    json.dumps(out)
    with pytest.raises(FlexmotionError) as e:
        plan_move(config_from_parameters({**base, "method": "fixed_time"}), rest_to_rest(cfg.model, 1.0, 1.0))
    assert e.value.parameter == "arrival_time"


def test_cli_refuses_an_early_arrival_with_one_line():
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "flexmotion_ros.cli.main",
            "plan",
            "--config",
            "config/friction_example.yaml",
            "--goal",
            "3.0",
            "--method",
            "fixed_time",
        ],
        capture_output=True,
        text=True,
        check=False,
        cwd=ROOT,
    )
    assert out.returncode == 2 and out.stdout == ""
    assert "arrival_time" in out.stderr and len(out.stderr.strip().splitlines()) == 1


@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    b0=st.floats(0.2, 2.0),
    w1=st.floats(0.5, 3.0),
    ratio=st.floats(1.5, 4.0),
    zeta=st.floats(0.0, 0.1),
    b=st.tuples(st.floats(0.3, 2.0), st.floats(-2.0, -0.3)),
    gamma=st.floats(0.1, 5.0),
    stretch=st.floats(1.0, 3.0),
    two_modes=st.booleans(),
)
def test_random_models_arrive_on_time_at_rest_with_the_lowest_bound(b0, w1, ratio, zeta, b, gamma, stretch, two_modes):
    omega = [w1, w1 * ratio] if two_modes else [w1]
    model = ModalModel(b0=b0, omega=omega, zeta=[zeta] * len(omega), b=list(b[: len(omega)]))
    problem = rest_to_rest(model, 1.0, gamma)
    T_star = plan_time_optimal(problem).duration
    T_req = stretch * T_star
    prof = plan_fixed_time(problem, T_req)
    assert prof.duration == pytest.approx(T_req, rel=1e-15, abs=0.0) or prof.duration == T_req
    bound = prof.extra["bound_used"]
    assert 0.0 < bound <= 1.0 and np.all(np.abs(prof.levels) <= 1.0)
    assert at_rest_error(problem, prof) < 1e-9 * (1.0 + gamma)
    assert prof.certified, prof.certificate.message
    # independent: the time-optimal move at the bound used takes T_req (via the scaling of rest-to-rest)
    scaled = plan_time_optimal(rest_to_rest(model, 1.0, gamma / bound))
    assert scaled.duration == pytest.approx(T_req, rel=1e-8)
    # the exact sampled version at about 200 samples
    rate = 200.0 / T_req
    sp = plan_fixed_time_zoh(problem, T_req, rate, prof)
    assert sp.samples >= round(T_req * rate)
    states = simulate_samples(model, problem.x0, sp.commands, sp.dt)
    scale = 1.0 + np.max(np.abs(states - model.rest_state(gamma)), axis=0)
    assert np.max(np.abs(states[-1] - model.rest_state(gamma)) / scale) < 1e-9
    assert np.max(np.abs(sp.commands)) <= 1.0
