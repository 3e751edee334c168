"""The lean path's smoothed guess brackets the duration to :data:`~.lean.LOG_TOL` where ``m(T)`` starts flat.

Two 3-mode replans of ``bench/replan_latency.py`` (seed 0 state 64, seed 1 state 19, carried to
the splice): ``dm/dT`` at the first duration is 4e-3 (or negative), the first step overshoots 2-4x and
the bracket needs 5-6 steps back.  Stopped after four (as before), the guess's duration was 11 % short,
the lean Newton failed and the fast path answered (~12 ms more).  Now the lean path answers, with the
same certified optimum.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexmotion_ros.core import chain, plan_time_optimal, state_to_rest
from flexmotion_ros.core.results import CertificateStatus
from flexmotion_ros.core.time_optimal import lean

STATES = (
    (1.9987946050345744, 2.2705368860553117, -0.03872300903615853, -0.016289887853217624,
     0.0028431146441266777, -0.2806584717692725, 0.0024445001739342945, 0.21889182511422609),
    (1.855495543472339, 2.3150424977506936, -0.012027957916768419, -0.6981791958405872,
     -0.005148857805513241, -0.09511445959805727, 0.005936371774847302, -0.04538153363945431),
)  # fmt: skip


@pytest.mark.parametrize("state", STATES)
def test_flat_start_is_bracketed_and_the_lean_path_answers(state):
    model = chain([0.5] * 4, [400.0] * 3, [0.4] * 3).model
    problem = state_to_rest(model, 10.0, np.array(state), 2.5)
    profile = plan_time_optimal(problem)
    assert profile.extra.get("fast_path_stage") == "lean"
    assert profile.certificate.status is CertificateStatus.OPTIMAL
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(lean, "OUTER_STEPS", 4)
        other = plan_time_optimal(problem)  # the fast path's answer (the old guess stopped short)
    assert other.certificate.status is CertificateStatus.OPTIMAL
    assert abs(other.duration - profile.duration) <= 1e-12 * profile.duration
    assert other.switch_times.size == profile.switch_times.size
    assert np.max(np.abs(other.switch_times - profile.switch_times)) <= 1e-9 * profile.duration
