"""The sampled friction LP, its exact commands and the structure read from a sampled move.

References: a dense LP written here (every velocity row explicit, ``min t`` with
``|u_k| <= t`` rows: the textbook form, not the scaled chain form under test),
and the event-located friction simulation with matrix exponentials.
"""

import math
import types

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.optimize import linprog

from flexmotion_ros.core import ModalModel, MoveProblem, plan_time_optimal, rest_to_rest, simulate
from flexmotion_ros.core.friction.contact import simulate_coulomb
from flexmotion_ros.core.friction.pattern_search import consistent_pattern, count_for_peak, fastest_samples
from flexmotion_ros.core.friction.sampled_lp import FrictionLP
from flexmotion_ros.core.friction.structure import bang_bang_guess, has_stick_arcs
from flexmotion_ros.core.simulation.exact import PiecewiseConstant

WB = ModalModel(b0=0.5, c=0.0, omega=[math.sqrt(2.0)], zeta=[0.0], b=[1.0])
# issue 18's friction reproducer: the time-optimal move rests on the way (stick arcs)
REPRO = ModalModel(
    b0=0.27336967201641243,
    c=0.0,
    omega=(0.41991476607082023, 3.194567184025729, 5.752751792341, 51.213173874446255),
    zeta=(0.018484257053140062, 0.10486902847816988, 0.0, 0.27982379019089254),
    b=(0.3847736811881417, -0.505944946955234, -0.4246379851543105, 0.49891839486279355),
)
REPRO_U, REPRO_GOAL, REPRO_F = 1.9268024392824576, -0.4781025580990753, 0.6088932026978997


def dense_least_peak(problem, F, K, dt, s):
    """min t s.t. |u_k| <= t, arrival at rest, s v_j >= 0 on both sides of every instant (dense, expm)."""
    model = problem.model
    A, B = model.A(), model.B()
    n = A.shape[0]
    M = np.zeros((n + 2, n + 2))
    M[:n, :n], M[:n, n] = A * dt, B * dt
    g = np.zeros(n)
    g[1] = abs(model.b0)
    M[:n, n + 1] = -F * g * dt
    E = expm(M)
    Phi, Gam, Fr = E[:n, :n], E[:n, n], E[:n, n + 1]  # Fr: effect of the friction of sign +1 over one sample
    xf = model.rest_state(problem.target)
    # x_k = Phi^k x0 + sum_m Phi^(k-1-m) (Gam u_m + Fr s_m)
    P = [np.eye(n)]
    for _ in range(K):
        P.append(Phi @ P[-1])
    X_u = np.zeros((K + 1, n, K))
    x_c = np.zeros((K + 1, n))
    for k in range(K + 1):
        x_c[k] = P[k] @ problem.x0
        for m in range(k):
            X_u[k, :, m] = P[k - 1 - m] @ Gam
            x_c[k] += P[k - 1 - m] @ Fr * s[m]
    nv = K + 1
    cost = np.zeros(nv)
    cost[-1] = 1.0
    rows, rhs = [], []
    for k in range(K):
        for sg in (1.0, -1.0):
            r = np.zeros(nv)
            r[k], r[-1] = sg, -1.0
            rows.append(r)
            rhs.append(0.0)
    for j in range(1, K):
        for sd in {s[j - 1], s[j]}:
            r = np.zeros(nv)
            r[:K] = -sd * X_u[j, 1]
            rows.append(r)
            rhs.append(sd * x_c[j, 1])
    A_eq = np.column_stack([X_u[K], np.zeros(n)])
    res = linprog(
        cost,
        A_ub=np.array(rows),
        b_ub=np.array(rhs),
        A_eq=A_eq,
        b_eq=xf - x_c[K],
        bounds=[(None, None)] * K + [(0, None)],
    )
    assert res.status in (0, 2)
    return res.x[-1] if res.status == 0 else None


@pytest.mark.parametrize("K, reversal", [(52, None), (60, None), (60, 20)])
def test_least_peak_matches_the_dense_reference(K, reversal):
    problem = rest_to_rest(WB, 1.0, 2.0)
    dt, F = 0.1, 0.2
    s = np.ones(K)
    if reversal is not None:
        s[reversal : reversal + 10] = -1.0
    lp = FrictionLP(problem, F, dt)
    ref = dense_least_peak(problem, F, K, dt, s)
    chain = lp.solve(K, s)
    window = lp.solve_windowed(K, s, np.ones(K, bool), np.ones(K))
    if ref is None:
        assert chain is None and window is None
        return
    assert chain.t == pytest.approx(ref, rel=1e-8)
    assert window.t == pytest.approx(ref, rel=1e-8)


def test_windowed_lp_holds_the_samples_outside_its_windows():
    """Windows around the sign changes of the full optimum, the rest held at its signs: the window LP
    holds them at +-t and finds the same least peak (the full optimum is one of its points)."""
    problem = rest_to_rest(WB, 1.0, 2.0)
    lp = FrictionLP(problem, 0.2, 0.05)
    K = 104
    full = lp.solve(K, np.ones(K))
    sigma = np.sign(full.u)
    sat = np.abs(full.u) >= full.t * (1.0 - 1e-9)
    free = ~sat
    for k in np.flatnonzero(~sat):
        free[max(0, k - 2) : k + 3] = True
    free[:3] = free[-3:] = True
    assert free.sum() < K // 2
    sol = lp.solve_windowed(K, np.ones(K), free, sigma)
    assert sol is not None
    assert np.allclose(sol.u[~free], sigma[~free] * sol.t, rtol=0, atol=1e-12 * sol.t)
    assert sol.t == pytest.approx(full.t, rel=1e-9)


def test_sampled_move_with_stick_arcs_rests_exactly_at_the_target():
    """Issue 18's reproducer: the fewest-sample move holds |u| = F while the body rests; after the exact
    correction the event-located simulation (sticking included) ends at rest at the target."""
    problem = MoveProblem(REPRO, REPRO_U, [0.0] * REPRO.n_states, REPRO_GOAL)
    base = plan_time_optimal(problem)  # its velocity signs: the first pattern (a monotone one cannot work)
    v = simulate(REPRO, problem.x0, base.input(), times=np.linspace(0.0, base.duration, 257))[:, 1]
    signs = np.where(v[:-1] + v[1:] > 0.0, 1.0, -1.0)
    dt = base.duration / 64
    lp = FrictionLP(problem, REPRO_F, dt)
    sol = fastest_samples(lp, lambda tau: signs[np.minimum((np.asarray(tau) * 256).astype(int), 255)], 64, K_max=256)
    assert sol is not None and sol.t <= REPRO_U
    assert has_stick_arcs(sol.u, REPRO_F, sol.t)
    u = lp.exact_commands(sol)
    assert np.max(np.abs(u)) <= REPRO_U
    T = sol.K * dt
    x = simulate_coulomb(REPRO, problem.x0, PiecewiseConstant.from_samples(u, dt), REPRO_F, [T, T + 20.0])
    target = REPRO.rest_state(REPRO_GOAL)
    assert np.max(np.abs(x - target)) < 1e-12


def test_consistent_pattern_finds_a_reversal_the_template_lacks():
    """Wie-Bernstein at F = 0.1: the body briefly moves back mid-move; from a no-reversal template the
    fixed point (friction of the pattern as a known force, signs of the result as the next pattern)
    finds a pattern with reversals that needs no more peak than the monotone one."""
    problem = rest_to_rest(WB, 1.0, 1.0)
    lp = FrictionLP(problem, 0.1, 0.05)
    K = 86
    sol = consistent_pattern(lp, K, np.ones(K))
    mono = lp.solve(K, np.ones(K))
    assert sol is not None and mono is not None
    assert sol.t <= mono.t * (1.0 + 1e-12)
    v = lp.velocities(sol.u, sol.pattern)
    assert np.all(sol.pattern[:-1] * v[1:-1] >= -1e-9) and np.all(sol.pattern[1:] * v[1:-1] >= -1e-9)


@pytest.mark.parametrize("seed", range(4))
def test_bang_bang_guess_keeps_the_mean_force_of_every_sample(seed):
    rng = np.random.default_rng(seed)
    u = np.sign(rng.standard_normal(40)) * 2.0
    u[rng.integers(0, 40, 8)] = rng.uniform(-2.0, 2.0, 8)
    dt = 0.1
    levels, t_sw, T = bang_bang_guess(u, dt, 2.0)
    assert T == pytest.approx(40 * dt) and np.all(np.abs(levels) == 2.0)
    pc = PiecewiseConstant.from_switches(t_sw, levels, T)
    fine = np.linspace(0.0, T, 40 * 4000, endpoint=False) + T / (2 * 40 * 4000)
    means = pc(fine).reshape(40, 4000).mean(axis=1)
    assert np.allclose(means, u, atol=2e-3)


def test_stuck_samples_hold_the_body_and_the_move_rests_exactly():
    """Fuzz case 492 of issue 18 (two close slow modes, F = 0.5 u_max, c < 0): no sliding pattern reaches
    rest; with stuck samples (pattern 0: |u| <= F, the body held by friction) the search finds a move.
    The exact event-located simulation (sticking included) confirms what the LP assumed: the body does
    not move on the stuck samples, never moves back, and rests at the target at the end and after."""
    m = ModalModel(
        b0=0.13422842892094394,
        c=-0.70400694826743,
        omega=(0.7721549463467025, 0.7923167284232879, 29.701533690589205),
        zeta=(0.26457178493966277, 0.27920761139920636, 0.0752186001428152),
        b=(0.39211715189292795, -0.9704074569056195, -0.5598962490544935),
    )
    u_max, F, goal = 0.7454725539854661, 0.36988037191729395, 0.3668231174880086
    problem = MoveProblem(m, u_max, [0.0] * m.n_states, goal)
    dt = 0.11
    lp = FrictionLP(problem, F, dt)
    assert fastest_samples(lp, lambda tau: np.ones(np.shape(tau)), 64, K_max=256) is None  # sliding only
    sol = fastest_samples(lp, lambda tau: np.ones(np.shape(tau)), 64, K_max=256, stick=True)
    assert sol is not None and sol.t <= u_max
    stuck = sol.pattern == 0.0
    assert stuck.any() and np.all(np.abs(sol.u[stuck]) <= F)
    K = sol.K
    x = simulate_coulomb(m, problem.x0, PiecewiseConstant.from_samples(sol.u, dt), F, dt * np.arange(K + 1))
    assert np.all(np.diff(x[:, 0]) >= -1e-12)  # never back
    held = np.flatnonzero(stuck)
    assert np.max(np.abs(x[held + 1, 0] - x[held, 0])) < 1e-12 and np.max(np.abs(x[held + 1, 1])) < 1e-12
    end = simulate_coulomb(m, problem.x0, PiecewiseConstant.from_samples(sol.u, dt), F, [K * dt, K * dt + 30.0])
    assert np.max(np.abs(end - m.rest_state(goal))) < 1e-9


# ------------------------------------------------------------------ fewer LPs (issue 18)
def test_count_for_peak_scales_the_excess_over_friction_as_k_squared():
    sol = types.SimpleNamespace(t=5.0)
    # (t - F) K^2 constant: (5 - 1) 64^2 = (u_max - 1) K^2 -> K = 64 sqrt(4 / 1) = 128, +0.1 % rounded up
    assert count_for_peak(64, sol, 1.0, 2.0) == 129
    assert count_for_peak(100, types.SimpleNamespace(t=1.5), 1.0, 3.0) == 50  # below u_max: fewer samples
    assert count_for_peak(64, None, 1.0, 2.0) is None
    assert count_for_peak(64, types.SimpleNamespace(t=0.5), 1.0, 2.0) is None  # not above friction: no scale


def test_a_period_too_fine_for_the_move_is_left_after_one_relaxed_lp():
    """Fuzz case 39 of seed 18 (a 9.2 s move first tried with 10 ms samples): no signed LP has a solution
    up to ``K_max``; the LP without sign rows (a relaxation: its least peak is a lower bound for the pattern)
    says the count needed is far past ``K_max``, so the search stops after a handful of LPs (it probed 14
    counts, 24 LPs for two patterns, before) and the caller tries coarser samples."""
    m = ModalModel(
        b0=0.8840645134751459,
        c=0.0,
        omega=(1.189875684135764, 36.645880960090786),
        zeta=(0.20862040732839457, 0.09533200224712425),
        b=(-0.22399973091343323, 1.7767336588734592),
    )
    u_max, F, goal = 0.2767137129265001, 0.1124859552495107, -0.0003093646103619222
    problem = MoveProblem(m, u_max, [0.0] * m.n_states, goal)
    lp = FrictionLP(problem, F, 0.01)
    direction = -1.0
    sol = fastest_samples(lp, lambda tau: np.full(np.shape(tau), direction), 64, K_max=256)
    assert sol is None
    assert lp.solves <= 8


def test_a_monotone_pattern_is_solved_by_its_arrival_rows_when_no_sign_is_violated(spy):
    """Before: every signed LP of the structure search was the chain form (2 K + 2 columns, about one simplex
    iteration per row: 2-4 ms at 190 samples).  Now a monotone pattern's LP is first solved with the arrival
    rows alone (K + 1 columns); where its velocities keep their sign that is the signed LP's optimum, the same
    peak and commands as the chain form's.  The LP without sign conditions is its arrival rows alone."""
    from flexmotion_ros.core.friction import sampled_lp as mod

    # seed-18 fuzz case 88 (two modes, c = 0, F = 0.22 u_max): a monotone move (188 samples of 0.13 s)
    m = ModalModel(
        b0=0.1545043630137464,
        c=0.0,
        omega=(1.1467813684326982, 47.6835289244803),
        zeta=(0.05789717439445904, 0.2803840841994864),
        b=(1.282615117912985, -1.1313217744408233),
    )
    u_max = 0.8662531907123768
    problem, F = MoveProblem(m, u_max, [0.0] * m.n_states, 18.125361827457088), 0.22264954899363443 * u_max
    direction = 1.0
    columns = spy(mod, "solve_lp", lambda **kw: kw["cost"].size)
    for K, dt in ((64, 0.38), (66, 0.38), (188, 0.13), (192, 0.13)):  # the structure search's LPs of this move
        fast = FrictionLP(problem, F, dt)
        fast.monotone_rows = True  # as the structure search makes them (set after, so the old code runs too)
        chain = FrictionLP(problem, F, dt)
        columns.clear()
        a = fast.solve(K, np.full(K, direction))
        assert columns == [K + 1]  # one LP, no chain variables
        b = chain.solve(K, np.full(K, direction))
        assert columns[1:] == [2 * K + 2]
        assert a is not None and b is not None
        assert abs(a.t - b.t) <= 1e-9 * b.t
        assert np.max(np.abs(a.u - b.u)) <= 1e-6 * b.t
        v = fast.velocities(a.u, a.pattern)
        assert np.all(direction * v[1:K] >= -1e-12 * np.max(np.abs(v)))
        # without sign conditions (the pattern's friction a known force only) the LP is its arrival rows too
        columns.clear()
        c = fast.solve(K, np.full(K, direction), signs=False)
        d = chain.solve(K, np.full(K, direction), signs=False)
        assert columns == [K + 1, 2 * K + 2]
        assert abs(c.t - d.t) <= 1e-9 * d.t
        assert fast.feasible_solves == chain.feasible_solves == 2  # counted alike (the planner reads it)
