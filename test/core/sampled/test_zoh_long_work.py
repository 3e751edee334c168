"""Work bounds of the 1 kHz ZOH stage on long moves (issue 15: a 26-40 min move hung the fuzz for 17-25 s).

Three bounds, each checked by counting work, not by timing it: the peak LP's unpresolved dual simplex
stops at an iteration limit (HiGHS then presolves), the least-norm correction over ``K >> n`` samples goes
through the ``n x n`` Gram matrix (no ``K x n`` QR), and the count search stops after
``SAMPLE_BUDGET / K_lo`` counts with a one-line refusal.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexmotion_ros.core.errors import SolverError
from flexmotion_ros.core.model.boundary import state_to_rest
from flexmotion_ros.core.model.modal_model import ModalModel
from flexmotion_ros.core.sampled import correction, peak_lp, zoh
from flexmotion_ros.core.sampled.correction import correct_exactly, lands_exactly
from flexmotion_ros.core.sampled.peak_lp import grid_sample_vectors, solve_peak_lp
from flexmotion_ros.core.simulation.prepared import prepare
from flexmotion_ros.core.time_optimal.solver import plan_time_optimal

WB = ModalModel(b0=0.5, c=0.0, omega=(2**0.5,), zeta=(0.05,), b=(1.0,))


def _scaled(problem, K: int, dt: float):
    move = prepare(problem)
    scale = move.error_scale(K * dt)
    G = grid_sample_vectors(move.response, K, dt) / scale
    w = -move.response.expm_x(K * dt, move.x0) / scale
    return move, G, w


def test_the_peak_lp_runs_under_an_iteration_limit_and_the_presolved_solve_answers_past_it(monkeypatch):
    problem = state_to_rest(WB, 1.0, np.zeros(4), 2.0)
    T = plan_time_optimal(problem).duration
    K = int(np.ceil(T / 0.01)) + 3
    _, G, w = _scaled(problem, K, 0.01)
    S = G @ np.array([0.0, 1.0, 0.3, -0.2])  # any signs: the windows only shape the LP
    signs = np.where(S >= 0.0, 1.0, -1.0)
    free = np.ones(K, dtype=bool)
    calls = []
    solve = peak_lp.solve_lp

    def recording(**kw):
        res = solve(**kw)
        calls.append((kw.get("iteration_limit"), res.status))
        return res

    monkeypatch.setattr(peak_lp, "solve_lp", recording)
    u, t, _ = solve_peak_lp(G, w, signs, free)
    # the first (unpresolved) solve is bounded: a long move's wide windows took 84,455 iterations (8 s) there
    assert calls[0][0] is not None and calls[0][0] <= peak_lp.PEAK_LP_ITERATIONS + 2 * K
    # past the limit HiGHS's presolve answers: the same optimum
    calls.clear()
    monkeypatch.setattr(peak_lp, "peak_lp_iterations", lambda columns: 1)
    u1, t1, _ = solve_peak_lp(G, w, signs, free)
    assert calls[0][0] == 1 and calls[0][1] is peak_lp.LpStatus.TIME_LIMIT and len(calls) == 2
    assert t1 == pytest.approx(t, rel=1e-7)
    assert np.max(np.abs(G.T @ u1 - w)) <= 1e-7 * max(1.0, float(np.max(np.abs(w))))


def test_a_correction_over_many_samples_factorises_no_tall_matrix(monkeypatch):
    # 150,000 samples (150 s at 1 kHz): the QR of the 150,000 x 4 matrix and its Q product were ~1 s per
    # correction at 2.4e6 samples; the Gram matrix is 4 x 4
    K = 150_000
    problem = state_to_rest(WB, 1.0, np.zeros(4), 3.0)
    _, G, _ = _scaled(problem, K, 0.001)
    rng = np.random.default_rng(3)
    u_true = 0.9 * np.sign(np.sin(np.arange(K) * 2e-4 + 0.3))
    w = G.T @ u_true
    u = u_true + rng.normal(0.0, 1e-9, K)  # an LP point: its rows met to the solver's tolerance

    def no_qr(*args, **kwargs):
        raise AssertionError("a K x n QR")

    factorised = []
    inner = correction._least_norm_solver

    def recording(GS):
        factorised.append(np.shares_memory(GS, G))
        return inner(GS)

    monkeypatch.setattr(correction, "qr", no_qr)
    monkeypatch.setattr(correction, "_least_norm_solver", recording)
    fixed = correct_exactly(G, w, u, 1.0)
    assert factorised and all(factorised)  # every sample has slack: G itself, no K x n copy
    assert fixed is not None and lands_exactly(G, w, fixed)
    assert np.max(np.abs(fixed)) <= 1.0
    assert np.max(np.abs(fixed - u)) <= 1e-6  # a least-norm change: spread thin, not a jump


def test_the_count_search_of_a_long_move_is_bounded_and_refuses_in_one_line(monkeypatch):
    # a 20 s move at 1 kHz (K_lo ~ 20,000) whose every candidate fails the exact check: before, 201 counts
    # (a 1.6e6-sample move: ~3 s each, minutes); now SAMPLE_BUDGET / K_lo of them (here 8) and one line
    problem = state_to_rest(WB, 1.0, np.zeros(4), 50.0)
    continuous = plan_time_optimal(problem)
    tried = []
    inner = zoh.switch_sample_sequence

    def counting(G, w, S, u_max):
        tried.append(G.shape[0])
        return inner(G, w, S, u_max)

    def failing(*args, **kwargs):
        raise SolverError("forced: the exact check fails")

    monkeypatch.setattr(zoh, "switch_sample_sequence", counting)
    monkeypatch.setattr(zoh, "finish_sampled", failing)
    monkeypatch.setattr(zoh, "SAMPLE_BUDGET", 100_000, raising=False)
    with pytest.raises(SolverError) as info:
        zoh.plan_time_optimal_zoh(problem, 1000.0, continuous)
    K_lo = int(np.ceil(continuous.duration * 1000.0 * (1.0 - 1e-12)))
    assert K_lo > 10_000
    assert len(set(tried)) <= 9  # MIN_EXTRA_SAMPLES + 1 counts
    assert max(tried) <= K_lo + 8
    text = str(info.value)
    assert "lower the rate" in text and "\n" not in text


def test_extra_samples_keeps_the_full_range_for_moves_up_to_100k_samples():
    assert zoh.extra_samples(1) == zoh.MAX_EXTRA_SAMPLES
    assert zoh.extra_samples(100_000) == zoh.MAX_EXTRA_SAMPLES
    assert zoh.extra_samples(1_600_000) == 12
    assert zoh.extra_samples(5_000_000) == zoh.MIN_EXTRA_SAMPLES


class _CountingRows(np.ndarray):
    """Sample vectors that count the products over all their rows (``x @ G`` with ``G`` this array)."""

    rows = 0
    full = 0

    def __rmatmul__(self, other):
        if self.shape[0] == _CountingRows.rows:
            _CountingRows.full += 1
        return np.asarray(other) @ np.asarray(self)


def test_the_switch_samples_of_a_long_move_sum_all_samples_once_per_count(monkeypatch):
    # the walk's patterns each formed signs @ G over every sample (O(K n), up to 11 per count: 2 s of a
    # 2.4e6-sample plan); past SUMMED_ROWS the sum is formed once and updated where the signs change.
    # A 3-mode replan whose walk takes 2+ patterns (test_switch_walk), with the long-move path forced on.
    from flexmotion_ros.core import chain, plan_time_optimal_zoh
    from flexmotion_ros.core.sampled import switch_samples

    from .test_switch_walk import STATES

    model = chain([0.5] * 4, [400.0] * 3, [0.4] * 3).model
    problem = state_to_rest(model, 10.0, np.array(STATES[0]), 2.5)
    continuous = plan_time_optimal(problem)
    reference = plan_time_optimal_zoh(problem, 1000.0, continuous)
    tries = []
    inner_seq = switch_samples._sequence_on

    def counting_seq(*args, **kwargs):
        tries.append(1)
        return inner_seq(*args, **kwargs)

    calls = []
    inner = zoh.switch_sample_sequence

    def counting(G, w, S, u_max):
        _CountingRows.rows, _CountingRows.full = G.shape[0], 0
        out = inner(G.view(_CountingRows), w, S, u_max)
        calls.append(_CountingRows.full)
        return None if out is None else np.asarray(out)

    monkeypatch.setattr(switch_samples, "SUMMED_ROWS", 0, raising=False)
    monkeypatch.setattr(switch_samples, "_sequence_on", counting_seq)
    monkeypatch.setattr(zoh, "switch_sample_sequence", counting)
    new = plan_time_optimal_zoh(problem, 1000.0, continuous)
    assert len(tries) >= 2  # the walk ran: the old code summed every sample per try
    assert calls and max(calls) == 1
    assert new.samples == reference.samples and new.minimal == reference.minimal
    assert np.max(np.abs(new.commands - reference.commands)) <= 1e-9 * problem.u_max
