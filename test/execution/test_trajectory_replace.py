"""Preemption in trajectory mode: the replacement a JTC receives mid-move, and how it merges.

The JTC forgets its trajectory when a new one arrives; the replacement
therefore starts at the sample being played and repeats the old commands up
to the splice.  Played by the JTC's rule at jittered ticks, the commands are
the old plan up to the splice and the new one after it, and the exact
propagation ends at rest on the new goal.  The naive replacement (starting at
the splice) is shown to break that.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from flexmotion_ros.core.config import PlannerConfig
from flexmotion_ros.core.interfaces import CommandInterface, setpoints, simulate_servo
from flexmotion_ros.core.interfaces.reference import reference_for
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.model.boundary import state_to_rest
from flexmotion_ros.core.model.builders import crane_acceleration
from flexmotion_ros.core.model.modal_model import ModalModel
from flexmotion_ros.core.simulation.exact import modal_amplitudes, simulate_samples
from flexmotion_ros.execution.jtc import TrajectoryPlayer
from flexmotion_ros.execution.timeline import Segment, predicted_state
from flexmotion_ros.execution.trajectory import (
    ReceiverSettings,
    SampleClock,
    TrajectoryPoint,
    timeline_commands,
    timeline_trajectory,
)

WB = ModalModel(b0=0.5, omega=[math.sqrt(2.0)], zeta=[0.0], b=[1.0])
CRANE = crane_acceleration(2.0).model
RATE = 100.0
CLOCK = SampleClock(origin_ns=1_700_000_000_000_000_000, rate_hz=RATE)
FIRST_GOAL, SECOND_GOAL = 0.5, 0.2


def plan(model: ModalModel, x0, target, start: int) -> Segment:
    cfg = PlannerConfig(model=model, u_max=1.0, rate_hz=RATE)
    s = plan_move(cfg, state_to_rest(model, 1.0, x0, target), RATE).sampled
    return Segment(np.asarray(s.commands, float), np.asarray(s.states, float), start=start)


def play(player: TrajectoryPlayer, iface, k_from: int, k_to: int, deliveries: dict, rng) -> list[float]:
    """One tick per sample interval, at a random phase in it; ``deliveries[k]`` arrives just before tick ``k``."""
    out = []
    for k in range(k_from, k_to):
        if k in deliveries:
            player.receive(deliveries[k])
        tau = int(rng.integers(CLOCK.at(k), CLOCK.at(k + 1)))
        out.append(player.tick(tau).field(iface)[0])
    return out


@pytest.mark.parametrize("iface", [CommandInterface.EFFORT, CommandInterface.VELOCITY], ids=lambda c: c.value)
@pytest.mark.parametrize("settings", [ReceiverSettings(), ReceiverSettings.jazzy(RATE)], ids=["lookahead0", "jazzy"])
def test_replacement_mid_move_plays_old_then_new_exactly(iface, settings):
    model = WB if iface is CommandInterface.EFFORT else CRANE
    start, lead = 10, 6
    a = plan(model, model.rest_state(0.0), FIRST_GOAL, start)
    m = start + a.samples // 3  # the sample being played when the goal arrives
    k_s = m + lead
    b = plan(model, predicted_state([a], k_s), SECOND_GOAL, k_s)
    old, new = [a], [a, b]
    kw = dict(model=model, clock=CLOCK, interface=iface, joint_name="j", settings=settings)
    first = timeline_trajectory(old, start, **kw)
    replacement = timeline_trajectory(new, m, **kw)
    # the replacement's points coincide with the old ones on the shared samples, to the nanosecond
    shared = set(first.point_times_ns()) & set(replacement.point_times_ns())
    assert len(shared) >= lead
    # the whole sequence the timeline sends, and what the servo needs
    sent = timeline_commands(new, start, b.end)
    np.testing.assert_array_equal(sent, np.concatenate([a.commands[: k_s - start], b.commands]))
    ref = reference_for(model, sent, CLOCK.dt, model.rest_state(0.0), iface)
    want = setpoints(ref, iface)
    hold = TrajectoryPoint(time_from_start_ns=0, positions=(0.0,), velocities=(0.0,), effort=(0.0,))
    rng = np.random.default_rng(7)
    tail = 5
    for arrival in (m + 1, k_s - 1):  # any tick after the sample it starts from and before the splice
        player = TrajectoryPlayer(settings, hold)
        got = play(player, iface, start - 2, b.end + tail, {start - 1: first, arrival: replacement}, rng)
        assert got[:2] == [0.0, 0.0]
        if iface is CommandInterface.EFFORT:
            np.testing.assert_array_equal(got[2 : 2 + sent.size], want)  # the commands themselves, bit for bit
        else:
            # a velocity reference is a running sum: the replacement restarts it from the state the timeline
            # predicts at its first sample, so it may differ from the sum from rest in the last bits only
            scale = float(np.max(np.abs(want)))
            np.testing.assert_allclose(got[2 : 2 + sent.size], want, rtol=0.0, atol=8 * np.finfo(float).eps * scale)
        assert got[2 + sent.size :] == [0.0] * tail  # the hold (0 N or 0 m/s), never the last command
        x = end_state(model, iface, got[2 : 2 + sent.size])
        assert abs(x[0] - SECOND_GOAL) < 1e-9 and abs(x[1]) < 1e-9
        assert modal_amplitudes(model, x)[0] < 1e-9


def end_state(model, iface, values):
    if iface is CommandInterface.EFFORT:
        return simulate_samples(model, model.rest_state(0.0), values, CLOCK.dt)[-1]
    return simulate_servo(model, model.rest_state(0.0), values, CLOCK.dt, iface).states[-1]


def test_a_replacement_that_starts_at_the_splice_is_not_exact():
    """The JTC forgets the old trajectory on arrival: before the new first point it holds what it had."""
    start, lead = 10, 6
    a = plan(CRANE, CRANE.rest_state(0.0), FIRST_GOAL, start)
    m = start + a.samples // 3
    k_s = m + lead
    b = plan(CRANE, predicted_state([a], k_s), SECOND_GOAL, k_s)
    settings = ReceiverSettings.jazzy(RATE)
    kw = dict(model=CRANE, clock=CLOCK, interface="velocity", joint_name="j", settings=settings)
    naive = timeline_trajectory([a, b], k_s, **kw)
    hold = TrajectoryPoint(time_from_start_ns=0, positions=(0.0,), velocities=(0.0,))
    player = TrajectoryPlayer(settings, hold)
    deliveries = {start: timeline_trajectory([a], start, **kw), m + 1: naive}
    got = play(player, "velocity", start, b.end, deliveries, np.random.default_rng(8))
    sent = timeline_commands([a, b], start, b.end)
    want = setpoints(reference_for(CRANE, sent, CLOCK.dt, CRANE.rest_state(0.0), "velocity"), "velocity")
    gap = got[m + 1 - start : k_s - start]
    assert gap == [got[m - start]] * len(gap)  # the last command, held while the plan accelerates
    assert not np.array_equal(got, want)
    x = simulate_servo(CRANE, CRANE.rest_state(0.0), got, CLOCK.dt, "velocity").states[-1]
    assert abs(x[0] - SECOND_GOAL) > 1e-6 * SECOND_GOAL or modal_amplitudes(CRANE, x)[0] > 1e-6 * SECOND_GOAL


def test_points_carry_the_timelines_predicted_states():
    """The positions and velocities sent are the planner's own predicted states (independent expm)."""
    a = plan(CRANE, CRANE.rest_state(0.0), FIRST_GOAL, 0)
    k_s = a.samples // 2
    b = plan(CRANE, predicted_state([a], k_s), SECOND_GOAL, k_s)
    traj = timeline_trajectory(
        [a, b], 3, model=CRANE, clock=CLOCK, interface="position", joint_name="cart", settings=ReceiverSettings()
    )
    for j, pt in enumerate(traj.points[:-1]):
        x = predicted_state([a, b], 3 + j)
        assert abs(pt.positions[0] - x[0]) < 1e-12 and abs(pt.velocities[0] - x[1]) < 1e-12
    assert traj.points[-1].positions[0] == traj.points[-2].positions[0] and traj.points[-1].velocities == (0.0,)
    assert timeline_trajectory([], 0, model=CRANE, clock=CLOCK, interface="position", joint_name="cart") is None
