"""The simulated actuator (issue 14): disturbances, servos, trajectories played and rewound; exact.

Independent checks: piecewise-constant inputs through :func:`core.simulation.exact.final_state`
(one matrix exponential per piece, with the impulse applied by hand between
two pieces), the servo through :func:`core.interfaces.servo.simulate_servo`.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexmotion_ros.core.errors import ConfigError
from flexmotion_ros.core.interfaces.servo import Servo, simulate_servo
from flexmotion_ros.core.model.modal_model import ModalModel
from flexmotion_ros.core.simulation.exact import PiecewiseConstant, final_state
from flexmotion_ros.execution.actuator import Actuator, TrajectoryPlayback
from flexmotion_ros.execution.actuator_settings import (
    Disturbance,
    DisturbanceKind,
    disturbance_settings,
    servo_settings,
)
from flexmotion_ros.execution.timeline import Segment
from flexmotion_ros.execution.trajectory import NS, SampleClock, timeline_trajectory

WB = ModalModel(b0=0.5, omega=[2**0.5], zeta=[0.02], b=[1.0])
DT_NS = 10_000_000  # 100 Hz
RNG = np.random.default_rng(7)
U = RNG.uniform(-1.0, 1.0, 60)


def lockstep(act: Actuator, values) -> np.ndarray:
    for v in values:
        t = act.t_ns + DT_NS
        act.set(v, t)
        act.advance_to(t)
    return act.x


def test_an_impulse_mid_sample_is_applied_exactly_at_its_instant():
    d = Disturbance(kind=DisturbanceKind.IMPULSE, time_s=0.2345, value=0.3)
    x = lockstep(Actuator(WB, WB.rest_state(0.0), "effort", disturbance=d), U)
    # independently: the sequence up to 0.2345 s, the kick B J, the rest (from the first non-zero force, t = 0)
    t = np.arange(U.size + 1) * 0.01
    pre = PiecewiseConstant(np.append(t[t < 0.2345], 0.2345), U[: np.sum(t < 0.2345)])
    x_hit = final_state(WB, WB.rest_state(0.0), pre) + 0.3 * WB.B()
    rest = np.concatenate([[0.2345], t[t > 0.2345]]) - 0.2345
    post = PiecewiseConstant(rest, U[np.sum(t < 0.2345) - 1 :])
    np.testing.assert_allclose(x, final_state(WB, x_hit, post), rtol=0, atol=1e-12)


def test_a_step_acts_from_its_instant_and_the_clock_starts_with_the_first_move():
    d = Disturbance(kind=DisturbanceKind.STEP, time_s=0.105, value=-0.2)
    values = np.concatenate([np.zeros(7), U])  # idle holds first: the disturbance's clock has not started
    x = lockstep(Actuator(WB, WB.rest_state(0.0), "effort", disturbance=d), values)
    t = 0.07 + np.arange(U.size + 1) * 0.01
    bounds = np.sort(np.append(t, 0.07 + 0.105))
    forces = [U[min(int(np.searchsorted(t, lo, side="right")) - 1, U.size - 1)] for lo in bounds[:-1]]
    forces = [f + (-0.2 if lo >= 0.175 - 1e-12 else 0.0) for f, lo in zip(forces, bounds[:-1])]
    expected = final_state(WB, WB.rest_state(0.0), PiecewiseConstant(bounds - bounds[0], np.array(forces)))
    np.testing.assert_allclose(x, expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("iface", ["velocity", "position"])
@pytest.mark.parametrize("bandwidth", [None, 40.0])
def test_a_servo_joint_in_lockstep_is_the_core_servo(iface, bandwidth):
    model = ModalModel(b0=1.0, omega=[3.0], zeta=[0.0], b=[-1.0])
    values = np.cumsum(RNG.uniform(-0.01, 0.01, 40)) + (0.3 if iface == "position" else 0.0)
    x0 = model.rest_state(0.3)
    act = Actuator(model, x0, iface, servo=Servo(bandwidth=bandwidth))
    x = lockstep(act, values)
    ref = simulate_servo(model, x0, values, 0.01, iface, Servo(bandwidth=bandwidth))
    np.testing.assert_allclose(x, ref.states[-1], rtol=0, atol=1e-12)


def test_settings_refuse_what_they_cannot_simulate():
    with pytest.raises(ConfigError, match="plant.disturbance.type"):
        disturbance_settings({"plant.disturbance.type": "impulse", "plant.disturbance.value": 1.0}, "velocity")
    with pytest.raises(ConfigError, match="plant.disturbance.type"):
        disturbance_settings({"plant.disturbance.type": "kick"}, "effort")
    with pytest.raises(ConfigError, match="plant.disturbance.time_s"):
        disturbance_settings({"plant.disturbance.time_s": -1.0}, "effort")
    with pytest.raises(ConfigError, match="plant.servo_bandwidth"):
        servo_settings({"plant.servo_bandwidth": -3.0})


def test_a_lockstep_playback_rewinds_for_a_replacement_and_ends_where_the_spliced_timeline_does():
    clock = SampleClock(origin_ns=5 * NS, rate_hz=100.0)
    first = Segment(U.copy(), np.zeros((U.size + 1, 4)), start=10)
    first.states[:] = WB.rest_state(0.0)  # the states are only used at the start sample here
    other = -0.5 * U[:30]
    second = Segment(other, np.zeros((31, 4)), start=30)
    t1 = timeline_trajectory([first], 10, model=WB, clock=clock, interface="effort", joint_name="j")
    # the replacement, published from the sample being played (25), repeats the first until the splice (30)
    second.states[:] = 0.0
    t2 = timeline_trajectory([first, second], 25, model=WB, clock=clock, interface="effort", joint_name="j")
    act = Actuator(WB, WB.rest_state(0.0), "effort", t_ns=clock.at(0))
    pb = TrajectoryPlayback(act, "j")
    samples: list[int] = []
    pb.receive_eager(t1, clock.at(0), on_sample=samples.append)
    assert act.t_ns == clock.at(10 + U.size + 2)  # played to its last point at once, and one period of the hold
    pb.receive_eager(t2, clock.at(20))
    assert pb.rewinds == 1
    sent = np.concatenate([U[:20], other])  # samples 10..29 of the first, then the second from 30
    expected = final_state(
        WB, WB.rest_state(0.0), PiecewiseConstant(np.arange(sent.size + 3) * 0.01, np.append(sent, [0.0, 0.0]))
    )
    np.testing.assert_allclose(act.x, expected, rtol=0, atol=1e-12)
    assert len(samples) == U.size + 1  # one state per sample played
