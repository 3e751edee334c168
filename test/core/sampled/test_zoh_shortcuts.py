"""The ZOH stage's shortcuts against the paths they replace.

* ``simulation.sample_grid.expm_x_grid`` (complex power products on the grid)
  equals ``ModalResponse.expm_x_many`` on the same grid to 1e-12 of each
  column's size, with and without the position state, with and without the
  rigid body's damping ``c``.
* ``sampled.zoh.grid_sample_vectors``, the sequence from the switching
  function's signs without an LP (``sampled.switch_samples``) and the exact
  correction on the LP's free windows (``correct_exactly(..., on=free)``): the exact ZOH
  optimum of random moves has the same (proved fewest) sample count and the
  same proof as with the old sample vectors and the correction spread over
  every sample, lands exactly (matrix-exponential simulation) and stays
  within the bound.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from reference_solutions import deviation_from_target

from flexmotion_ros.core import (
    ModalModel,
    SolverError,
    chain,
    plan_time_optimal,
    plan_time_optimal_zoh,
    rest_to_rest,
    simulate_samples,
    state_to_rest,
)
from flexmotion_ros.core.sampled import correction, lp_tools, switch_samples, zoh
from flexmotion_ros.core.simulation.modal_response import ModalResponse
from flexmotion_ros.core.simulation.sample_grid import expm_x_grid

from ..time_optimal.test_solver_properties import FINAL_RTOL, SETTINGS, WB, describe, safe_note
from .test_zoh import U_MAX, bench_problem
from .test_zoh_properties import NYQUIST_FRACTION, zoh_cases


def random_model(rng: np.random.Generator, damped_rigid: bool) -> ModalModel:
    n = int(rng.integers(1, 9))
    omega = tuple(np.sort(rng.uniform(0.3, 60.0, n)) * (1.0 + 0.01 * np.arange(n)))
    return ModalModel(
        b0=float(rng.uniform(0.1, 5.0)),
        c=-float(rng.uniform(0.01, 1.0)) if damped_rigid else 0.0,
        omega=omega,
        zeta=tuple(rng.uniform(0.0, 0.3, n)),
        b=tuple(rng.uniform(-2.0, 2.0, n)),
    )


@pytest.mark.parametrize("seed", range(12))
def test_grid_responses_equal_closed_forms(seed):
    rng = np.random.default_rng(seed)
    model = random_model(rng, damped_rigid=seed % 2 == 1)
    for include_position in (True, False):
        resp = ModalResponse(model, include_position=include_position)
        x = rng.standard_normal(resp.n)
        for K, dt in ((0, 1e-3), (1, 1e-3), (7, 0.05), (5003, 1e-3), (997, 0.011)):
            fast = expm_x_grid(resp, dt, K, x)
            ref = resp.expm_x_many(dt * np.arange(K), x)
            assert fast.shape == ref.shape == (K, resp.n)
            if K:
                size = np.maximum(np.max(np.abs(ref), axis=0), 1e-300)
                assert np.max(np.abs(fast - ref) / size) <= 1e-12
        ref = lp_tools.sample_vectors(resp, 400, 2e-3)
        fast = zoh.grid_sample_vectors(resp, 400, 2e-3)
        assert np.max(np.abs(fast - ref) / np.max(np.abs(ref), axis=0)) <= 1e-12


def old_path(mp: pytest.MonkeyPatch) -> None:
    """The ZOH stage before the shortcuts: ``expm_x_many`` sample vectors, the correction over every sample."""
    full = correction.correct_exactly
    mp.setattr(zoh, "SWITCH_SAMPLES", False)
    mp.setattr(zoh, "grid_sample_vectors", lp_tools.sample_vectors)
    mp.setattr(
        correction, "correct_exactly", lambda G, w, u, u_max, on=None: None if on is not None else full(G, w, u, u_max)
    )


def check_lands(problem, sp) -> None:
    cmds = np.asarray(sp.commands, float)
    assert np.all(np.abs(cmds) <= problem.u_max)
    X = simulate_samples(problem.model, problem.x0, cmds, sp.dt)
    dev, scale = deviation_from_target(problem, X)
    assert float(np.max(np.abs(dev[-1]) / scale)) <= FINAL_RTOL


@settings(max_examples=20, **SETTINGS)
@given(zoh_cases("state"))
def test_same_fewest_samples_as_the_old_path(case):
    problem, rate = case
    safe_note(describe(problem))
    continuous = plan_time_optimal(problem)
    T = continuous.duration
    wd_max = float(np.max(problem.model.omega_d)) if problem.model.n_modes else 0.0
    if T * rate > 800:  # as the property tests: keep K moderate, never below the Nyquist limit
        rate = max(800 / T, wd_max / (NYQUIST_FRACTION * math.pi))
    safe_note(f"rate_hz={rate!r}")
    with pytest.MonkeyPatch.context() as mp:
        old_path(mp)
        try:
            old = plan_time_optimal_zoh(problem, rate, continuous)
        except SolverError:  # e.g. a mode near the drawn rate's Nyquist limit: refused before, too
            old = None
    if old is None:
        try:
            check_lands(problem, plan_time_optimal_zoh(problem, rate, continuous))
        except SolverError:
            pass
        return
    new = plan_time_optimal_zoh(problem, rate, continuous)
    assert new.samples == old.samples
    assert new.minimal == old.minimal and new.lower_bound_samples == old.lower_bound_samples
    # the commands themselves may differ: a switching-function sign within rounding of zero can fall the
    # other way with vectors 1e-15 apart, and another window LP's point (peak within u_max) is as exact
    check_lands(problem, new)


@pytest.mark.parametrize(("modes", "switch_samples"), [(1, True), (3, True), (5, True), (8, False)])
def test_bench_move_same_as_old_path(modes, switch_samples):
    """``bench/planner_latency.py``'s 5 s move at 1 kHz: same count, proof and (to 1e-9 of u_max) commands.

    With 1-3 modes the switch-sample sequence is taken (no LP, no correction); with 5 too since its free
    samples walk to the sampled switches (``switch_samples._walk``); with 8 the sampled structure is not
    the continuous one, and the LP path decides (the correction on its windows).
    """
    problem = bench_problem(modes, 5.0)
    continuous = plan_time_optimal(problem)
    calls = []
    real = correction.correct_exactly
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(
            correction, "correct_exactly", lambda *a, **k: calls.append(k.get("on") is not None) or real(*a, **k)
        )
        new = plan_time_optimal_zoh(problem, 1000.0, continuous)
    assert calls == ([] if switch_samples else [True])  # never the K x n factorisation
    with pytest.MonkeyPatch.context() as mp:
        old_path(mp)
        old = plan_time_optimal_zoh(problem, 1000.0, continuous)
    assert new.samples == old.samples and new.minimal and old.minimal
    check_lands(problem, new)
    assert np.max(np.abs(new.commands - old.commands)) <= 1e-9 * U_MAX


@pytest.mark.parametrize(("goal", "rate"), [(1.0, 50.0), (0.5, 1000.0), (-3.0, 200.0)])
def test_switch_samples_take_no_lp_and_give_the_lp_vertex(goal, rate):
    """Wie-Bernstein: the sequence from the signs is the LP's vertex (to rounding), with no LP solved."""
    problem = rest_to_rest(WB, 1.0, goal)
    continuous = plan_time_optimal(problem)

    def no_lp(*args, **kwargs):
        raise AssertionError("an LP was solved")

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(zoh, "solve_peak_lp", no_lp)
        new = plan_time_optimal_zoh(problem, rate, continuous)
    with pytest.MonkeyPatch.context() as mp:
        old_path(mp)
        old = plan_time_optimal_zoh(problem, rate, continuous)
    assert new.samples == old.samples and new.minimal and old.minimal
    check_lands(problem, new)
    assert np.max(np.abs(new.commands - old.commands)) <= 1e-9 * problem.u_max


def replan_states(modes: int, count: int, seed: int = 0):
    """As ``bench/replan_latency.py``: moving, vibrating states along a 1 kHz rest-to-rest move of a chain."""
    rng = np.random.default_rng(seed)
    model = chain([0.5] * (modes + 1), [400.0] * modes, [0.4] * modes).model
    gamma = 0.5 * abs(model.b0) * 10.0
    nominal = plan_time_optimal_zoh(rest_to_rest(model, 10.0, gamma), 1000.0)
    excursion = np.max(np.abs(nominal.states[:, 2::2]), axis=0)
    for _ in range(count):
        x = nominal.states[int(rng.uniform(0.1, 0.9) * nominal.samples)].copy()
        x += model.B() * rng.uniform(-0.5, 0.5)
        x[2::2] += 0.3 * excursion * rng.uniform(-1.0, 1.0, modes)
        yield state_to_rest(model, 10.0, x, gamma)


def test_switch_samples_move_a_free_sample_to_its_switchs_other_sample():
    """Replans from vibrating states: most sampled switches fall one sample from the signs' guess.

    With the move to the neighbour (``SWAP_ROUNDS``) 8 of these 12 need no LP (5 without it);
    every count is the LP path's.
    """
    hits = {1: 0, 3: 0}
    taken = []
    real = switch_samples.switch_sample_sequence

    def recorded(*args):
        taken.append(real(*args))
        return taken[-1]

    for rounds in hits:
        for problem in replan_states(1, 12):
            continuous = plan_time_optimal(problem)
            taken.clear()
            with pytest.MonkeyPatch.context() as mp:
                mp.setattr(switch_samples, "SWAP_ROUNDS", rounds)
                mp.setattr(switch_samples, "WALK_ROUNDS", 0)  # the swaps alone (the walk: test_switch_walk.py)
                mp.setattr(zoh, "switch_sample_sequence", recorded)
                new = plan_time_optimal_zoh(problem, 1000.0, continuous)
            hits[rounds] += taken[0] is not None
            with pytest.MonkeyPatch.context() as mp:
                old_path(mp)
                old = plan_time_optimal_zoh(problem, 1000.0, continuous)
            assert new.samples == old.samples and new.minimal == old.minimal
            check_lands(problem, new)
    assert hits[3] >= hits[1] + 2
