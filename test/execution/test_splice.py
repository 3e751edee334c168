"""The splice point and the look-ahead policy, against an exact simulation of the commands sent."""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import pytest

from flexmotion_ros.core.config import PlannerConfig
from flexmotion_ros.core.errors import GoalError
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.model.boundary import state_to_rest
from flexmotion_ros.core.model.modal_model import ModalModel
from flexmotion_ros.core.simulation.exact import simulate_samples
from flexmotion_ros.execution import (
    DEFAULT_PLAN_TIME_S,
    PLAN_TIME_FACTOR,
    PLAN_TIME_MARGIN_S,
    Segment,
    ended_at_rest,
    lead_samples,
    longer_lead,
    plan_summary,
    predicted_state,
    splice_point,
)
from flexmotion_ros.execution.lookahead import MAX_LEAD_S
from flexmotion_ros.execution.ready_stops import STOP_PREP_DUTY, StopPreparer

#: Wie-Bernstein at 20 Hz: a 1.0 move is 85 samples, planned in ~30 ms.
WB = ModalModel(b0=0.5, omega=[math.sqrt(2.0)], zeta=[0.0], b=[1.0])
CFG = PlannerConfig(model=WB, u_max=1.0, rate_hz=20.0)
DT = 1.0 / CFG.rate_hz
#: The first move starts at this global sample (the stream had been running).
K0 = 100


def plan(x0: np.ndarray, target: float | None, start: int) -> Segment:
    """A planned segment from ``x0`` to ``target``, installed at global sample ``start``."""
    s = plan_move(CFG, state_to_rest(WB, CFG.u_max, x0, target), CFG.rate_hz).sampled
    return Segment(np.asarray(s.commands, float), np.asarray(s.states, float), start=start)


@pytest.fixture(scope="module")
def first() -> Segment:
    return plan(WB.rest_state(0.0), 1.0, K0)


def exact_state_after(commands: np.ndarray) -> np.ndarray:
    """The state from rest at 0 after ``commands`` (independent of the planner's prediction)."""
    return simulate_samples(WB, WB.rest_state(0.0), commands, DT)[-1]


@pytest.mark.parametrize(("sent", "lead"), [(0, 1), (10, 7), (40, 20), (60, 3)])
def test_splice_state_is_the_exact_state_after_the_commands_sent(first, sent, lead):
    k_next = K0 + sent
    point = splice_point([first], k_next, lead, WB.n_modes)
    assert point.sample == k_next + lead and point.lead == lead
    expected = exact_state_after(first.commands[: sent + lead])
    np.testing.assert_allclose(point.state, expected, rtol=0, atol=1e-12)
    # the machine is moving there: an index off by one would give another state
    assert abs(point.state[1]) > 0.01
    assert not np.allclose(exact_state_after(first.commands[: sent + lead + 1]), point.state, rtol=0, atol=1e-6)


def test_after_a_splice_the_prediction_follows_the_new_plan(first):
    at = K0 + 30
    second = plan(first.state_at(at), -0.5, at)
    k_next, lead = at + 10, 15  # the second plan has been playing for 10 samples
    point = splice_point([first, second], k_next, lead, WB.n_modes)
    assert point.sample == at + 25
    expected = exact_state_after(np.concatenate([first.commands[:30], second.commands[:25]]))
    np.testing.assert_allclose(point.state, expected, rtol=0, atol=1e-12)
    # the first plan alone predicts somewhere else
    assert not np.allclose(exact_state_after(first.commands[:55]), point.state, rtol=0, atol=1e-3)
    # before the second plan starts, the first one still decides
    early = splice_point([first, second], K0 + 5, 10)
    np.testing.assert_allclose(early.state, exact_state_after(first.commands[:15]), rtol=0, atol=1e-12)


def test_past_the_end_of_the_move_the_splice_state_is_the_rest_at_the_target(first):
    point = splice_point([first], K0 + first.samples - 2, 50)
    np.testing.assert_allclose(point.state, exact_state_after(first.commands), rtol=0, atol=1e-12)
    np.testing.assert_allclose(point.state, WB.rest_state(1.0), rtol=0, atol=1e-9)


def test_from_its_first_sample_on_the_later_segment_decides():
    old = Segment(np.zeros(5), -np.arange(24.0).reshape(6, 4), start=0)
    new = Segment(np.ones(3), np.arange(16.0).reshape(4, 4) + 1.0, start=3)
    np.testing.assert_array_equal(predicted_state([old, new], 2), old.states[2])
    np.testing.assert_array_equal(predicted_state([old, new], 3), new.states[0])
    np.testing.assert_array_equal(predicted_state([old, new], 10), new.states[-1])  # at rest after its end
    assert predicted_state([], 3) is None


def test_idle_has_no_splice_point():
    assert splice_point([], 12, 5, WB.n_modes) is None


def test_a_plan_with_another_number_of_modes_is_refused(first):
    with pytest.raises(GoalError, match=r"number of modes changed during a move \(1 -> 2\)"):
        splice_point([first], K0, 5, n_modes=2)
    assert splice_point([first], K0, 5, n_modes=1) is not None


def test_look_ahead_covers_the_slowest_recent_plan():
    rate = 1000.0
    times = [0.05, 0.31, 0.12]
    lead = lead_samples(times, 0.0, rate)
    need_s = PLAN_TIME_FACTOR * 0.31 + PLAN_TIME_MARGIN_S
    assert (lead - 1) / rate < need_s <= lead / rate  # the least whole number of samples that covers it
    assert need_s > 1.5 * 0.31  # with a margin beyond 1.5 x the slowest
    assert lead_samples(sorted(times), 0.0, rate) == lead == lead_samples([0.31], 0.0, rate)  # only the slowest counts
    assert lead_samples([0.05], 0.0, rate) < lead


def test_look_ahead_is_at_least_the_configured_lead():
    assert lead_samples([0.01], 1.0, 100.0) == 100
    assert lead_samples([0.01], 0.0, 100.0) == math.ceil((1.5 * 0.01 + 0.02) * 100.0) == 4


def test_look_ahead_before_any_plan_assumes_the_default_plan_time():
    assert DEFAULT_PLAN_TIME_S == 0.2
    lead = lead_samples([], 0.0, 1000.0)
    assert lead == lead_samples([DEFAULT_PLAN_TIME_S], 0.0, 1000.0)
    assert 320 <= lead <= 321  # 0.32 s at 1 kHz (321 by the rounding of 0.32 x 1000 up)
    assert lead_samples([0.1], 0.0, 1000.0) < lead


def test_an_overrun_doubles_the_look_ahead():
    assert [longer_lead(n) for n in (1, 7, 320)] == [2, 14, 640]


def test_a_refused_splice_starts_from_rest_only_if_the_move_had_ended(first):
    end = first.end
    assert ended_at_rest([first], end, idle=True)
    assert ended_at_rest([first], end + 10, idle=True)
    assert not ended_at_rest([first], end - 1, idle=True)  # planned from a moving state: replan
    assert not ended_at_rest([first], end + 10, idle=False)  # something else is playing now
    assert not ended_at_rest([], end, idle=True)


def test_plan_summary_reports_the_plan(first):
    result = plan_move(CFG, state_to_rest(WB, CFG.u_max, WB.rest_state(0.0), 1.0), CFG.rate_hz)
    info = plan_summary(result, 0.125)
    assert info["samples"] == first.samples == 85 and info["duration_s"] == pytest.approx(85 * DT)
    assert info["peak_command"] == pytest.approx(np.max(np.abs(first.commands))) and 0 < info["peak_command"] <= 1.0
    assert info["plan_time_s"] == 0.125 and info["method"] == CFG.method
    assert info["certified"] in (True, False) and info["final_state_error"] < 1e-6


def test_look_ahead_is_not_hostage_to_one_slow_plan():
    # issue 16: 1.5 x the slowest of the last five; after an 8.9 s stop plan a mid-move goal was spliced 13.4 s
    # after its request (old main: 2674 samples at 200 Hz here)
    rate = 200.0
    usual = lead_samples([0.05] * 5, 0.0, rate)
    assert usual == math.ceil((1.5 * 0.05 + 0.02) * rate)  # 19 or 20 by the rounding of 0.095 s x 200
    assert lead_samples([0.05] * 4 + [8.9], 0.0, rate) == usual  # the outlier is set aside
    assert lead_samples([0.05] * 16 + [8.9, 3.0, 2.0, 7.0], 0.0, rate) == usual  # 4 of 20: still the slowest 20 %


def test_look_ahead_is_capped_unless_the_configured_lead_asks_for_more():
    rate = 200.0
    assert lead_samples([8.9] * 20, 0.0, rate) == math.ceil(MAX_LEAD_S * rate) == 200
    assert lead_samples([8.9] * 20, 2.0, rate) == 400  # replan_lead_s is the user's own floor
    assert lead_samples([0.3, 0.31], 0.0, rate) == math.ceil((1.5 * 0.31 + 0.02) * rate)  # few plans: the slowest


def _preparer_on_a_fake_move(plan_s: float, paused):
    """A StopPreparer over a long fake move whose 'plan' sleeps ``plan_s``; returns it and the plan start times."""
    model = ModalModel(b0=1.0, omega=(2.0,), zeta=(0.0,), b=(1.0,))
    n = 100_000
    states = np.zeros((n + 1, 4))
    seg = Segment(np.zeros(n), states, start=0, info="move")
    starts: list[float] = []
    k0 = time.monotonic()

    def snapshot():
        return int((time.monotonic() - k0) * 100.0), [seg]

    def plan(x0, key):
        starts.append(time.monotonic())
        time.sleep(plan_s)
        return Segment(np.zeros(3), np.zeros((4, 4)), info="stop")

    assert model.n_modes == 1
    prep = StopPreparer(plan, snapshot, lambda: "key", lambda timeline: True, 100.0, paused=paused)
    return prep, starts


def test_stop_preparer_plans_at_most_half_the_time_and_not_while_a_goal_is_planned():
    # issue 11: the preparer planned back to back during every move (duty 1), also while a goal was planned
    assert STOP_PREP_DUTY <= 0.5
    goal_planning = threading.Event()
    prep, starts = _preparer_on_a_fake_move(0.02, goal_planning.is_set)
    prep.start()
    try:
        time.sleep(0.6)
        # duty: each plan start is at least plan time / duty after the previous one
        gaps = np.diff(starts)
        assert starts and np.all(gaps >= 0.02 / STOP_PREP_DUTY - 0.003), gaps
        goal_planning.set()
        time.sleep(0.05)  # a plan under way finishes
        n = len(starts)
        time.sleep(0.4)
        assert len(starts) == n, "planned stops while a goal was being planned"
        assert prep.pauses > 0
        goal_planning.clear()
        time.sleep(0.3)
        assert len(starts) > n  # resumes
    finally:
        prep.stop()
