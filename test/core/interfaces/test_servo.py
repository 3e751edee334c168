"""The servo simulation: exact against SciPy's own first-order-hold discretisation, and lockstep loops at rest."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import lsim

from flexmotion_ros.core.config import PlannerConfig
from flexmotion_ros.core.errors import ConfigError
from flexmotion_ros.core.interfaces import (
    CommandInterface,
    Servo,
    hold_setpoint,
    reference_for,
    setpoints,
    simulate_servo,
)
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.model.boundary import rest_to_rest
from flexmotion_ros.core.model.builders import crane_acceleration
from flexmotion_ros.core.model.modal_model import ModalModel
from flexmotion_ros.core.simulation.exact import modal_amplitudes, simulate_samples

CRANE = crane_acceleration(2.0, zeta=0.01).model
WB = ModalModel(b0=0.5, omega=[math.sqrt(2.0)], zeta=[0.0], b=[1.0])
RATE = 200.0
GOAL = 1.0


@pytest.fixture(scope="module")
def crane_plan() -> np.ndarray:
    cfg = PlannerConfig(model=CRANE, u_max=0.5, rate_hz=RATE)
    return np.asarray(plan_move(cfg, rest_to_rest(CRANE, 0.5, GOAL), RATE).sampled.commands, float)


def test_ideal_servo_follows_the_plan_exactly(crane_plan):
    ref = reference_for(CRANE, crane_plan, 1.0 / RATE, CRANE.rest_state(0.0), "velocity")
    plan_states = simulate_samples(CRANE, CRANE.rest_state(0.0), crane_plan, 1.0 / RATE)
    for iface in ("velocity", "position"):
        run = simulate_servo(CRANE, CRANE.rest_state(0.0), setpoints(ref, iface), 1.0 / RATE, iface)
        assert np.max(np.abs(run.states - plan_states)) < 1e-11, iface
        assert np.max(np.abs(run.accelerations - crane_plan)) < 1e-6, (
            iface
        )  # rebuilt from the setpoints (rounding / dt^2)
        np.testing.assert_allclose(run.reference_velocities, ref.velocities, atol=1e-12)


@pytest.mark.parametrize("bandwidth", [3.0, 40.0, 700.0])
def test_first_order_servo_is_scipys_first_order_hold_response(crane_plan, bandwidth):
    """Velocity loop ``a = w (r_v - v)`` with the setpoints linearly interpolated: ``scipy.signal.lsim`` (FOH)."""
    dt = 1.0 / RATE
    ref = reference_for(CRANE, crane_plan, dt, CRANE.rest_state(0.0), "velocity")
    values = np.concatenate([setpoints(ref, "velocity"), np.zeros(100)])
    run = simulate_servo(CRANE, CRANE.rest_state(0.0), values, dt, "velocity", Servo(bandwidth=bandwidth))
    A, B = CRANE.A(), CRANE.B() / CRANE.b0
    Acl = A - bandwidth * np.outer(B, np.eye(CRANE.n_states)[1])
    r_v = np.concatenate([[0.0], values])  # the reference velocity at every sample instant, linear in between
    t = dt * np.arange(r_v.size)
    _, _, x = lsim((Acl, bandwidth * B[:, None], np.eye(CRANE.n_states), np.zeros((CRANE.n_states, 1))), r_v, t)
    scale = np.max(np.abs(x), axis=0)
    assert np.max(np.abs(run.states - x) / scale) < 1e-9
    # the position servo is the same equation from its tied start (from rest: the same run)
    pos = simulate_servo(
        CRANE,
        CRANE.rest_state(0.0),
        np.concatenate([setpoints(ref, "position"), np.full(100, ref.positions[-1])]),
        dt,
        "position",
        Servo(bandwidth=bandwidth),
    )
    assert np.max(np.abs(pos.states - run.states) / scale) < 1e-9
    # and keeps v = w (r_p - p) along the way
    tie = bandwidth * (pos.reference_positions - pos.states[:, 0]) - pos.states[:, 1]
    assert np.max(np.abs(tie)) < 1e-9 * scale[1] * max(1.0, bandwidth * dt)


def test_a_first_order_servo_costs_time_not_residual(crane_plan):
    """At the planned arrival the lag leaves an error that shrinks with the bandwidth; once the servo has
    settled, none is left: the joint's acceleration is the plan's filtered by ``w / (s + w)``, and an LTI
    filter keeps the zeros of the plan's transform at the mode's poles (zero residual vibration)."""
    dt = 1.0 / RATE
    ref = reference_for(CRANE, crane_plan, dt, CRANE.rest_state(0.0), "velocity")
    values = np.concatenate([setpoints(ref, "velocity"), np.zeros(4000)])
    at_arrival, settled = [], []
    for w in (2.0, 20.0, 200.0, 2000.0):
        states = simulate_servo(CRANE, CRANE.rest_state(0.0), values, dt, "velocity", Servo(bandwidth=w)).states
        at_arrival.append(modal_amplitudes(CRANE, states[crane_plan.size])[0] / GOAL)
        settled.append(max(modal_amplitudes(CRANE, states[-1])[0], abs(states[-1, 0] - GOAL)) / GOAL)
    assert all(a > b for a, b in zip(at_arrival, at_arrival[1:])), at_arrival
    assert at_arrival[0] > 1e-2 and at_arrival[-1] < 1e-3
    assert max(settled) < 1e-9, settled


def test_servo_settings_refused():
    for bad in (0.0, -3.0, math.nan, "fast"):
        with pytest.raises(ConfigError, match="plant.servo_bandwidth"):
            Servo(bandwidth=bad)
    assert Servo().ideal and not Servo(bandwidth=10).ideal


@pytest.mark.parametrize("iface", list(CommandInterface), ids=lambda c: c.value)
def test_lockstep_loop_ends_at_rest_with_the_ideal_servo(iface, crane_plan):
    """Plan, send one setpoint per sample, simulate the plant through its servo sample by sample, then hold."""
    if iface is CommandInterface.EFFORT:
        cfg = PlannerConfig(model=WB, u_max=1.0, rate_hz=RATE)
        model, u = WB, np.asarray(plan_move(cfg, rest_to_rest(WB, 1.0, GOAL), RATE).sampled.commands, float)
    else:
        model, u = CRANE, crane_plan
    dt = 1.0 / RATE
    ref = reference_for(model, u, dt, model.rest_state(0.0), iface)
    values = np.concatenate([setpoints(ref, iface), np.full(200, hold_setpoint(ref, iface))])
    x = model.rest_state(0.0)
    states = [x]
    for value in values:  # lockstep: the plant advances one sample per setpoint received, from its own state
        x = simulate_servo(model, x, [value], dt, iface).states[-1]
        states.append(x)
    run = simulate_servo(model, model.rest_state(0.0), values, dt, iface)
    assert np.max(np.abs(np.array(states) - run.states)) < 1e-9 * GOAL  # the ideal servo needs no memory
    after = run.states[u.size :]
    err = np.max(np.abs(after[:, 0] - GOAL)) / GOAL
    vel = np.max(np.abs(after[:, 1])) / GOAL
    residual = np.max(modal_amplitudes(model, after)) / GOAL
    assert err < 1e-6 and vel < 1e-6 and residual < 1e-6, (err, vel, residual)
