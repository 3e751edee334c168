"""A ZOH plan encoded as a joint trajectory, played by the JTC's sampling rule at jittered instants.

The check of "exact" is independent of the encoding: the values the rule
gives are compared bit for bit with the planned sequence, and the sequence
recovered from them is propagated by matrix exponentials
(:mod:`flexmotion_ros.core.simulation.exact`, or the servo's augmented
exponential for velocity / position joints) to the target's rest.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import settings as hypothesis_settings
from hypothesis import strategies as st

from flexmotion_ros.core.config import PlannerConfig
from flexmotion_ros.core.errors import ConfigError
from flexmotion_ros.core.interfaces import CommandInterface, reference_for, setpoints, simulate_servo
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.model.boundary import rest_to_rest
from flexmotion_ros.core.model.builders import crane_acceleration
from flexmotion_ros.core.model.modal_model import ModalModel
from flexmotion_ros.core.simulation.exact import PiecewiseConstant, final_state, modal_amplitudes, simulate_samples
from flexmotion_ros.execution.jtc import TrajectoryPlayer, held_pieces, sample, started
from flexmotion_ros.execution.trajectory import (
    NS,
    Interpolation,
    ReceiverSettings,
    SampleClock,
    TrajectoryPoint,
    encode,
)

WB = ModalModel(b0=0.5, omega=[math.sqrt(2.0)], zeta=[0.0], b=[1.0])
CRANE = crane_acceleration(2.0).model  # cart acceleration in (m/s^2), payload offset from the cart as the mode
RATE = 100.0
ORIGIN_NS = 1_764_000_000_123_456_789  # a wall-clock-like origin: integer ns arithmetic must stay exact
GOAL = 0.5


def planned(model: ModalModel, u_max: float, rate: float = RATE, goal: float = GOAL) -> np.ndarray:
    cfg = PlannerConfig(model=model, u_max=u_max, rate_hz=rate)
    return np.asarray(plan_move(cfg, rest_to_rest(model, u_max, goal), rate).sampled.commands, float)


@pytest.fixture(scope="module")
def wb_commands() -> np.ndarray:
    return planned(WB, 1.0)


@pytest.fixture(scope="module")
def crane_commands() -> np.ndarray:
    return planned(CRANE, 1.0)


def model_and_commands(iface, wb_commands, crane_commands):
    return (WB, wb_commands) if iface is CommandInterface.EFFORT else (CRANE, crane_commands)


def jittered_instants(clock: SampleClock, k: int, rng, n: int = 3) -> list[int]:
    """``n`` instants (ns) in ``[t_k, t_{k+1})``, always including both ends' neighbours."""
    lo, hi = clock.at(k), clock.at(k + 1)
    return sorted({lo, hi - 1, *(int(x) for x in rng.integers(lo, hi, n))})


SETTINGS = [
    ReceiverSettings(),  # Humble's rule, or the plant node: no look-ahead
    ReceiverSettings.jazzy(RATE),  # Jazzy JTC at the plan's rate
    ReceiverSettings.jazzy(1000.0),  # Jazzy JTC ticking 10x faster than the plan
]


@pytest.mark.parametrize("settings", SETTINGS, ids=["lookahead0", "jazzy100Hz", "jazzy1kHz"])
@pytest.mark.parametrize("iface", list(CommandInterface), ids=lambda c: c.value)
def test_none_plays_the_zoh_sequence_exactly_at_jittered_instants(settings, iface, wb_commands, crane_commands):
    model, u = model_and_commands(iface, wb_commands, crane_commands)
    clock = SampleClock(origin_ns=ORIGIN_NS, rate_hz=RATE)
    first = 37
    ref = reference_for(model, u, clock.dt, model.rest_state(0.0), iface)
    traj = encode(ref, interface=iface, joint_name="cart", clock=clock, first_sample=first, settings=settings)
    assert traj.stamp_ns == clock.at(first) and len(traj.points) == u.size + 2
    assert np.all(np.diff(traj.point_times_ns()) > 0)  # the JTC refuses non-increasing times
    assert traj.points[-1].velocities == (0.0,) or abs(traj.points[-1].velocities[0]) < 1e-12
    want = setpoints(ref, iface)
    hold = TrajectoryPoint(time_from_start_ns=0, positions=(0.0,), velocities=(0.0,), effort=(0.0,))
    rng = np.random.default_rng(1)
    got = []
    for k in range(u.size):
        values = {
            sample(traj, tau + settings.lookahead_ns, Interpolation.NONE, hold).field(iface)[0]
            for tau in jittered_instants(clock, first + k, rng)
        }
        assert values == {want[k]}, f"sample {k}: {values} != {want[k]}"  # bit for bit, anywhere in the interval
        got.append(values.pop())
    # before the start: the point before; from the end on, for ever: the hold, never the last command
    assert sample(traj, clock.at(first) - 1 + settings.lookahead_ns, "none", hold) is hold
    for tau in (clock.at(first + u.size), clock.at(first + u.size) + 10 * NS):
        end = sample(traj, tau + settings.lookahead_ns, "none", hold)
        assert end.field(iface)[0] == (ref.positions[-1] if iface is CommandInterface.POSITION else 0.0)
    # the recovered sequence, propagated exactly, ends at rest on the goal
    if iface is CommandInterface.EFFORT:
        x = simulate_samples(model, model.rest_state(0.0), got, clock.dt)[-1]
    else:
        x = simulate_servo(model, model.rest_state(0.0), got, clock.dt, iface).states[-1]
    assert abs(x[0] - GOAL) < 1e-9 * GOAL and abs(x[1]) < 1e-9 * GOAL
    assert float(np.max(modal_amplitudes(model, x))) < 1e-9 * GOAL


def test_splines_reproduce_the_exact_piecewise_quadratic_at_any_instant(crane_commands):
    """Positions + velocities only: the JTC's cubic is the plan's quadratic (to rounding); with accelerations it is not."""
    clock = SampleClock(origin_ns=ORIGIN_NS, rate_hz=RATE)
    ref = reference_for(CRANE, crane_commands, clock.dt, CRANE.rest_state(0.0), "velocity")
    settings = ReceiverSettings.jazzy(1000.0, Interpolation.SPLINES)
    traj = encode(ref, interface="velocity", joint_name="cart", clock=clock, settings=settings)
    assert traj.points[1].accelerations == ()
    assert traj.point_times_ns()[0] == clock.at(0)  # no shift: the command at tau is the reference at tau + lookahead
    rng = np.random.default_rng(2)
    taus = rng.integers(clock.at(0), clock.at(ref.samples), 400)
    worst_p = worst_v = worst_a = 0.0
    for tau in taus:
        pt = sample(traj, int(tau), Interpolation.SPLINES)
        t = (int(tau) - clock.at(0)) / NS
        k = clock.index(int(tau))
        worst_p = max(worst_p, abs(pt.positions[0] - ref.position_at(t)))
        worst_v = max(worst_v, abs(pt.velocities[0] - ref.velocity_at(t)))
        worst_a = max(worst_a, abs(pt.accelerations[0] - ref.accelerations[k]))
    assert worst_p < 1e-12 and worst_v < 1e-9 and worst_a < 1e-6, (worst_p, worst_v, worst_a)
    # the same points with accelerations: the quintic assumes a continuous acceleration and misses
    quintic = encode(ref, interface="velocity", joint_name="cart", clock=clock, settings=ReceiverSettings())
    quintic = type(quintic)(joint_names=quintic.joint_names, stamp_ns=clock.at(0), points=quintic.points)
    miss = max(
        abs(
            sample(quintic, int(tau), Interpolation.SPLINES).velocities[0]
            - ref.velocity_at((int(tau) - clock.at(0)) / NS)
        )
        for tau in taus
    )
    assert miss > 1e-4


def test_effort_with_splines_is_refused(wb_commands):
    clock = SampleClock(origin_ns=0, rate_hz=RATE)
    ref = reference_for(WB, wb_commands, clock.dt, WB.rest_state(0.0))
    with pytest.raises(ConfigError, match="interpolation_method"):
        encode(ref, interface="effort", joint_name="j", clock=clock, settings=ReceiverSettings(interpolation="splines"))


@pytest.mark.parametrize("rate", [300.0, 1000.0, 333.0, 7.0])
def test_sample_clock_index_and_instants_agree(rate):
    clock = SampleClock(origin_ns=ORIGIN_NS, rate_hz=rate)
    for k in range(-5, 2000, 7):
        t = clock.at(k)
        assert clock.index(t) == k and clock.index(t - 1) == k - 1 and clock.index(clock.at(k + 1) - 1) == k
        assert abs((clock.at(k + 1) - t) - NS / rate) <= 1.0


def test_stamp_zero_starts_at_the_first_tick(wb_commands):
    clock = SampleClock(origin_ns=0, rate_hz=RATE)
    ref = reference_for(WB, wb_commands, clock.dt, WB.rest_state(0.0))
    traj = encode(ref, interface="effort", joint_name="j", clock=clock)
    assert traj.stamp_ns == 0
    tick0 = 5 * NS + 12345
    player = TrajectoryPlayer(
        ReceiverSettings(), TrajectoryPoint(time_from_start_ns=0, positions=(0.0,), effort=(0.0,))
    )
    player.receive(traj)
    out = [player.tick(tick0 + round(k * NS / RATE)).effort[0] for k in range(ref.samples + 3)]
    assert player.current.stamp_ns == tick0 and started(player.current, 99) is player.current
    np.testing.assert_array_equal(out, [*ref.commands, 0.0, 0.0, 0.0])


def test_held_pieces_change_at_the_sample_instants_not_at_the_plant_ticks(wb_commands):
    """The plant integrates each piece exactly: the same final state whatever its ticks."""
    clock = SampleClock(origin_ns=ORIGIN_NS, rate_hz=RATE)
    settings = ReceiverSettings.jazzy(RATE)
    ref = reference_for(WB, wb_commands, clock.dt, WB.rest_state(0.0))
    traj = encode(ref, interface="effort", joint_name="j", clock=clock, settings=settings)
    hold = TrajectoryPoint(time_from_start_ns=0, positions=(0.0,), effort=(0.0,))
    rng = np.random.default_rng(3)
    end = clock.at(ref.samples + 20)
    ticks = np.unique(np.concatenate([[clock.at(-3)], rng.integers(clock.at(-3), end, 150), [end]]))
    breaks, levels = [], []
    for a, b in zip(ticks[:-1], ticks[1:]):
        for piece in held_pieces(traj, int(a), int(b), settings, hold):
            breaks.append(piece.start_ns)
            levels.append(piece.point.effort[0])
    # the pieces tile the window, and merging equal neighbours leaves the sample grid and the planned values
    times = np.array([*breaks, int(ticks[-1])])
    change = np.flatnonzero(np.diff(levels) != 0) + 1
    assert set(times[change]) <= {clock.at(k) for k in range(ref.samples + 1)}
    # exact integration over the pieces (phi(h) per piece) = the planned ZOH from rest
    t_rel = (times - clock.at(-3)) / NS
    x = final_state(WB, WB.rest_state(0.0), PiecewiseConstant(t_rel, np.array(levels)))
    assert abs(x[0] - GOAL) < 1e-9 and abs(x[1]) < 1e-9 and modal_amplitudes(WB, x)[0] < 1e-9


@pytest.mark.parametrize("iface", [CommandInterface.VELOCITY, CommandInterface.POSITION], ids=lambda c: c.value)
def test_a_plant_stepping_by_its_own_jittered_clock_plays_the_plan_exactly(iface, crane_commands):
    """The plant node's loop: held pieces between its ticks, the servo stepped over each piece exactly."""
    from flexmotion_ros.core.interfaces import Servo, servo_advance, servo_setpoint, servo_start

    clock = SampleClock(origin_ns=ORIGIN_NS, rate_hz=RATE)
    settings = ReceiverSettings.jazzy(1000.0)
    ref = reference_for(CRANE, crane_commands, clock.dt, CRANE.rest_state(0.0), iface)
    traj = encode(ref, interface=iface, joint_name="cart", clock=clock, settings=settings)
    hold = TrajectoryPoint(time_from_start_ns=0, positions=(0.0,), velocities=(0.0,))
    rng = np.random.default_rng(9)
    end = clock.at(ref.samples + 30)
    ticks = np.unique(np.concatenate([[clock.at(-2)], rng.integers(clock.at(-2), end, 300), [end]]))
    for servo in (Servo(), Servo(bandwidth=50.0)):
        state = servo_start(CRANE, CRANE.rest_state(0.0), iface, servo)
        started = False
        for a, b in zip(ticks[:-1], ticks[1:]):
            for piece in held_pieces(traj, int(a), int(b), settings, hold):
                if piece.begins or not started:  # a new setpoint, due at the end of its whole piece
                    started = True
                    due = piece.due_ns if piece.due_ns is not None else piece.start_ns + round(NS / RATE)
                    state = servo_setpoint(state, piece.point.field(iface)[0], (due - piece.start_ns) / NS, iface)
                arrive = piece.end_ns == piece.due_ns
                state = servo_advance(CRANE, state, (piece.end_ns - piece.start_ns) / NS, iface, servo, arrive)
        values = np.concatenate(
            [
                np.zeros(2),
                setpoints(ref, iface),
                np.full(30, ref.positions[-1] if iface is CommandInterface.POSITION else 0.0),
            ]
        )
        want = simulate_servo(CRANE, CRANE.rest_state(0.0), values, clock.dt, iface, servo).states[-1]
        np.testing.assert_allclose(state.x, want, rtol=0, atol=1e-9)
        if servo.ideal:
            assert abs(state.x[0] - GOAL) < 1e-9 and modal_amplitudes(CRANE, state.x)[0] < 1e-9


@hypothesis_settings(max_examples=40)
@given(
    rate=st.floats(5.0, 2000.0),
    lookahead_periods=st.floats(0.0, 3.0),
    origin=st.integers(-(10**18), 10**18),
    first=st.integers(-1000, 1000),
    commands=st.lists(st.floats(-1.0, 1.0), min_size=1, max_size=40),
    phase=st.floats(0.0, 1.0, exclude_max=True),
)
def test_property_any_rate_lookahead_and_origin_play_the_sequence_exactly(
    rate, lookahead_periods, origin, first, commands, phase
):
    clock = SampleClock(origin_ns=origin, rate_hz=rate)
    settings = ReceiverSettings(lookahead_ns=int(lookahead_periods * NS / rate))
    ref = reference_for(WB, commands, clock.dt, WB.rest_state(0.0))
    traj = encode(ref, interface="effort", joint_name="j", clock=clock, first_sample=first, settings=settings)
    hold = TrajectoryPoint(time_from_start_ns=0, positions=(0.0,), effort=(0.0,))
    for k, u in enumerate(commands):
        lo, hi = clock.at(first + k), clock.at(first + k + 1)
        for tau in (lo, hi - 1, lo + int(phase * (hi - lo))):
            assert sample(traj, tau + settings.lookahead_ns, "none", hold).effort == (u,)
    assert sample(traj, clock.at(first + len(commands)) + settings.lookahead_ns, "none", hold).effort == (0.0,)
