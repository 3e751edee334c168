"""The command stream on a fake clock: order, absolute deadlines, no skipped sample, the hold, splices."""

from __future__ import annotations

import math
import threading

import numpy as np
import pytest

from flexmotion_ros.core.config import PlannerConfig
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.model.boundary import state_to_rest
from flexmotion_ros.core.model.modal_model import ModalModel
from flexmotion_ros.core.simulation.exact import simulate_samples
from flexmotion_ros.execution import HOLD, CommandStream, Segment, lead_samples, splice_point
from flexmotion_ros.execution.ready_stops import STOP_MARGIN_SAMPLES, StopPreparer, ready_stop_usable
from flexmotion_ros.execution.stream_halt import HaltCause, StreamStopped

RATE = 100.0
DT = 1.0 / RATE
T0 = 1000.0  # the fake clock's start (s)


class FakeClock:
    """A monotonic clock (s) that only moves when slept on (or pushed by a test)."""

    def __init__(self, t0: float = T0) -> None:
        self.now = t0
        self.sleeps: list[float] = []
        self._lock = threading.Lock()  # the threaded test reads it from two threads

    def __call__(self) -> float:
        with self._lock:
            return self.now

    def sleep(self, seconds: float) -> None:
        with self._lock:
            self.sleeps.append(seconds)
            self.now += seconds

    def advance(self, seconds: float) -> None:
        with self._lock:
            self.now += seconds


class Recorder:
    """The publisher (a list) and the stream's callbacks."""

    def __init__(self, clock: FakeClock, cost_s: float = 0.0) -> None:
        self.clock = clock
        self.cost_s = cost_s  # how long one publish takes on the fake clock (s)
        self.stall: dict[int, float] = {}  # publish number -> extra time it takes (s)
        self.values: list[float] = []
        self.started: list[Segment] = []
        self.finished: list[Segment] = []

    def publish(self, value: float) -> None:
        self.clock.advance(self.cost_s + self.stall.get(len(self.values), 0.0))
        self.values.append(value)


def make_stream(hold_when_idle: bool = False, cost_s: float = 0.0) -> tuple[CommandStream, FakeClock, Recorder]:
    clock = FakeClock()
    rec = Recorder(clock, cost_s)
    stream = CommandStream(
        RATE,
        rec.publish,
        hold_when_idle,
        on_start=rec.started.append,
        on_finish=rec.finished.append,
        clock=clock,
        sleep=clock.sleep,
    )
    return stream, clock, rec


def segment(commands) -> Segment:
    u = np.asarray(commands, float)
    return Segment(u, np.zeros((u.size + 1, 4)))


def run_until_idle(stream: CommandStream, limit: int = 10_000) -> list:
    steps = []
    while not stream.idle:
        steps.append(stream.step())
        assert len(steps) < limit
    return steps


def test_samples_go_out_in_order_at_absolute_deadlines():
    # each publish costs 4 ms of the 10 ms period: a loop sleeping dt after each
    # sample would drift by 4 ms a sample; absolute deadlines do not
    stream, clock, rec = make_stream(cost_s=0.004)
    seg = segment([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    assert stream.start_now(seg) == 0
    steps = run_until_idle(stream)
    assert rec.values == [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, HOLD]
    assert [s.sample for s in steps] == list(range(7))
    k = np.arange(7)
    np.testing.assert_allclose([s.deadline for s in steps], T0 + k * DT, rtol=0, atol=1e-9)
    np.testing.assert_allclose(stream.sent_times, T0 + k * DT, rtol=0, atol=1e-9)
    np.testing.assert_allclose(stream.lateness, 0.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(clock.sleeps, DT - 0.004, rtol=0, atol=1e-9)  # the rest of each period
    assert stream.time_of(10) == pytest.approx(T0 + 10 * DT, abs=1e-9)
    assert rec.started == [seg] and rec.finished == [seg] and seg.started_at == pytest.approx(T0)


def test_a_late_step_skips_no_sample_and_the_deadlines_stay_on_the_grid():
    stream, clock, rec = make_stream()
    rec.stall[2] = 3.5 * DT  # publishing sample 2 stalls for 35 ms
    commands = [float(i + 1) for i in range(10)]
    stream.start_now(segment(commands))
    steps = run_until_idle(stream)
    assert rec.values == [*commands, HOLD]  # every sample, in order
    assert [s.sample for s in steps] == list(range(11))
    np.testing.assert_allclose([s.deadline for s in steps], T0 + np.arange(11) * DT, rtol=0, atol=1e-9)
    late = np.array(stream.lateness)
    # samples 3..5 go out at once, late; from sample 6 on the stream is back on its grid
    np.testing.assert_allclose(late[3:6], [2.5 * DT, 1.5 * DT, 0.5 * DT], rtol=0, atol=1e-9)
    np.testing.assert_allclose(late[:3], 0.0, atol=1e-9)
    np.testing.assert_allclose(late[6:], 0.0, atol=1e-9)
    assert len(clock.sleeps) == 7  # no sleep before the three late samples


def test_a_move_ends_with_exactly_one_hold_then_the_stream_is_silent():
    stream, clock, rec = make_stream(hold_when_idle=False)
    first = segment([0.5, -0.5, 0.25])
    stream.start_now(first)
    run_until_idle(stream)
    assert rec.values == [0.5, -0.5, 0.25, HOLD]
    assert rec.finished == [first]  # after the hold, once
    t = clock()
    assert stream.step() is None and stream.step() is None  # idle: nothing is due, no sleep
    assert clock() == t and rec.values == [0.5, -0.5, 0.25, HOLD]
    # a move after a silent pause starts on the next sample, due now: no burst of missed samples
    clock.advance(2.0)
    second = segment([1.0, 1.0])
    assert stream.start_now(second) == 4
    steps = run_until_idle(stream)
    assert rec.values == [0.5, -0.5, 0.25, HOLD, 1.0, 1.0, HOLD]
    assert steps[0].deadline == pytest.approx(t + 2.0, abs=1e-9) and steps[0].time == steps[0].deadline
    assert rec.finished == [first, second] and rec.started == [first, second]


def test_the_idle_hold_when_enabled():
    stream, clock, rec = make_stream(hold_when_idle=True)
    for _ in range(5):
        stream.step()
    assert rec.values == [HOLD] * 5
    np.testing.assert_allclose(stream.sent_times, T0 + np.arange(5) * DT, rtol=0, atol=1e-9)
    seg = segment([2.0, 3.0])
    assert stream.start_now(seg) == 5  # on the hold stream's grid
    for _ in range(5):
        stream.step()
    assert rec.values == [HOLD] * 5 + [2.0, 3.0, HOLD, HOLD, HOLD]
    assert rec.finished == [seg]  # the move's own hold, not the idle holds, ends it
    np.testing.assert_allclose(stream.sent_times, T0 + np.arange(10) * DT, rtol=0, atol=1e-9)
    # switched off: silent; on again after a pause: resumes now, without catching up
    stream.hold_when_idle = False
    assert stream.step() is None
    clock.advance(1.0)
    stream.hold_when_idle = True
    first = stream.step()
    assert first.value == HOLD and first.deadline == pytest.approx(clock(), abs=1e-9)
    assert len(rec.values) == 11


def test_a_splice_takes_effect_at_the_splice_sample():
    stream, _, rec = make_stream()
    old = segment(np.arange(1.0, 11.0))
    new = segment([-1.0, -2.0, -3.0])
    stream.start_now(old)
    for _ in range(3):
        stream.step()
    assert not stream.splice(segment([9.0]), 2)  # sample 2 was sent: refused, nothing changes
    assert stream.splice(new, 6) and new.start == 6
    k_next, timeline = stream.snapshot()
    assert k_next == 3 and timeline == [old, new]
    steps = run_until_idle(stream)
    assert rec.values == [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, -1.0, -2.0, -3.0, HOLD]
    assert [s.sample for s in steps] == list(range(3, 10))
    assert rec.started == [old, new] and rec.finished == [new]
    assert not stream.splice(segment([1.0]), 20)  # idle: start_now applies


def test_a_preemption_reaches_the_predicted_state_at_the_splice_sample():
    """Real plans: a new goal mid-move, spliced at the look-ahead; an exact simulation of what was sent."""
    model = ModalModel(b0=0.5, omega=[math.sqrt(2.0)], zeta=[0.0], b=[1.0])
    cfg = PlannerConfig(model=model, u_max=1.0, rate_hz=RATE)

    def plan(x0, target):
        s = plan_move(cfg, state_to_rest(model, cfg.u_max, x0, target), RATE).sampled
        return Segment(np.asarray(s.commands, float), np.asarray(s.states, float))

    stream, _, rec = make_stream()
    first = plan(model.rest_state(0.0), 1.0)
    stream.start_now(first)
    for _ in range(40):
        stream.step()
    lead = lead_samples([0.05], 0.0, RATE)  # 0.095 s: 10 samples
    k_next, timeline = stream.snapshot()
    point = splice_point(timeline, k_next, lead, model.n_modes)
    second = plan(point.state, -0.5)
    assert stream.splice(second, point.sample)
    run_until_idle(stream)
    u = np.array(rec.values)
    s = point.sample
    assert s == 50 and u.size == s + second.samples + 1
    np.testing.assert_array_equal(u, np.concatenate([first.commands[:s], second.commands, [HOLD]]))
    X = simulate_samples(model, model.rest_state(0.0), u, DT)
    np.testing.assert_allclose(X[s], second.states[0], rtol=0, atol=1e-9)  # where the new plan started
    assert abs(X[s, 1]) > 0.1  # moving there
    np.testing.assert_allclose(X[-1], model.rest_state(-0.5), rtol=0, atol=1e-6)
    assert np.max(np.abs(u)) <= cfg.u_max


def test_the_thread_plays_a_move_then_waits_for_the_next():
    clock = FakeClock()
    values: list[float] = []
    done = threading.Event()
    stream = CommandStream(RATE, values.append, False, on_finish=lambda seg: done.set(), clock=clock, sleep=clock.sleep)
    stream.start()
    try:
        stream.start_now(segment([1.0, 2.0, 3.0]))
        assert done.wait(5.0)
        assert values == [1.0, 2.0, 3.0, HOLD] and stream.samples_sent == 4
        t = clock()
        done.clear()
        threading.Event().wait(0.05)  # real time passes; the idle, silent thread sends nothing
        assert stream.samples_sent == 4 and clock() == t
        stream.start_now(segment([4.0]))
        assert done.wait(5.0)
        assert values == [1.0, 2.0, 3.0, HOLD, 4.0, HOLD]
    finally:
        stream.stop()
    with pytest.raises(RuntimeError, match="stopped"):  # stopped: nothing more goes out
        stream.start_now(segment([5.0]))
    threading.Event().wait(0.05)
    assert values == [1.0, 2.0, 3.0, HOLD, 4.0, HOLD]


def test_recent_timing_is_the_last_samples_sent():
    stream, clock, rec = make_stream(hold_when_idle=True)
    rec.stall[3] = 1.5 * DT  # sample 4 goes out 5 ms late
    for _ in range(6):
        stream.step()
    times, late = stream.recent_timing(3)
    np.testing.assert_allclose(times, T0 + np.array([3.0, 4.0, 5.0]) * DT + [0.0, 0.5 * DT, 0.0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(late, [0.0, 0.5 * DT, 0.0], rtol=0, atol=1e-9)
    assert [a.size for a in stream.recent_timing(1)] == [0, 0]  # one sample has no period


# ------------------------------------------------------------------ the hold on stop and on a fault


def test_stop_mid_move_sends_the_hold_at_once_and_nothing_after():
    # the old stop() only joined the thread: the actuator kept the last force (issue 11)
    stream, clock, rec = make_stream()
    stream.start_now(segment([1.0, 0.9, 0.8, 0.7, 0.6]))
    stream.step()
    stream.step()
    halt = stream.stop("shutdown")
    assert rec.values == [1.0, 0.9, HOLD]
    assert halt.cause is HaltCause.STOPPED and halt.why == "shutdown"
    assert halt.held and halt.hold_sent and halt.interrupted and halt.last_value == 0.9 and halt.sample == 3
    assert "hold (0) sent" in halt.describe() and "cut off" in halt.describe()
    assert stream.stop("again") is halt  # idempotent: one hold
    assert stream.step() is None and rec.values == [1.0, 0.9, HOLD]
    assert stream.idle


def test_stop_after_the_move_ended_sends_no_second_hold():
    stream, clock, rec = make_stream()
    stream.start_now(segment([0.5, -0.5]))
    run_until_idle(stream)
    halt = stream.stop("deactivated")
    assert rec.values == [0.5, -0.5, HOLD]
    assert halt.held and not halt.hold_sent and not halt.interrupted
    assert "already the hold" in halt.describe()


def test_the_thread_stopped_mid_move_ends_with_one_hold():
    values: list[float] = []
    stream = CommandStream(1000.0, values.append, False)  # the real clock
    stream.start()
    stream.start_now(segment([1.0] * 5000))
    deadline = threading.Event()
    while len(values) < 20:
        assert not deadline.wait(0.002)
    halt = stream.stop("shutdown")
    assert not stream.running
    n = len(values)
    assert values[-1] == HOLD and values[:-1] == [1.0] * (n - 1)
    assert halt.hold_sent and halt.interrupted
    threading.Event().wait(0.02)
    assert len(values) == n  # nothing after the hold


def test_a_fault_in_the_stream_thread_ends_with_the_hold_and_the_stream_restarts():
    clock = FakeClock()
    values: list[float] = []
    faults = []
    fail = {"at": 3}

    def publish(value: float) -> None:
        if len(values) == fail["at"]:
            fail["at"] = -1
            raise OSError("publisher's context is invalid")
        values.append(value)

    stream = CommandStream(RATE, publish, False, clock=clock, sleep=clock.sleep, on_fault=faults.append)
    stream.start()
    stream.start_now(segment([1.0] * 10))
    stream._thread.join(5.0)  # noqa: SLF001 -- the test waits for the stream thread to end
    assert values == [1.0, 1.0, 1.0, HOLD]
    assert len(faults) == 1 and faults[0] is stream.halted
    halt = faults[0]
    assert halt.cause is HaltCause.FAULT and "OSError" in halt.why and halt.hold_sent and halt.interrupted
    with pytest.raises(RuntimeError, match="fault"):
        stream.start_now(segment([2.0]))
    assert stream.stop("shutdown") is halt  # no second hold
    stream.start()  # a stopped stream starts again, idle, the sample index continuing
    try:
        done = threading.Event()
        stream._on_finish = lambda seg: done.set()  # noqa: SLF001
        seg = segment([2.0])
        stream.start_now(seg)
        assert done.wait(5.0)
        assert values[-2:] == [2.0, HOLD] and seg.start >= 4
    finally:
        stream.stop()


def test_a_failing_hold_is_reported_not_raised():
    clock = FakeClock()
    values: list[float] = []

    def publish(value: float) -> None:
        if value == HOLD:
            raise RuntimeError("context is invalid")
        values.append(value)

    stream = CommandStream(RATE, publish, False, clock=clock, sleep=clock.sleep)
    stream.start_now(segment([1.0, 1.0]))
    stream.step()
    halt = stream.stop("shutdown")
    assert not halt.held and not halt.hold_sent and "context is invalid" in halt.hold_error
    assert "could NOT be sent" in halt.describe()


# ------------------------------------------------------------------ ready stops (the stream's preparer)


def test_ready_stops_are_planned_ahead_and_used_only_while_the_timeline_still_predicts_them():
    states = np.cumsum(np.ones((1001, 4)), axis=0)  # a distinct predicted state at every sample
    move = Segment(np.ones(1000), states, start=0)
    k_now = {"k": 10}
    timeline = [move]
    key = {"config": object()}
    planned: list[np.ndarray] = []

    def plan(x0: np.ndarray, k) -> Segment:
        assert k is key["config"]
        planned.append(x0)
        return segment([-1.0, -1.0])

    prep = StopPreparer(plan, lambda: (k_now["k"], list(timeline)), lambda: key["config"], lambda tl: True, 1000.0)
    prep.start()
    try:
        prep.notify(0.01)  # the move took 10 ms to plan: the first guess of a stop's
        deadline = threading.Event()
        while len(prep.ready()) < 2:
            assert not deadline.wait(0.01)
        ready = prep.ready()
        assert all(r.sample >= 10 + STOP_MARGIN_SAMPLES for r in ready)
        assert all(np.array_equal(r.state, move.state_at(r.sample)) for r in ready)  # from the predicted state
        first = ready[0]
        assert ready_stop_usable(first, timeline, k_now["k"], key["config"])
        assert not ready_stop_usable(first, timeline, first.sample - 1, key["config"])  # too close: not seen in time
        assert not ready_stop_usable(first, timeline, k_now["k"], object())  # another configuration
        other = Segment(np.ones(1000), states + 1.0, start=5)  # a splice changed what is predicted there
        assert not ready_stop_usable(first, [move, other], k_now["k"], key["config"])
        got = prep.take()
        assert got is first and first not in prep.ready()
    finally:
        prep.stop()


def test_the_sample_record_is_a_ring_of_constant_size():
    # issue 16.8: a deque of Python floats (maxlen 200,000) grew the planner by ~13 MB over its first
    # 200,000 samples -- measured by the storm as a leak; the ring is allocated once
    from flexmotion_ros.execution.sample_record import SampleRecord

    rec = SampleRecord(5)
    nbytes = rec._buf.nbytes  # noqa: SLF001 -- the allocation itself is what is tested
    for k in range(12):
        rec.append(float(k), -float(k))
    assert rec._buf.nbytes == nbytes and len(rec) == 5  # noqa: SLF001
    times, late = rec.last(3)
    assert times.tolist() == [9.0, 10.0, 11.0] and late.tolist() == [-9.0, -10.0, -11.0]
    assert rec.last(3, before=2)[0].tolist() == [7.0, 8.0, 9.0]
    assert rec.last(10)[0].tolist() == [7.0, 8.0, 9.0, 10.0, 11.0]  # only what is kept
    assert rec.last(4, before=3)[0].tolist() == [7.0, 8.0]  # older ones are gone


def test_a_segment_offered_to_a_stopped_stream_is_refused_as_stopped_not_as_an_internal_failure():
    # old main: a plain RuntimeError, which the node answered as "unexpected RuntimeError" (an internal error
    # text in bench/storm.py: a stop still being planned when the node shut down)
    stream, _, rec = make_stream()
    stream.start_now(segment([1.0, 2.0]))
    stream.step()
    halt = stream.stop("shutdown")
    assert halt.hold_sent and rec.values == [1.0, HOLD]
    with pytest.raises(StreamStopped, match="stopped: shutdown"):
        stream.start_now(segment([1.0]))
    with pytest.raises(StreamStopped):
        stream.splice(segment([1.0]), stream.snapshot()[0] + 1)
    assert rec.values == [1.0, HOLD]  # nothing after the hold
