"""A converged switch-time Newton run with a pair of switches collapsed onto one point is certified without the pair.

On f74d334 the lean path's Newton run for ``bench/planner_latency.py``'s
3-mode 1 s move converged with three switches at one time-to-go (gaps of
1e-16 T).  That candidate's certificate failed (``S`` changes sign once
there, not three times) and its zeros gave the same structure without the
pair: a second simulation and certificate of the same input (2 candidates,
8.3 ms of the plan's CPU time under load).  :func:`drop_coincident` removes
the pair first: one candidate, the same certified optimum.
"""

from __future__ import annotations

import numpy as np
from reference_solutions import assert_certified_exact

from flexmotion_ros.core import chain, plan_time_optimal, rest_to_rest
from flexmotion_ros.core.time_optimal.structure_guess import COINCIDENT_RTOL, drop_coincident


def test_the_collapsed_pair_costs_no_second_certificate():
    model = chain([0.5] * 4, [400.0] * 3, [0.4] * 3, force_on=0).model  # the bench's 3-mode link
    problem = rest_to_rest(model, 10.0, abs(model.b0) * 10.0 * 1.0**2 / 4.0)  # rigid time 1 s
    profile = plan_time_optimal(problem)
    assert_certified_exact(problem, profile)
    assert profile.extra["fast_path_stage"] == "lean"
    assert profile.extra["fast_path_candidates"] == 1  # f74d334: 2 (the first with the collapsed pair)
    assert profile.switch_times.size == 7


def test_drop_coincident_removes_only_pairs_at_one_point():
    T = 2.0
    d = 0.1 * COINCIDENT_RTOL * T
    # three switches at one point: one stays; the input is the same
    assert np.array_equal(drop_coincident(np.array([0.3, 0.7, 0.7 + d, 0.7 + 2 * d, 1.5]), T), [0.3, 0.7 + 2 * d, 1.5])
    # two collapsed pairs: both go
    assert drop_coincident(np.array([0.2, 0.2 + d, 1.1, 1.1 + d]), T).size == 0
    # a narrow pulse that is not of zero width stays (1e-9 T wide)
    tau = np.array([0.5, 0.5 + 1e-9 * T, 1.0])
    assert np.array_equal(drop_coincident(tau, T), tau)
    assert drop_coincident(np.array([0.4]), T).size == 1
    assert drop_coincident(np.empty(0), T).size == 0
