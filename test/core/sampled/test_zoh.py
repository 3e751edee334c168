"""The fast paths of ``core.zoh`` (scaled peak LP, factorised exact correction).

* The two slow cases of ``bench/planner_latency.py`` (1 kHz, rest-to-rest,
  ``chain([0.5]*(n+1), [400.0]*n, [0.4]*n)``, u_max 10 N): 5 modes / 0.8333 m,
  whose windowed LPs fail and a full-horizon LP decides, and 8 modes / 13.89 m
  (5 s), must give the same sample count and commands (to 1e-9) as the
  planner before the fast paths.  The reference commands were recorded from
  that planner; they are stored below quantised to 1e-11 N (delta-encoded
  int64, zlib, base64).  The fewest count must be proved, and ``K - 1`` is
  re-proved infeasible here by a full LP in the direct ``min t`` form.
* ``solve_peak_lp`` (scaled form ``max s``) agrees with the direct ``min t``
  form on random windowed problems: peak, commands, dual vector.
* ``correct_exactly``'s factorised least-norm solve equals ``np.linalg.lstsq``,
  also on rank-deficient sample sets.
"""

from __future__ import annotations

import base64
import zlib

import numpy as np
import pytest
from scipy.optimize import linprog

from flexmotion_ros.core import (
    chain,
    plan_time_optimal,
    plan_time_optimal_zoh,
    rest_to_rest,
)
from flexmotion_ros.core.sampled import correction, peak_lp, zoh
from flexmotion_ros.core.sampled.lp_tools import sample_vectors
from flexmotion_ros.core.simulation.exact import simulate_samples
from flexmotion_ros.core.simulation.modal_response import ModalResponse
from flexmotion_ros.core.time_optimal.reachable_set import state_scale

U_MAX = 10.0
RATE = 1000.0

#: (modes, rigid-body time s) -> (samples, commands before the fast paths)
REFERENCE = {
    (5, 1.0): (
        1037,
        (
            "eNq7vDdt6wuGUTAKRsEoGAWjYBSMgqEP/kMBI5RfrHh27V0gv/eeUZASGeYxopk7GsKjYBTQD+DK"
            "fxLr/RZf+vf/v9PVxx+j6ZAv+9aFn9kCsvds6TwZxtF4GSpA8MCiPzHAdOJ5pH/GxRFcfu99LBW/"
            "FZhuX07fxC0zgvwd1WI0Ve/faL09WEHN7AVFj4C01gOdH+8oaOcRAhp6WRafgenAKOxEjDUR5QCp"
            "5o+CUTAKRgG9gHz31vx0IP2wxGvCjNF+6SgYBcMa7Do6NcYRSLtZZS3eN5rfR8EoGFTAIbxWcAew"
            "s5CmEhApSUVzDTSTNlsB87tW9IWHn4dgPxYAUeuH8w=="
        ),
    ),
    (8, 5.0): (
        5034,
        (
            "eNrt3D9IlGEcB/A7KqygwlzscDXEsqUlLjgxWlKkwCAaSg5sEMqzwSUqbLCga+hQhGhxKLgiFw/M"
            "SXJIQY3oDxUJQS4F0VARNN3T41hbaXBnn8/y410eHh6e5/n+3uF9v443PP6YAAAAAAAAAAAAAAAA"
            "AAAAAIDK0HBndmBfOYS1Gq+nON9/NZlIDJb6dnVYXgBgHfdHLaW+7KNYHxbnm2qTlTP/o5+nhzeE"
            "EJ5M1iw3h7Xr8/jVyFA+ezPWY6/Gm9qS1uN3vfUte1f2YSl/68ge+xCg4szO1Wc6Y36lD3yYmShX"
            "zz39+ulU7myc97Ybg6kz8fndzt2XUjFnMoWxH3XyBqDqDRTrFnfEmis1Ts/8g/esw9lTmztj7r05"
            "1HvuvdwAAP5Coe30t7nYp3Sllka3rGKc9olrB+/FvuT5l0x6SF8C/4Wlxctbu+P90bj/yvexsnMP"
            "AH/ibu3byU2xtrZ3v1iIefpg6sL527GP7v/UsXFYrgIAAAAAAAAAAADAulR4tj1/Mdau683h+Cr+"
            "P5DuOXH/ZTmE5dbcwskq/p7vJ7/6jhk="
        ),
    ),
}
QUANTUM = 1e-11  # N, of the stored reference


def decode(blob: str) -> np.ndarray:
    d = np.frombuffer(zlib.decompress(base64.b64decode(blob)), dtype="<i8")
    return np.cumsum(d) * QUANTUM


def bench_problem(n_modes: int, rigid_time: float):
    """As ``bench/planner_latency.py``: ``beam(n)`` and ``move_for(model, rigid_time)``."""
    model = chain([0.5] * (n_modes + 1), [400.0] * n_modes, [0.4] * n_modes, force_on=0).model
    gamma = abs(model.b0) * U_MAX * rigid_time**2 / 4.0
    return rest_to_rest(model, U_MAX, gamma)


def peak_lp_rows(G, w):
    """Full-horizon ``min t  s.t.  G^T u = w, |u_m| <= t`` in the direct form (dense rows)."""
    K = G.shape[0]
    I = np.eye(K)
    A_ub = np.block([[I, -np.ones((K, 1))], [-I, -np.ones((K, 1))]])
    cost = np.zeros(K + 1)
    cost[-1] = 1.0
    res = linprog(
        cost,
        A_ub=A_ub,
        b_ub=np.zeros(2 * K),
        A_eq=np.column_stack([G.T, np.zeros(G.shape[1])]),
        b_eq=w,
        bounds=[(None, None)] * K + [(0.0, None)],
        method="highs",
    )
    assert res.status == 0, res.message
    return float(res.x[-1]), np.asarray(res.eqlin.marginals, float)


@pytest.mark.parametrize("case", sorted(REFERENCE))
def test_benchmark_case_unchanged_and_proved(case):
    problem = bench_problem(*case)
    K_ref, blob = REFERENCE[case]
    u_ref = decode(blob)
    assert u_ref.size == K_ref
    prof = plan_time_optimal_zoh(problem, RATE)
    assert prof.samples == K_ref
    assert prof.minimal and prof.lower_bound_samples == prof.samples
    assert np.max(np.abs(prof.commands)) <= U_MAX
    assert np.max(np.abs(prof.commands - u_ref)) <= 1e-9 * U_MAX + QUANTUM
    # exact arrival, by matrix-exponential simulation
    X = simulate_samples(problem.model, problem.x0, prof.commands, prof.dt)
    dev = X - problem.model.rest_state(problem.target)
    assert np.max(np.abs(dev[-1]) / np.max(np.abs(dev), axis=0)) <= 1e-9


@pytest.mark.parametrize("case", sorted(REFERENCE))
def test_one_fewer_sample_infeasible_by_full_lp(case):
    """``K - 1`` samples: the direct full LP's peak and its dual bound exceed u_max."""
    problem = bench_problem(*case)
    K = REFERENCE[case][0] - 1
    dt = 1.0 / RATE
    system = ModalResponse(problem.model, problem.include_position)
    x0 = problem.shifted_initial()
    scale = state_scale(system, x0, U_MAX, plan_time_optimal(problem).duration)
    G = sample_vectors(system, K, dt) / scale
    w = -system.expm_x(K * dt, x0) / scale
    if K > 1500:  # the dense direct LP would be slow: the scaled form's dual bound
        sol = zoh.solve_peak_lp(G, w, np.ones(K), np.ones(K, dtype=bool))
        t_star, nu = sol[1], sol[2]
    else:
        t_star, nu = peak_lp_rows(G, w)
    assert t_star > U_MAX
    assert zoh.dual_bound(G, w, nu) > U_MAX * (1.0 + zoh.BOUND_RTOL)


def random_window_problem(rng, K=120, n=6):
    G = rng.standard_normal((K, n)) * np.exp(-0.02 * np.arange(K))[:, None]
    u_true = np.clip(rng.standard_normal(K), -1.0, 1.0) * 3.0
    w = G.T @ u_true
    signs = np.where(rng.standard_normal(K) >= 0.0, 1.0, -1.0)
    free = np.zeros(K, dtype=bool)
    free[rng.choice(K, size=40, replace=False)] = True
    free[:6] = True
    return G, w, signs, free


@pytest.mark.parametrize("seed", range(8))
def test_scaled_peak_lp_matches_direct_form(seed):
    rng = np.random.default_rng(seed)
    G, w, signs, free = random_window_problem(rng)
    fast = zoh.solve_peak_lp(G, w, signs, free)
    ref = peak_lp._solve_peak_lp_rows(G, w, signs, free)
    assert (fast is None) == (ref is None)
    if ref is None:
        return
    u, t, nu = fast
    _u_r, t_r, nu_r = ref
    assert t == pytest.approx(t_r, rel=1e-9)
    np.testing.assert_allclose(G.T @ u, w, atol=1e-8 * np.max(np.abs(w)))
    assert np.max(np.abs(u)) <= t * (1 + 1e-9)
    # the dual vector is the direct form's (same scale and sign): same bound
    assert zoh.dual_bound(G, w, nu) == pytest.approx(zoh.dual_bound(G, w, nu_r), rel=1e-7)
    assert float(nu @ w) == pytest.approx(float(nu_r @ w), rel=1e-7)


def test_peak_lp_zero_target():
    rng = np.random.default_rng(3)
    G = rng.standard_normal((50, 4))
    free = np.ones(50, dtype=bool)
    free[10:] = False
    u, t, _ = zoh.solve_peak_lp(G, np.zeros(4), np.ones(50), free)
    assert t == 0.0 and not np.any(u)


@pytest.mark.parametrize("rank_deficient", [False, True])
def test_least_norm_solver_matches_lstsq(rank_deficient):
    rng = np.random.default_rng(7)
    GS = rng.standard_normal((300, 8))
    if rank_deficient:
        GS[:, 5] = GS[:, 2] - 0.5 * GS[:, 1]
    r = rng.standard_normal(8)
    if rank_deficient:
        r = GS.T @ rng.standard_normal(300)  # consistent
    ref, *_ = np.linalg.lstsq(GS.T, r, rcond=None)
    np.testing.assert_allclose(correction._least_norm_solver(GS)(r), ref, rtol=1e-9, atol=1e-12 * np.max(np.abs(ref)))


def test_correct_exactly_lands_exactly_within_bound():
    rng = np.random.default_rng(11)
    G = rng.standard_normal((400, 10))
    u0 = np.clip(rng.standard_normal(400) * 5.0, -8.0, 8.0)
    w = G.T @ u0
    u_in = u0 + 1e-7 * rng.standard_normal(400)
    u = zoh.correct_exactly(G, w, u_in, 10.0)
    assert u is not None and np.max(np.abs(u)) <= 10.0
    assert np.max(np.abs(G.T @ u - w)) <= 1e-12 * np.max(np.abs(w))
    ref_du, *_ = np.linalg.lstsq(G.T, w - G.T @ u_in, rcond=None)
    np.testing.assert_allclose(u, u_in + ref_du, atol=1e-12)
