"""The planner's output (issue 14): setpoints of each command interface, trajectories, holds; on a fake clock.

Independent checks: the setpoints against :func:`core.interfaces.reference.reference_for`
(the exact reference of the plan), the trajectories against the JTC's sampling
rule re-implemented in :mod:`execution.jtc` driving the exact actuator.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexmotion_ros.core.config import PlannerConfig
from flexmotion_ros.core.errors import ConfigError
from flexmotion_ros.core.interfaces.reference import hold_setpoint, reference_for, setpoints
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.model.boundary import state_to_rest
from flexmotion_ros.core.model.modal_model import ModalModel
from flexmotion_ros.core.simulation.exact import modal_amplitudes
from flexmotion_ros.execution.actuator import Actuator, TrajectoryPlayback
from flexmotion_ros.execution.output import OutputStream, SetpointEncoder
from flexmotion_ros.execution.output_config import output_settings
from flexmotion_ros.execution.timeline import Segment, predicted_state
from flexmotion_ros.execution.trajectory import NS

#: An acceleration-input crane (c = 0, b0 = 1): fits every command interface.
CRANE = ModalModel(b0=1.0, omega=[3.13], zeta=[0.0], b=[-1.0])
RATE = 100.0
CFG = PlannerConfig(model=CRANE, u_max=2.0, rate_hz=RATE)


@pytest.fixture(scope="module")
def move() -> Segment:
    s = plan_move(CFG, state_to_rest(CRANE, 2.0, CRANE.rest_state(0.25), 1.25), RATE).sampled
    return Segment(np.asarray(s.commands, float), np.asarray(s.states, float))


class FakeClock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t

    def sleep(self, s: float) -> None:
        self.t += s


def stream(settings: dict, sent: list, published: list, clock: FakeClock) -> OutputStream:
    return OutputStream(
        RATE,
        sent.append,
        False,
        settings=output_settings(settings, CRANE),
        model=CRANE,
        joint_name="cart",
        publish_trajectory=published.append,
        ros_ns=lambda t: round(t * NS),
        clock=clock,
        sleep=clock.sleep,
    )


def run(s: OutputStream, n: int) -> None:
    for _ in range(n):
        s.step()


@pytest.mark.parametrize("iface", ["effort", "velocity", "position"])
def test_the_stream_sends_the_exact_reference_and_the_hold_of_each_interface(move, iface):
    sent: list = []
    s = stream({"command_interface": iface}, sent, [], FakeClock())
    s.start_now(Segment(move.commands.copy(), move.states.copy()))
    run(s, move.samples + 3)
    ref = reference_for(CRANE, move.commands, 1.0 / RATE, move.states[0], iface)
    np.testing.assert_array_equal(sent[:-1], setpoints(ref, iface))  # the same recursion: bit for bit
    assert sent[-1] == pytest.approx(hold_setpoint(ref, iface), abs=1e-12) and len(sent) == move.samples + 1
    if iface == "position":
        assert sent[-1] == pytest.approx(1.25, abs=1e-12)  # the hold of a position joint: where it ended, not 0


@pytest.mark.parametrize("iface", ["effort", "velocity", "position"])
def test_a_stop_mid_move_ends_with_the_hold_of_the_interface(move, iface):
    sent: list = []
    s = stream({"command_interface": iface}, sent, [], FakeClock())
    s.start_now(Segment(move.commands.copy(), move.states.copy()))
    run(s, 40)
    halt = s.stop("test")
    ref = reference_for(CRANE, move.commands, 1.0 / RATE, move.states[0], iface)
    hold = {"effort": 0.0, "velocity": 0.0, "position": ref.positions[40]}[iface]
    assert halt.interrupted and sent[-1] == pytest.approx(hold, abs=1e-12)


def test_encoder_refuses_a_viscous_model_for_a_servo_joint():
    with pytest.raises(Exception, match="model.c"):
        SetpointEncoder(CRANE.with_changes(c=-0.1), 0.01, "velocity")
    with pytest.raises(ConfigError, match="model.c"):
        output_settings({"command_interface": "position"}, CRANE.with_changes(c=-0.1))
    with pytest.raises(ConfigError, match="trajectory.interpolation"):
        output_settings({"output": "trajectory", "trajectory.interpolation": "splines"}, CRANE)
    with pytest.raises(ConfigError, match="output"):
        output_settings({"output": "trajectories"}, CRANE)


def play(trajectories: list, iface: str, x0, until_ns: int) -> np.ndarray:
    """The receiving end: each trajectory installed at its stamp's sample (or now), played exactly."""
    act = Actuator(CRANE, x0, iface, t_ns=trajectories[0][0] - 10**9)
    pb = TrajectoryPlayback(act, "cart")
    for at, traj in trajectories:
        pb.install(traj, at)
    pb.play_to(until_ns)
    return act.x


@pytest.mark.parametrize("iface", ["effort", "position"])
def test_trajectory_mode_a_delayed_start_a_replacement_from_the_sample_played_and_the_hold(move, iface):
    clock, published, sent = FakeClock(), [], []
    s = stream(
        {"output": "trajectory", "command_interface": iface, "trajectory.start_delay_s": 0.05}, sent, published, clock
    )
    seg = Segment(move.commands.copy(), move.states.copy())
    k0 = s.start_now(seg)
    assert sent == [] and k0 == 5  # trajectory mode sends nothing per sample; the move starts 5 samples ahead
    first = published[0]
    assert first.stamp_ns == s.sample_clock.at(k0) == round(s.time_of(k0) * NS)
    run(s, 60)
    # a too-close splice is refused (the trajectory could not reach the receiver); one far enough goes out
    stop = plan_move(CFG, state_to_rest(CRANE, 2.0, s.predicted_state(70), None), RATE).sampled
    assert not s.splice(Segment(np.asarray(stop.commands, float), np.asarray(stop.states, float)), 62)
    assert s.splice(Segment(np.asarray(stop.commands, float), np.asarray(stop.states, float)), 70)
    second = published[1]
    played = s.snapshot()[0] - 1  # the sample being played when it was published
    assert second.stamp_ns == s.sample_clock.at(played)
    j = played - k0
    # the same commands on the same instants until the splice (positions recomputed from the predicted state: 1 ulp)
    old = np.array([p.field(iface) for p in first.points[j + 1 : j + 11]])
    np.testing.assert_allclose([p.field(iface) for p in second.points[1:11]], old, rtol=0, atol=1e-12)
    assert [p.time_from_start_ns + second.stamp_ns for p in second.points[1:11]] == [
        p.time_from_start_ns + first.stamp_ns for p in first.points[j + 1 : j + 11]
    ]
    # played exactly: the receiver installs the replacement anywhere before the splice instant
    end = s.snapshot()[1][-1].end
    for at in (s.sample_clock.at(played) + 1234, s.sample_clock.at(69) + 7):
        x = play([(first.stamp_ns - 10**7, first), (at, second)], iface, move.states[0], s.sample_clock.at(end + 5))
        np.testing.assert_allclose(x, stop.states[-1], atol=1e-9)
        assert np.all(modal_amplitudes(CRANE, x) < 1e-9) and abs(x[1]) < 1e-9
    # an ending: the hold trajectory, now, where the reference is
    run(s, 10)
    k, timeline = s.snapshot()
    s.stop("test")
    hold = published[-1]
    assert hold.stamp_ns == 0 and len(hold.points) == 1 and hold.points[0].time_from_start_ns == 0
    assert hold.points[0].positions[0] == predicted_state(timeline, k - 1)[0]
    assert hold.points[0].velocities == (0.0,) and s.holds_published == 1
    s.stop("again")
    assert s.holds_published == 1  # one hold per ending
