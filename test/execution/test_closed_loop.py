"""The closed loop without ROS: Kalman filter, replanning every 0.1 s spliced 0.4 s ahead, a plant 15 % off.

The true plant is simulated here with its own matrix exponentials; the filter
(:class:`StreamEstimator`) reads both masses' positions after every command,
as the plant node's ``measurements`` do; every replan is spliced 8 samples
(0.4 s) ahead, as under load.  With full-force corrections the loop
limit-cycles (each small correction is a time-optimal bang-bang at ``u_max``
that swings the mode as much as the move did; 15 % off, it leaves more than it
corrected: 0.165 of the move after 30 s, still correcting); with corrections
at a bound proportional to the deviation, after the plan has arrived
(``replan(..., gentle=True)``) it converges.
"""

from __future__ import annotations

import math

import numpy as np

from flexmotion_ros.core.config import PlannerConfig
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.model.boundary import rest_to_rest
from flexmotion_ros.core.model.modal_model import ModalModel
from flexmotion_ros.core.simulation.exact import modal_amplitudes, step_matrices
from flexmotion_ros.execution.feedback import FeedbackSettings, StreamEstimator
from flexmotion_ros.execution.replan import ReplanStatus, replan
from flexmotion_ros.execution.timeline import Segment
from flexmotion_ros.execution.trajectory import timeline_commands

WB = ModalModel(b0=0.5, omega=[math.sqrt(2.0)], zeta=[0.0], b=[1.0])
RATE = 20.0
DT = 1.0 / RATE
CFG = PlannerConfig(model=WB, u_max=1.0, rate_hz=RATE)
C = np.array([[1.0, 0.0, 0.5, 0.0], [1.0, 0.0, -0.5, 0.0]])  # x1 = p + q / 2, x2 = p - q / 2
GOAL = 0.5
PERIOD = 2  # samples: 0.1 s
LEAD = 8  # samples: 0.4 s
SETTLE = 8  # hold samples after each plan, in which the loop still corrects (the node's settle window)
KICK_AT = 30  # an impulse (0.1 N s) at 1.5 s


def loop(
    scale: float, *, gentle: bool, seconds: float = 30.0, period: int = PERIOD, kick: float = 0.1
) -> tuple[float, int, int]:
    """(residual of the move at the end, replans, the sample the timeline ends) of one closed-loop run."""
    true = WB.with_changes(omega=(scale * WB.omega[0],))
    Phi, Gam = step_matrices(true.A(), true.B(), DT)
    first = plan_move(CFG, rest_to_rest(WB, 1.0, GOAL), RATE)
    s = first.sampled
    hold = np.repeat(s.states[-1:], SETTLE, axis=0)
    timeline = [Segment(np.append(s.commands, np.zeros(SETTLE)), np.vstack([s.states, hold]), start=0, info=first)]
    est = StreamEstimator(WB, DT, FeedbackSettings(replan_period_s=period * DT, min_deviation=1e-3), C)
    est.restart(0, WB.rest_state(0.0))
    x = WB.rest_state(0.0)
    replans = 0
    k = 0
    while k < timeline[-1].end and k < seconds * RATE:
        if k and k % period == 0:
            e = est.estimate()
            out = replan(timeline, k, LEAD, e.x, e.sample, config=CFG, target=GOAL, covariance=e.P, move_size=GOAL,
                         min_deviation=1e-3, gentle=gentle)  # fmt: skip
            assert out.status is not ReplanStatus.FAILED, out.reason
            if out.status is ReplanStatus.REPLANNED:
                seg = out.segment
                seg.commands = np.append(seg.commands, np.zeros(SETTLE))
                seg.states = np.vstack([seg.states, np.repeat(seg.states[-1:], SETTLE, axis=0)])
                timeline = [t for t in timeline if t.start < seg.start] + [seg]
                replans += 1
        u = float(timeline_commands(timeline, k, k + 1)[0])
        est.command(k, u, k)
        est.measurement(k, C @ x)  # the reading of the state the command is applied to, stamped as sent
        x = Phi @ x + Gam * u
        if k + 1 == KICK_AT:
            x = x + true.B() * kick
        k += 1
    residual = max(float(np.max(modal_amplitudes(true, x))), abs(x[1]), abs(x[0] - GOAL)) / GOAL
    return residual, replans, timeline[-1].end


def test_gentle_corrections_converge_where_full_force_ones_limit_cycle():
    open_loop, replans, _ = loop(1.15, gentle=True, period=10**9)
    assert replans == 0 and open_loop > 0.1
    closed, replans, end = loop(1.15, gentle=True)
    assert replans > 10 and closed < open_loop / 10.0, (closed, open_loop)
    assert end <= 30.0 * RATE  # the loop stopped correcting: the timeline ended within the window


def test_with_an_exact_model_and_no_disturbance_nothing_is_replanned():
    closed, replans, _ = loop(1.0, gentle=True, seconds=8.0, kick=0.0)
    assert replans == 0 and closed < 1e-9, (closed, replans)
