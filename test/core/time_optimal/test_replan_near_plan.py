"""A replan 1e-6 off the plan whose optimum has a notch no Newton run certified (issue 15).

Three undamped modes (1.324, 4.185, 8.875 rad/s), a rest-to-rest optimum of
3.7301 s, a replan at 1.3988 s from a state disturbed by 1e-6 of the move's
excursions.  Five switches of the plan are left, too few to reach rest from
a generic state of 8 coordinates (the final state depends on the switch
times and ``T`` only: 7 switches are needed); the optimum (2.3313344888654 s)
has the 5 plus a notch 8.3e-7 s wide at 0.805 s before arrival.  The notch
candidates of the structure search converged to it, but each with one more
pair of switches merged by rounding (two equal switch times): the
certificate rejects such a pair, and the planner returned a longer, two-notch
profile (2.3313345201 s), uncertified, with a 1 % bound.  Now the pair is
dropped and Newton solves the 7 switches: certified ``OPTIMAL``, warm and cold.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from flexmotion_ros.core import ModalModel, plan_time_optimal, rest_to_rest, state_to_rest
from flexmotion_ros.core.results import CertificateStatus
from flexmotion_ros.core.time_optimal.fallbacks import without_rounding_pairs
from flexmotion_ros.core.time_optimal.warm_start import remainder
from flexmotion_ros.core.tolerances import SWITCH_TIME_RTOL

from .test_solver_properties import check_continuous

MODEL = ModalModel(
    b0=-1.1793313452201026, c=-1.810671309517325, omega=(1.324036616198607, 4.185381281225221, 8.875024825684761),
    zeta=(0.0, 0.0, 0.0), b=(-0.10000230261160267, 5.6993183398173315, 1.0471285480508996),
)  # fmt: skip
U_MAX = 4.4436592357864715
TARGET = -4.08805022028747
ELAPSED = 1.3988000457239473  # s along the nominal plan
#: the state there, disturbed (hypothesis' falsifying example of test_warm_start's ``replans``)
STATE = np.array([
    -2.0810110497829446, -0.5232849315462116, -0.2732687141046324, -0.07521451556182501,
    -2.3163896945032856, -11.767041504628402, -0.22152251501909875, 0.3250798367185648,
])  # fmt: skip
#: what the planner answered before, uncertified (s)
OLD_DURATION = 2.3313345200992446


def test_the_replan_near_the_plan_is_certified_optimal_warm_and_cold():
    nominal = plan_time_optimal(rest_to_rest(MODEL, U_MAX, TARGET))
    problem = state_to_rest(MODEL, U_MAX, STATE, TARGET)
    cold = plan_time_optimal(problem)
    warm = plan_time_optimal(problem, remainder(nominal, ELAPSED))
    for profile in (cold, warm):
        assert profile.certificate.status is CertificateStatus.OPTIMAL, profile.certificate.message
        check_continuous(problem, profile)  # independent expm simulation, signs, proved optimality
        assert profile.switch_times.size == 7  # the plan's 5 and a notch
        assert profile.duration < OLD_DURATION - 1e-8
        assert np.min(np.diff(profile.switch_times)) > 100.0 * SWITCH_TIME_RTOL * profile.duration
    assert abs(warm.duration - cold.duration) <= 1e-12 * cold.duration
    # a disturbance of 1e-6 lengthens the rest of the plan by about as much, not more
    assert 0.0 < cold.duration - (nominal.duration - ELAPSED) < 1e-5


def test_without_rounding_pairs_drops_merged_pairs_only():
    T = 2.0
    tol = SWITCH_TIME_RTOL * T
    tau = np.array([0.3, 0.8, 0.8, 0.8 + 1e-6, 1.5])  # a zero-width pair beside a real notch
    assert np.array_equal(without_rounding_pairs(tau, T), np.array([0.3, 0.8 + 1e-6, 1.5]))
    triple = np.array([0.3, 0.3 + 0.5 * tol, 0.3 + tol, 1.0])  # a triple merged by rounding: one is left
    assert without_rounding_pairs(triple, T).size == 2
    ends = np.array([0.5 * tol, tol, 1.0, T - tol, T - 0.5 * tol])  # at the ends: boundary levels kept
    assert np.array_equal(without_rounding_pairs(ends, T), ends)


@given(st.lists(st.floats(0.01, 1.99), min_size=0, max_size=12, unique=True), st.integers(0, 3))
def test_without_rounding_pairs_keeps_an_even_change_and_wide_gaps(times, merged):
    T = 2.0
    tau = np.sort(np.array(times, dtype=float))
    for k in range(min(merged, tau.size)):  # duplicate some switches: pairs merged by rounding
        tau = np.sort(np.append(tau, tau[k]))
    kept = without_rounding_pairs(tau, T)
    assert (tau.size - kept.size) % 2 == 0  # pairs only: the levels on either side are unchanged
    assert np.all(np.isin(kept, tau))
    wide = np.diff(np.concatenate([[0.0], tau, [T]])) > SWITCH_TIME_RTOL * T
    if np.all(wide):
        assert np.array_equal(kept, tau)
    else:
        assert kept.size < tau.size
