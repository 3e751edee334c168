"""Replanning from an estimated state, against an independent simulation of the true plant.

The true plant is simulated here with its own matrix exponentials, with the
disturbance or the model error the planner does not know; the commands it
receives are exactly those the timeline sends (:func:`timeline_commands`).
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from flexmotion_ros.core.config import PlannerConfig
from flexmotion_ros.core.errors import SolverError
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.model.boundary import state_to_rest
from flexmotion_ros.core.model.modal_model import ModalModel
from flexmotion_ros.core.simulation.exact import modal_amplitudes, simulate_samples
from flexmotion_ros.execution.replan import ReplanStatus, replan, warm_start_at
from flexmotion_ros.execution.replan_point import carry, relative_deviation, replan_point
from flexmotion_ros.execution.timeline import Segment
from flexmotion_ros.execution.trajectory import timeline_commands

WB = ModalModel(b0=0.5, omega=[math.sqrt(2.0)], zeta=[0.0], b=[1.0])
RATE = 20.0
DT = 1.0 / RATE
CFG = PlannerConfig(model=WB, u_max=1.0, rate_hz=RATE)
GOAL = 1.0
START = 10


def plan(x0, target, start: int) -> Segment:
    s = plan_move(CFG, state_to_rest(WB, 1.0, x0, target), RATE).sampled
    return Segment(np.asarray(s.commands, float), np.asarray(s.states, float), start=start)


@pytest.fixture(scope="module")
def first() -> Segment:
    return plan(WB.rest_state(0.0), GOAL, START)


def residual(model: ModalModel, x: np.ndarray, target: float) -> float:
    """Position error, velocity and vibration amplitude left, as a fraction of the move."""
    return max(abs(x[0] - target), abs(x[1]), float(np.max(modal_amplitudes(model, x)))) / GOAL


def test_on_plan_when_the_model_is_exact_and_nothing_disturbs(first):
    truth = simulate_samples(WB, WB.rest_state(0.0), first.commands, DT)
    for k_e in (START, START + 17, START + 40, first.end - 3):
        out = replan([first], k_e, 2, truth[k_e - START], k_e, config=CFG, target=GOAL)
        assert out.status is ReplanStatus.ON_PLAN and out.segment is None, out.reason
        assert out.point.sample == k_e + 2 and out.point.deviation < 1e-12
    assert replan([], 0, 2, WB.rest_state(0.0), 0, config=CFG, target=GOAL).status is ReplanStatus.IDLE


def test_an_impulse_is_corrected_by_the_next_plan(first):
    """A force impulse mid-move: the open loop ends vibrating; the replan from the measured state ends at rest."""
    k_hit = START + 30
    kick = 0.3 * WB.B()  # an impulse of 0.3 N s: every velocity jumps by its input gain
    x = simulate_samples(WB, WB.rest_state(0.0), first.commands[: k_hit - START], DT)[-1] + kick
    open_loop = simulate_samples(WB, x, first.commands[k_hit - START :], DT)[-1]
    assert residual(WB, open_loop, GOAL) > 0.05
    out = replan([first], k_hit + 1, 3, x, k_hit, config=CFG, target=GOAL)
    assert out.status is ReplanStatus.REPLANNED and out.point.sample == k_hit + 4
    timeline = [first, out.segment]
    sent = timeline_commands(timeline, k_hit, out.segment.end)
    assert np.max(np.abs(sent)) <= CFG.u_max
    x_end = simulate_samples(WB, x, sent, DT)[-1]
    assert residual(WB, x_end, GOAL) < 1e-9
    # the carried estimate is the true state at the splice
    x_s = simulate_samples(WB, x, sent[: out.point.sample - k_hit], DT)[-1]
    np.testing.assert_allclose(out.point.state, x_s, atol=1e-12)


def test_periodic_replanning_beats_the_open_loop_under_a_model_error(first):
    """The plant's frequency is 5 % off: replanning from its measured state every 0.2 s leaves far less.

    Each replan is a time-optimal move on the nominal model, so the closed loop keeps correcting and
    arrives later than the nominal plan; the corrections after arrival are planned at a bound proportional
    to what is left (``gentle``), about half a period each, so it settles within 15 s of the nominal
    arrival; then it is at rest."""
    plant = WB.with_changes(omega=(1.05 * WB.omega[0],))
    hold = int(round(15.0 * RATE))
    open_loop = simulate_samples(plant, WB.rest_state(0.0), np.concatenate([first.commands, np.zeros(hold)]), DT)
    period = max(1, int(round(0.2 * RATE)))  # 0.2 s: half the plans of 0.1 s, to keep the suite quick
    timeline = [first]
    x = WB.rest_state(0.0)
    k = START
    end_k = first.end + hold
    replans = 0
    while k < end_k:
        if (k - START) % period == 0 and k + 1 < end_k:
            out = replan(timeline, k, 1, x, k, config=CFG, target=GOAL, min_deviation=1e-6, gentle=True)
            assert out.status is not ReplanStatus.FAILED, out.reason
            if out.status is ReplanStatus.REPLANNED:
                timeline = [*timeline, out.segment]
                replans += 1
        x = simulate_samples(plant, x, timeline_commands(timeline, k, k + 1), DT)[-1]
        k += 1
    closed = residual(plant, x, GOAL)
    opened = residual(plant, open_loop[-1], GOAL)
    assert replans > 10 and timeline[-1].end < end_k  # arrived within the window
    assert opened > 0.1 and closed < 1e-5 and closed < opened / 10.0, (closed, opened)


def test_a_failed_replan_leaves_the_plan_and_says_why(first):
    def refuse(config, problem, rate):
        raise SolverError("no profile passed its final-state check")

    x = simulate_samples(WB, WB.rest_state(0.0), first.commands[:20], DT)[-1] + 0.2 * WB.B()
    out = replan([first], START + 20, 2, x, START + 20, config=CFG, target=GOAL, planner=refuse)
    assert out.status is ReplanStatus.FAILED and out.segment is None
    assert "the plan goes on" in out.reason and "final-state check" in out.reason


def test_a_deviation_within_the_estimates_noise_is_not_corrected(first):
    truth = simulate_samples(WB, WB.rest_state(0.0), first.commands, DT)
    k = START + 25
    P = np.diag([1e-4, 1e-4, 1e-4, 1e-4])
    noisy = truth[k - START] + np.array([5e-3, -5e-3, 5e-3, 5e-3])  # half a standard deviation
    out = replan([first], k, 2, noisy, k, config=CFG, target=GOAL, covariance=P)
    assert out.status is ReplanStatus.ON_PLAN and "within the estimate's noise" in out.reason
    far = truth[k - START] + np.array([0.1, 0.1, 0.1, 0.1])
    assert replan([first], k, 2, far, k, config=CFG, target=GOAL, covariance=P).status is ReplanStatus.REPLANNED


def test_deviation_measure_and_carry():
    d = np.array([0.0, 0.01, 0.0, 0.0])
    assert relative_deviation(WB, d, 2.0, 3.0) == pytest.approx(0.015)
    q = np.array([0.0, 0.0, 0.0, math.sqrt(2.0) * 0.1])  # a mode released with speed: amplitude 0.1
    assert relative_deviation(WB, q, 1.0, 0.0) == pytest.approx(0.1)
    x, P = carry(WB, DT, WB.rest_state(0.0), np.eye(4), [1.0, -1.0])
    np.testing.assert_allclose(x, simulate_samples(WB, WB.rest_state(0.0), [1.0, -1.0], DT)[-1], atol=1e-15)
    assert P.shape == (4, 4)
    with pytest.raises(Exception, match="later than the splice"):
        replan_point([Segment(np.zeros(3), np.zeros((4, 4)), start=0)], 0, 1, np.zeros(4), 5, model=WB, dt=DT)


def test_the_plan_being_executed_is_the_warm_start_and_a_failed_one_falls_back(first):
    """The segment's recorded plan (a PlanResult, or a node's record with one as ``result``) is the warm start."""
    result = plan_move(CFG, state_to_rest(WB, 1.0, WB.rest_state(0.0), GOAL), RATE)
    seg = Segment(np.asarray(result.sampled.commands, float), np.asarray(result.sampled.states, float), start=START)
    assert warm_start_at([seg], START + 20, DT) is None  # no plan recorded
    seg.info = SimpleNamespace(result=result)  # as a node's MoveRecord
    ws = warm_start_at([seg], START + 20, DT)
    assert ws is not None and abs(ws.duration - (result.continuous.duration - 20 * DT)) < 1e-12
    seg.info = result
    assert warm_start_at([seg], START + 20, DT) is not None
    assert warm_start_at([seg], seg.end + 5, DT) is None  # nothing plays there
    # a small disturbance: the warm replan is the cold one, and the planner is told the guess
    x = simulate_samples(WB, WB.rest_state(0.0), seg.commands[:20], DT)[-1] + np.array([0.0, 1e-4, 0.0, 0.0])
    seen = []

    def spy(config, problem, rate_hz, **kwargs):
        seen.append(kwargs.get("warm_start"))
        return plan_move(config, problem, rate_hz, **kwargs)

    warm = replan(
        [seg], START + 20, 1, x, START + 20, config=CFG, target=GOAL, planner=spy, gentle=False, warm_start=True
    )
    cold = replan([seg], START + 20, 1, x, START + 20, config=CFG, target=GOAL, warm_start=False, gentle=False)
    assert seen and seen[0] is not None
    assert warm.status is cold.status is ReplanStatus.REPLANNED
    assert abs(warm.result.continuous.duration - cold.result.continuous.duration) <= 1e-9
    assert np.array_equal(warm.segment.commands.shape, cold.segment.commands.shape)
    # a guess that leads nowhere (the rest of another move): the cold optimum all the same
    other = plan_move(CFG, state_to_rest(WB, 1.0, WB.rest_state(0.0), -3.0 * GOAL), RATE)
    seg.info = other
    wrong = replan([seg], START + 20, 1, x, START + 20, config=CFG, target=GOAL, gentle=False, warm_start=True)
    assert wrong.status is ReplanStatus.REPLANNED
    assert abs(wrong.result.continuous.duration - cold.result.continuous.duration) <= 1e-9
