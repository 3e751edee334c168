"""The smoothed warm start's line search: halvings evaluated several per pass, the same step chosen.

On a coarse grid the smoothed Newton steps of a chattering stop are cut 10-20
times; one pass over the grid per halving made the line search most of the
warm start.  :func:`~flexmotion_ros.core.time_optimal.smoothed_dual.armijo_step`
must choose the step halving one at a time chooses, in fewer passes.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexmotion_ros.core.time_optimal import smoothed_dual


def sequential(phi, f, dec, steps=smoothed_dual.LINE_SEARCH_STEPS):
    t = 1.0
    for _ in range(steps):
        if phi(t) <= f - 0.25 * t * dec:
            return t
        t *= 0.5
    return None


@pytest.mark.parametrize("seed", range(20))
def test_batched_halvings_choose_the_sequential_step_in_fewer_passes(seed):
    rng = np.random.default_rng(seed)
    # a convex objective along the line whose Newton step overshoots by 2^k
    k = int(rng.integers(0, 25))
    scale = 2.0**k
    a = rng.uniform(0.5, 2.0)

    def phi(t):
        x = scale * t - 1.0
        return a * np.sqrt(x * x + 1e-6)

    f = float(phi(0.0))
    dec = 2.0 * f
    passes = []

    def values(ts):
        passes.append(len(ts))
        return phi(np.asarray(ts))

    assert smoothed_dual.armijo_step(values, f, dec) == sequential(phi, f, dec)
    halvings = sum(passes)
    assert len(passes) <= 1 + -(-max(halvings - 1, 0) // smoothed_dual.LINE_SEARCH_BATCH)
    if halvings > 2:
        assert len(passes) < halvings  # one pass over the grid per halving before


def test_no_acceptable_step_gives_none():
    assert smoothed_dual.armijo_step(lambda ts: np.full(len(ts), 1.0), 0.5, 1.0) is None
