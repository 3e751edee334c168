"""Issue 15's tail: a converged extremal the check rejected is not checked again (``structure_guess``).

Fuzz case 1446 (seed 15; 7 modes, a 1,323-unit rest-to-rest move) certified the same 15-switch extremal
8 times on b4affa1 (about 6 ms each): the one-dip alternatives of its 123 sign changes each converged
back to it, and each was simulated and certified again, with the same verdict.  Now a candidate within
``SAME_EXTREMAL_RTOL`` of a rejected one is skipped (its edits were queued the first time).
"""

from __future__ import annotations

import numpy as np
from reference_solutions import bang_bang_final_error

from flexmotion_ros.core import ModalModel, MoveProblem
from flexmotion_ros.core.results import SolverPath
from flexmotion_ros.core.time_optimal.solver import plan_time_optimal
from flexmotion_ros.core.time_optimal.structure_guess import newton_from_guess

CASE_1446 = MoveProblem(
    ModalModel(
        b0=4.840610482643152,
        c=-0.05509054624751297,
        omega=(0.6166698186253496, 0.7087505664380042, 1.422796663780538, 1.785229996987265, 11.222212828668347,
               16.68731890913328, 40.184017360285594),
        zeta=(0.13886531218956585, 0.2613321999893424, 0.09333004284588738, 0.08167024024226638,
              0.2786525713968779, 6.942352922787442e-05, 0.18995505521442993),
        b=(1.9583740340760998, 1.9070299392162369, 1.665193990543133, 1.9599813225793459, 1.5864077913931338,
           1.9476015339763724, 1.5699149471558433),
    ),
    0.6393334243362341,
    np.zeros(16),
    -1322.8328410358088,
)  # fmt: skip
#: Its certified optimum on b4affa1 (fast path, 10 candidates certified), s.
T_1446 = 48.89592251505596


def test_case_1446_certifies_each_extremal_once():
    problem = CASE_1446
    profile = plan_time_optimal(problem)
    assert profile.certified, profile.certificate.message
    assert profile.extra["solver_path"] is SolverPath.FAST
    assert abs(profile.duration - T_1446) <= 1e-9 * T_1446
    assert profile.extra["fast_path_candidates"] <= 5  # 10 on b4affa1: one extremal certified 8 times
    assert bang_bang_final_error(problem, profile) <= 1e-9  # own expm propagation
    assert np.all(np.abs(profile.levels) <= problem.u_max)


def test_newton_runs_converging_to_a_rejected_extremal_are_not_checked_again():
    # every run, whatever its start, converges to the one extremal (2 switches), which the check rejects
    # with two new sign changes in each arc: the edits and the one-dip alternatives all lead back to it
    T = 10.0
    extremal = np.array([3.0, 6.0])
    checked = []

    def refine(roots, sign0, nuh, T):
        return True, extremal + 1e-13 * len(checked), nuh, T, 0.0

    def check(nuh, T, roots, signs):
        checked.append(roots.copy())
        zeros = np.sort(np.concatenate([roots, [1.0, 1.5, 4.0, 4.5, 7.5, 8.0]]))
        return None, zeros, signs[0]

    def switching(nuh, tau):
        return np.where((tau > 1.0) & (tau < 1.5) | (tau > 4.0) & (tau < 4.5) | (tau > 7.5) & (tau < 8.0), -1.0, 1.0)

    found = newton_from_guess(
        None, np.ones(3), T, check, refine=refine, structure=(np.array([2.9, 6.1]), 1.0), switching=switching
    )
    assert found is None
    assert len(checked) == 1  # once per distinct extremal (on b4affa1: once per run, up to 12)
