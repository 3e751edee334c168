"""The switch-sample sequence walks its free samples to the sampled switches (``switch_samples._walk``).

A replan from a moving, vibrating state of a 3-mode chain (``bench/replan_latency.py``)
has its sampled switches 1-3 samples from where the continuous optimum's
switching function changes sign; the swaps to the neighbouring sample did not
reach them, and the ZOH stage solved the peak LP (about 2 ms of a 7 ms replan)
in 48 of the bench's 200 3-mode states.  The walk finds the sequence without an
LP; the count and its proof are the LP path's, and it lands exactly
(matrix-exponential simulation) within the bound.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexmotion_ros.core import chain, plan_time_optimal, plan_time_optimal_zoh, state_to_rest
from flexmotion_ros.core.sampled import switch_samples, zoh

from .test_zoh_shortcuts import check_lands, old_path, replan_states

#: States of the bench's 3-mode replans (seed 0, states 0, 1 and 8: carried 10 samples to the splice) whose
#: sampled switches lie 1-3 samples from the signs' guess; the old search solved an LP for each.
STATES = (
    (2.2416944352259223, 1.3565100214985193, -0.0015182103322460738, -0.14176552435348114,
     -0.004012449007321939, -0.35089026488719943, 0.007858395839678891, 0.4665353521435926),
    (0.36487749874949144, 2.1188499362905637, 0.01764304543795354, 0.5976063047622554,
     0.015000632071611644, 0.46366160302300674, -0.004250706017513424, -0.3377184877304903),
    (0.5383128424913544, 2.3517742138536435, 0.029362583193032393, -0.1377040987935519,
     0.00013343314860890136, 0.05413050590988046, -0.004131287141069243, 0.07424271698738663),
)  # fmt: skip


@pytest.mark.parametrize("state", STATES)
def test_walk_takes_no_lp_and_gives_the_lp_paths_count(state):
    model = chain([0.5] * 4, [400.0] * 3, [0.4] * 3).model
    problem = state_to_rest(model, 10.0, np.array(state), 2.5)
    continuous = plan_time_optimal(problem)

    def no_lp(*args, **kwargs):
        raise AssertionError("an LP was solved")

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(zoh, "solve_peak_lp", no_lp)
        new = plan_time_optimal_zoh(problem, 1000.0, continuous)
    with pytest.MonkeyPatch.context() as mp:
        old_path(mp)
        old = plan_time_optimal_zoh(problem, 1000.0, continuous)
    assert new.samples == old.samples and new.minimal and old.minimal
    check_lands(problem, new)


def test_walk_answers_more_replans_with_the_same_counts():
    """Twelve 3-mode replan states: more answered without an LP than with the swaps alone, same counts."""
    hits = {0: 0, switch_samples.WALK_ROUNDS: 0}
    taken = []
    real = switch_samples.switch_sample_sequence

    def recorded(*args):
        taken.append(real(*args))
        return taken[-1]

    for problem in replan_states(3, 12):
        continuous = plan_time_optimal(problem)
        counts = set()
        for rounds in hits:
            taken.clear()
            with pytest.MonkeyPatch.context() as mp:
                mp.setattr(switch_samples, "WALK_ROUNDS", rounds)
                mp.setattr(zoh, "switch_sample_sequence", recorded)
                new = plan_time_optimal_zoh(problem, 1000.0, continuous)
            hits[rounds] += taken[0] is not None
            counts.add((new.samples, new.minimal))
            check_lands(problem, new)
        with pytest.MonkeyPatch.context() as mp:
            old_path(mp)
            old = plan_time_optimal_zoh(problem, 1000.0, continuous)
        assert counts == {(old.samples, old.minimal)}
    assert hits[switch_samples.WALK_ROUNDS] >= hits[0] + 2


@pytest.mark.parametrize("d", [0, 1, 2])
def test_min_peak_factorises_once(d):
    """``_min_peak`` takes its least-norm point from the SVD it needs anyway: no least-squares solves, same point."""
    rng = np.random.default_rng(d)
    M = rng.standard_normal((8, 8 + d))
    w = rng.standard_normal(8)
    calls = []
    real = np.linalg.lstsq
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(np.linalg, "lstsq", lambda *a, **k: calls.append(1) or real(*a, **k))
        x, x0 = switch_samples._min_peak(M, w)
    assert not calls
    ref = switch_samples._solve(M, w)
    assert np.max(np.abs(x0 - ref)) <= 1e-13 * np.max(np.abs(ref))
    assert np.max(np.abs(M @ x0 - w)) <= 1e-13 * np.max(np.abs(w))


def test_square_pattern_with_nothing_pinned_is_solved_once():
    """A square pattern (as many unknowns as states) with no free sample at the peak: one SVD, no re-solve."""
    rng = np.random.default_rng(5)
    K, n = 40, 4
    G = rng.standard_normal((K, n))
    signs = np.where(np.arange(K) < 20, 1.0, -1.0)
    free = np.array([5, 19, 31])  # three free samples and the peak: 4 unknowns, 4 equations
    u_true = signs * 2.0
    u_true[free] = [0.5, -1.0, 1.5]
    w = G.T @ u_true
    calls = []
    real = switch_samples._solve
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(switch_samples, "_solve", lambda *a: calls.append(1) or real(*a))
        u, over, v = switch_samples._sequence_on(G, w, signs, free, 3.0)
    assert not calls
    assert np.max(np.abs(u - u_true)) <= 1e-12
