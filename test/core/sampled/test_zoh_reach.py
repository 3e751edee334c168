"""``reaches_rest_within``: the one-LP feasibility verdict that gates the short-move search."""

from __future__ import annotations

import numpy as np
import pytest

from flexmotion_ros.core.config import PlannerConfig
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.model.boundary import state_to_rest
from flexmotion_ros.core.model.modal_model import ModalModel
from flexmotion_ros.core.sampled.zoh import reaches_rest_within
from flexmotion_ros.core.simulation.prepared import prepare

WB = ModalModel(b0=0.5, c=0.0, omega=(2**0.5,), zeta=(0.0,), b=(1.0,))


@pytest.mark.parametrize("seed", range(6))
def test_the_verdict_agrees_with_the_fewest_samples_of_a_small_correction(seed):
    # a vibrating state near its target: a rigid-body bound of a few samples, an answer of 100+ (the feedback
    # loop's replans); the short-move search tried 48 counts here (0.3-1.2 s) before this one-LP gate
    rng = np.random.default_rng(seed)
    x0 = np.array([0.5, 0.0, 0.0, 0.0]) + rng.normal(0.0, 1e-2, 4)
    problem = state_to_rest(WB, 1.0, x0, 0.5)
    result = plan_move(PlannerConfig(model=WB, u_max=1.0, rate_hz=100.0), problem, 100.0)
    K = result.sampled.samples
    assert result.sampled.minimal  # every count below K is proved infeasible by the planner's own search
    move = prepare(problem)
    assert reaches_rest_within(move, 0.01, K) is True
    assert reaches_rest_within(move, 0.01, K + 7) is True  # monotone: holds after arriving
    assert reaches_rest_within(move, 0.01, K - 1) is False
    assert reaches_rest_within(move, 0.01, max(1, K - 40)) is False
