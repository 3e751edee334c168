"""The exact check every sampled planner's sequence passes (core.sampled_check)."""

from __future__ import annotations

import numpy as np
import pytest

from flexmotion_ros.core import (
    ModalModel,
    motion_to_rest,
    plan_time_optimal_zoh,
    rest_to_rest,
)
from flexmotion_ros.core.errors import SolverError
from flexmotion_ros.core.sampled.check import verified_samples

WB = ModalModel(b0=0.5, c=0.0, omega=[2**0.5], zeta=[0.0], b=[1.0])


def test_the_zoh_optimum_passes_and_a_perturbed_one_is_refused():
    problem = rest_to_rest(WB, 1.0, 1.0)
    z = plan_time_optimal_zoh(problem, 50.0)
    ok = verified_samples(problem, z.commands, z.dt, "zoh", True, z.samples)
    assert ok.final_state_error_relative < 1e-12 and ok.method == "zoh"
    bad = z.commands.copy()
    assert abs(bad[50]) > 0.5
    bad[50] *= 1.0 - 1e-6  # one sample 1e-6 off: a miss of ~1e-8 of the state scale, above 1e-9
    with pytest.raises(SolverError, match="misses the target"):
        verified_samples(problem, bad, z.dt, "zoh", True, z.samples)


def test_a_command_above_the_bound_is_refused_even_if_it_arrives():
    problem = rest_to_rest(WB, 1.0, 1.0)
    z = plan_time_optimal_zoh(problem, 50.0)
    with pytest.raises(SolverError, match="exceeds u_max"):
        # the 50 Hz optimum's least peak is 0.998 N: a bound of 0.99 N refuses it
        verified_samples(rest_to_rest(WB, 0.99, 1.0), z.commands, z.dt, "zoh", True, z.samples)


def test_free_final_position_is_not_checked():
    problem = motion_to_rest(WB, 1.0, 0.5)
    z = plan_time_optimal_zoh(problem, 50.0)
    out = verified_samples(problem, z.commands, z.dt, "zoh", True, z.samples)
    assert abs(out.states[-1][0]) > 0.01  # it moved, and may stop anywhere
    assert np.max(np.abs(out.states[-1][1:])) < 1e-9
