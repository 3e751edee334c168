"""The limited planner's sample-count search: no wasted probes, no repeated row rounds.

The search may only change the order and size of its LPs, never a claim: the
plans below are checked exact and within every limit by the helpers of
``test_planner`` (independent matrix-exponential simulation and a second LP
formulation for ``K - 1``).
"""

import math

import numpy as np

from flexmotion_ros.core import ModalModel, plan_time_optimal_zoh, rest_to_rest
from flexmotion_ros.core.constraints.level import Level
from flexmotion_ros.core.constraints.limits import Limits
from flexmotion_ros.core.constraints.planner import plan_limited_zoh

from .test_planner import check_every_limit, feasible_state_space

WB = ModalModel(b0=0.5, c=0.0, omega=[math.sqrt(2.0)], zeta=[0.0], b=[1.0])


def test_fewest_steps_down_from_a_feasible_guess_instead_of_bisecting():
    """A feasible first probe (the guess extrapolated from the coarser levels, usually within a
    sample of the answer) is followed by the count just below it, not by the midpoint towards the
    unlimited count (at 1 kHz hundreds of samples below: one wasted LP of a few hundred free
    samples, 0.2 s, per limit on the bench's 2 m move).  On the old search the second probe was 5314."""
    problem = rest_to_rest(WB, 1.0, 2.0)
    level = Level(problem, 1000.0, Limits(velocity_max=0.5), K_cap=10**6, lp=object())
    answer = 5596
    probed = []

    def probe(K):
        probed.append(K)
        level.t[K] = 0.9999 if K >= answer else 1.0004
        return level.t[K]

    level.probe = probe
    assert level.fewest(answer, 5033) == answer
    assert probed == [answer, answer - 1]
    # a guess a few samples high still ends on the first feasible count (doubling steps, then bisection)
    probed.clear()
    level.t.clear()
    assert level.fewest(answer + 5, 5033) == answer
    assert all(k >= answer - 8 for k in probed)


def test_rows_inside_runs_are_seeded_across_counts_and_levels():
    """Riding a deflection limit, every sample of a run needs its limit row; found one LP round at a
    time for every new count, they cost one extra LP per probe.  Seeded from the nearest solved count
    (or the coarser level's rows) the 250 Hz plan takes 14 LPs (18 before); it is the same plan:
    exact, within every limit, proved fewest, and ``K - 1`` independently infeasible."""
    problem = rest_to_rest(WB, 1.0, 2.0)
    rate = 250.0
    unlimited = plan_time_optimal_zoh(problem, rate)
    peak_q = float(np.max(np.abs(unlimited.states[:, 2])))
    limits = Limits(deflection_max=(0.6 * peak_q,))
    r = plan_limited_zoh(problem, rate, limits, unlimited)
    assert r.lp_solves <= 15
    check_every_limit(problem, r, limits)
    K = r.sampled.samples
    assert r.minimal and r.lower_bound_samples == K
    assert not feasible_state_space(problem, K - 1, 1.0 / rate, limits)
