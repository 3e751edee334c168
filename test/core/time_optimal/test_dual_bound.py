"""The weak-duality lower bound (``time_optimal.dual_bound``) proves only what is true.

It must never "prove" a time at which the target is reachable: past a certified optimum ``T*`` every
time is (arrive, then hold at rest), so asked about ``T*(1 + 1e-6)`` with the optimum's own co-state
(the switches at the same times to go: the tightest direction there is) it must decline.  At ``T*``
the bound it proves is checked by the test's own weak-duality integral (``reference_solutions``:
expm of the augmented matrix, cells split at the zeros of ``S``).
"""

from __future__ import annotations

import numpy as np
from hypothesis import event, given, settings
from reference_solutions import lower_bound_gap

from flexmotion_ros.core import ModalModel, plan_time_optimal, rest_to_rest
from flexmotion_ros.core.results import CertificateStatus
from flexmotion_ros.core.simulation.prepared import prepare
from flexmotion_ros.core.time_optimal.dual_bound import CERTIFY_GAPS, REPORT_GAPS, proved_lower_bound
from flexmotion_ros.core.tolerances import GAP_RTOL

from .test_lean import small_problems
from .test_solver_properties import SETTINGS

LATE = 1e-6


def _bound(problem, T, switch_times, levels, gaps=CERTIFY_GAPS):
    move = prepare(problem)
    return proved_lower_bound(move.response, move.x0, problem.u_max, T, switch_times, levels, gaps)


def test_a_double_integrator_is_bounded_at_its_optimum_and_not_after():
    problem = rest_to_rest(ModalModel(b0=1.0), 1.0, 1.0)
    T = 2.0  # 2 sqrt(d / a)
    proof = _bound(problem, T, np.array([1.0]), np.array([1.0, -1.0]))
    assert proof is not None and proof[0] == T * (1.0 - 0.5 * GAP_RTOL)
    late = T * (1.0 + LATE)
    assert _bound(problem, late, np.array([1.0 + T * LATE]), np.array([1.0, -1.0])) is None


@settings(max_examples=25, **SETTINGS)
@given(small_problems())
def test_never_proves_a_reachable_time_and_its_proofs_hold(problem):
    profile = plan_time_optimal(problem)
    if profile.duration == 0.0 or profile.certificate.status is not CertificateStatus.OPTIMAL:
        return
    T = profile.duration
    late = T * (1.0 + LATE)  # reachable: T* then rest
    assert _bound(problem, late, profile.switch_times + (late - T), profile.levels) is None
    # the coarser gaps of an uncertified answer's report: whatever they prove lies below T* and holds
    report = _bound(problem, late, profile.switch_times + (late - T), profile.levels, REPORT_GAPS)
    if report is not None:
        assert report[0] < T
        assert lower_bound_gap(problem, report[0], report[1], use_lp=False) > 0.0
    proof = _bound(problem, T, profile.switch_times, profile.levels)
    event(f"proved at T*: {proof is not None}")
    if proof is not None:
        T_dual, nu = proof
        assert T_dual < T
        assert lower_bound_gap(problem, T_dual, nu, use_lp=False) > 0.0
