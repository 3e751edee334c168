"""Exact ZOH optimum with m inputs: fewest samples, bounds, exact arrival, and K - 1 proved infeasible
by an independent LP (HiGHS interior point, dense rows built here from scipy's expm)."""

from __future__ import annotations

import numpy as np
import pytest

from flexmotion_ros.core import ModalModel, plan_time_optimal_zoh, rest_to_rest
from flexmotion_ros.core.multi_input import MultiModel, multi_rest_to_rest, multi_state_to_rest
from flexmotion_ros.core.multi_input.builders import gantry, multi_chain
from flexmotion_ros.core.multi_input.zoh import plan_multi_time_optimal_zoh

from . import independent as ind


def check_sequence(problem, sp):
    dt = sp.dt
    K = sp.samples
    xT = ind.final_state(problem, dt * np.arange(K + 1), sp.commands)
    assert ind.relative_error(problem, xT, K * dt, problem.u_max) < 1e-9
    assert np.all(np.abs(sp.commands) <= problem.u_max)
    assert sp.commands.shape == (K, problem.model.m)


def check_fewest(problem, sp):
    """K samples reach rest (LP peak <= 1), K - 1 cannot (LP peak > 1 and its dual bound > 1, computed here)."""
    peak_K, _ = ind.zoh_lp_peak(problem, sp.samples, sp.dt)
    assert peak_K <= 1.0 + 1e-7
    peak, bound = ind.zoh_lp_peak(problem, sp.samples - 1, sp.dt)
    assert peak > 1.0 and bound[0] > 1.0


@pytest.mark.parametrize("sync", ["time", "none", "phase"])
def test_gantry_at_a_coarse_rate(sync):
    g = gantry(10.0, 40.0, 5.0, 2.0, trolley_force=30.0, bridge_force=50.0)
    p = multi_rest_to_rest(g.model, g.u_max, [3.0, 2.0])
    sp = plan_multi_time_optimal_zoh(p, 10.0, sync=sync)
    assert sp.minimal and sp.lower_bound_samples == sp.samples
    check_sequence(p, sp)
    if sync != "phase":
        check_fewest(p, sp)
    d = sp.to_dict()
    assert d["samples"] == sp.samples and all(len(r) == 2 for r in d["commands"])
    if sync == "time":  # both axes move until the last sample
        assert np.all(np.any(sp.commands[-3:] != 0.0, axis=0))


def test_coupled_chain_moving_start_at_a_coarse_rate():
    c = multi_chain([1.0, 0.8, 1.2], [60.0, 80.0], [0.1, 0.1], actuated=(0, 2), u_max=[5.0, 3.0])
    x0 = np.zeros(c.model.n_states)
    x0[1], x0[2], x0[5] = 0.3, 0.01, -0.05
    p = multi_state_to_rest(c.model, c.u_max, x0, [1.0])
    sp = plan_multi_time_optimal_zoh(p, 25.0)
    assert sp.minimal
    check_sequence(p, sp)
    check_fewest(p, sp)


def test_single_input_sample_count_equals_the_existing_planner():
    mm = ModalModel(b0=0.5, omega=[2**0.5], zeta=[0.0], b=[1.0])
    ref = plan_time_optimal_zoh(rest_to_rest(mm, 1.0, 1.0), 20.0)
    p = multi_rest_to_rest(MultiModel.from_modal(mm), [1.0], [1.0])
    sp = plan_multi_time_optimal_zoh(p, 20.0)
    assert sp.samples == ref.samples and sp.minimal
    check_sequence(p, sp)


def test_singular_input_at_a_coarse_rate():
    M = MultiModel(
        inputs=("u0", "u1", "u2"),
        rigid_bodies=("x",),
        b0=((-0.58, 0.0, -0.29),),
        c=(0.0,),
        omega=(0.88, 4.21),
        zeta=(0.002, 0.026),
        b=((0.4, 0.0, -0.7), (0.0, -0.94, 0.41)),
    )
    p = multi_rest_to_rest(M, [2.6, 4.2, 0.6], [0.3])
    sp = plan_multi_time_optimal_zoh(p, 20.0)
    assert sp.minimal
    check_sequence(p, sp)
    check_fewest(p, sp)
