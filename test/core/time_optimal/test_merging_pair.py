"""A pair of switches merging in the fast path's switch-time Newton (issue 15's tail, fourth pass).

When a full Newton step carries a pair of neighbouring switches past each
other, :func:`~.switch_newton.damped_step` halves it until they stay
ordered: the run crawls (fuzz case 2380: 24 halved steps) or stops after 30
steps, after which the fast path removed that pair and tried again, or the
full solver took over (cases 311 and 2115 below, full solver on c32a8c3).
With ``merge`` the pair that blocks three full steps in a row is removed
at once.  A pair merged that the optimum needs (a narrow blip: case 1342)
comes back through the certificate's zeros; the structure with it is not
counted as tried, or the fast path would stop there and hand over to the
full solver.
"""

from __future__ import annotations

import numpy as np
import pytest
from reference_solutions import bang_bang_final_error

from flexmotion_ros.core import ModalModel
from flexmotion_ros.core.model.boundary import state_to_rest
from flexmotion_ros.core.results import SolverPath
from flexmotion_ros.core.time_optimal.solver import plan_time_optimal
from flexmotion_ros.core.time_optimal.switch_newton import MERGE_RTOL, merging_pair

#: bench/fuzz.py, seed 15: (model, u_max, x0, target).
CASES = {
    311: (
        ModalModel(b0=2.1885062220257296, c=0.0, omega=(0.7168818098834637, 3.5036369044606257, 50.33433868581297),
                   zeta=(0.26871412169670805, 0.001467440925726915, 0.159300893239299),
                   b=(0.8459860147673833, 0.2767607762423407, -0.18760063713152386)),
        4.676306491264718,
        [0.0, 318.8546506076175, 108.66146954196327, -142.47412626336885, -0.9170091515157658, -8.787795737493111,
         -0.007137549947846005, 0.206928577078106],
        570.0964191880214,
    ),
    2115: (
        ModalModel(b0=4.0925223359861045, c=0.0,
                   omega=(0.9932705531819379, 3.0224569816362745, 27.966109970580092, 36.99321751752548),
                   zeta=(0.022247608984573564, 0.07118337995241457, 0.08117757032185983, 0.031329693166141925),
                   b=(0.4982480244203108, -0.9826607298908375, -1.1263553472121608, 1.751674332759536)),
        7.555263416265503,
        [0.0] * 10,
        3405.1017329537567,
    ),
    1342: (
        ModalModel(b0=0.1370090904548421, c=-0.8513039329040137,
                   omega=(0.8083953157427641, 1.8621872921361629, 15.408088830869461, 56.151526515922015),
                   zeta=(0.13759623896571432, 0.06841462059930956, 0.09957406134405422, 0.08172926698382336),
                   b=(1.9435465541769388, -0.4721961020467858, -0.0605718074480072, -0.3882452573956973)),
        0.8951219049306757,
        [0.0] * 10,
        4.3068369516870355,
    ),
}  # fmt: skip


@pytest.mark.parametrize("index", sorted(CASES))
def test_the_fast_path_answers_certified(index):
    # c32a8c3: 311 and 2115 by the full solver (the fast path's runs crawled or stalled on a merging pair);
    # 1342 by the full solver when a merged pair's structure counted as tried
    model, u_max, x0, target = CASES[index]
    problem = state_to_rest(model, u_max, np.asarray(x0), target)
    profile = plan_time_optimal(problem)
    assert profile.certified, profile.certificate.message
    assert bang_bang_final_error(problem, profile) <= 1e-9
    assert np.all(np.abs(profile.levels) <= u_max)
    assert profile.extra["solver_path"] is SolverPath.FAST


def test_merging_pair_is_the_one_close_pair_a_step_crosses():
    T = 10.0
    tau = np.array([1.0, 2.0, 2.0 + 0.5 * MERGE_RTOL * T, 5.0])
    assert merging_pair(tau, np.array([0.0, 0.01, -0.01, 0.0]), T) == 1
    assert merging_pair(tau, np.array([0.0, 0.001, -0.001, 0.0]), T) is None  # not crossed
    wide = np.array([1.0, 2.0, 2.0 + 2.0 * MERGE_RTOL * T, 5.0])
    assert merging_pair(wide, np.array([0.0, 0.1, -0.1, 0.0]), T) is None  # not close: a structure to keep
    assert merging_pair(tau, np.array([0.0, 0.01, -0.01, -3.5]), T) is None  # two crossings
    assert merging_pair(tau, np.array([-1.5, 0.01, -0.01, 0.0]), T) is None  # the first switch leaves at 0
