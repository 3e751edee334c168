"""Minimum-fuel moves and the fuel/time curve (seed eq. 2.38) against independent computations.

References: the rigid body's closed-form bang-off-bang optimum; a second,
state-space LP built from ``scipy.linalg.expm`` step matrices (no closed
forms); brute-force vertex enumeration of a tiny LP; the dual value by
quadrature of ``(|nu^T e^{A tau} B| - 1)_+`` with ``expm``; and the exact
matrix-exponential simulation for every arrival.
"""

import itertools
import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.linalg import expm
from scipy.optimize import linprog

from flexmotion_ros.cli.main import main as cli_main
from flexmotion_ros.core import (
    ModalModel,
    config_from_parameters,
    final_state,
    motion_to_rest,
    plan_time_optimal,
    plan_time_optimal_zoh,
    rest_to_rest,
    simulate_samples,
)
from flexmotion_ros.core.errors import ConfigError, GoalError, SolverError
from flexmotion_ros.core.fuel.curve import fuel_time_curve, sampled_fuel_curve
from flexmotion_ros.core.fuel.lp import plan_min_fuel_zoh
from flexmotion_ros.core.fuel.min_fuel import plan_min_fuel
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.simulation.exact import step_matrices

WB = ModalModel(b0=0.5, c=0.0, omega=[math.sqrt(2.0)], zeta=[0.0], b=[1.0])
DAMPED = ModalModel(b0=1.0, c=-0.3, omega=[3.0, 7.0], zeta=[0.05, 0.02], b=[0.7, -0.4])


# ------------------------------------------------------------ references
def state_space_fuel(model, x0, target, u_max, K, dt, include_position=True):
    """Min ``dt sum |u_k|`` by a second LP: states as variables, expm step matrices, forward time."""
    A, B = model.A(), model.B()
    x0 = np.array(x0, float)
    xf = model.rest_state(target if target is not None else 0.0)
    if not include_position:
        A, B, x0, xf = A[1:, 1:], B[1:], x0[1:], xf[1:]
    n = A.shape[0]
    Phi, Gam = step_matrices(A, B, dt)
    # variables: p_0..p_{K-1}, m_0..m_{K-1} (u = p - m), x_1..x_K
    nv = 2 * K + n * K
    Aeq = np.zeros((n * K + n, nv))
    beq = np.zeros(n * K + n)
    for k in range(K):
        r = slice(n * k, n * k + n)
        Aeq[r, 2 * K + n * k : 2 * K + n * k + n] = np.eye(n)
        Aeq[r, k] = -Gam
        Aeq[r, K + k] = Gam
        if k == 0:
            beq[r] = Phi @ x0
        else:
            Aeq[r, 2 * K + n * (k - 1) : 2 * K + n * k] = -Phi
    Aeq[n * K :, 2 * K + n * (K - 1) :] = np.eye(n)
    beq[n * K :] = xf
    cost = np.concatenate([np.full(2 * K, dt), np.zeros(n * K)])
    bounds = [(0.0, u_max)] * (2 * K) + [(None, None)] * (n * K)
    res = linprog(cost, A_eq=Aeq, b_eq=beq, bounds=bounds, method="highs")
    return res.fun if res.status == 0 else None


def rigid_fuel(b0, u_max, gamma, T):
    """Closed-form continuous min fuel for a rigid body (c = 0), rest to rest by gamma in time T."""
    a = abs(b0) * u_max
    disc = T * T - 4.0 * abs(gamma) / a
    t1 = 0.5 * (T - math.sqrt(disc))
    return 2.0 * u_max * t1, t1


def dual_by_quadrature(model, x0, T, u_max, nu, include_position=True, n=50_001):
    """``nu^T w - u_max int (|S| - 1)_+`` with ``S = nu^T e^{A tau} B`` from expm on a fine grid."""
    A, B = model.A(), model.B()
    if not include_position:
        A, B = A[1:, 1:], B[1:]
    w = -expm(A * T) @ x0
    tau = np.linspace(0.0, T, n)
    E = expm(A * (tau[1] - tau[0]))
    g = B.copy()
    S = np.empty(n)
    for i in range(n):
        S[i] = nu @ g
        g = E @ g
    f = np.maximum(np.abs(S) - 1.0, 0.0)
    integral = (tau[1] - tau[0]) * (f.sum() - 0.5 * (f[0] + f[-1]))
    return float(nu @ w - u_max * integral)


def check_arrival(problem, profile):
    x = final_state(problem.model, problem.x0, profile.input())
    target = problem.model.rest_state(problem.target if problem.target is not None else 0.0)
    dev = (x - target)[0 if problem.target is not None else 1 :]
    assert np.max(np.abs(dev)) <= 1e-8 * max(1.0, abs(problem.target or 0.0))


# ------------------------------------------------------------- continuous
@pytest.mark.parametrize("factor", [1.02, 1.3, 2.5])
def test_rigid_body_matches_closed_form(factor):
    model = ModalModel(b0=2.0)
    problem = rest_to_rest(model, 1.5, 0.8)
    T = plan_time_optimal(problem).duration * factor
    p = plan_min_fuel(problem, T)
    fuel, t1 = rigid_fuel(2.0, 1.5, 0.8, T)
    assert p.fuel == pytest.approx(fuel, rel=1e-10)
    np.testing.assert_allclose(p.switch_times, [t1, T - t1], rtol=1e-10)
    np.testing.assert_array_equal(p.levels, [1.5, 0.0, -1.5])
    check_arrival(problem, p)


@pytest.mark.parametrize(
    "problem",
    [rest_to_rest(WB, 1.0, 1.0), rest_to_rest(DAMPED, 2.0, 1.5), motion_to_rest(DAMPED, 2.0, 1.5)],
    ids=["wie-bernstein", "damped-2-mode", "damped-motion-to-rest"],
)
def test_continuous_is_bang_off_bang_exact_and_optimal(problem):
    to = plan_time_optimal(problem)
    T = round(1.25 * to.duration, 2)  # a multiple of the sample period below
    p = plan_min_fuel(problem, T, to)
    assert p.certified
    assert set(np.abs(p.levels)) <= {0.0, problem.u_max}
    check_arrival(problem, p)
    assert p.fuel == pytest.approx(float(np.sum(np.diff(p.input().breaks) * np.abs(p.input().levels))), rel=1e-12)
    # weak duality, independently: the dual value by quadrature with expm bounds every input's fuel
    d = dual_by_quadrature(
        problem.model, problem.shifted_initial(), T, problem.u_max, p.costate, problem.include_position
    )
    assert d == pytest.approx(p.fuel, rel=1e-6)
    # any ZOH sequence is an admissible continuous input: the sampled optimum cannot use less
    for rate in (100.0, 400.0):
        s = plan_min_fuel_zoh(problem, rate, T, to, nu_guess=p.costate)
        assert s.duration == pytest.approx(T)
        assert s.extra["fuel"] >= p.fuel * (1.0 - 1e-9)
    assert s.extra["fuel"] - p.fuel <= 5e-3 * p.fuel  # and converges to it


def test_at_time_optimal_time_fuel_is_u_max_T_star():
    problem = rest_to_rest(WB, 1.0, 1.0)
    to = plan_time_optimal(problem)
    p = plan_min_fuel(problem, to.duration, to)
    assert p.fuel == pytest.approx(to.duration, rel=1e-12)
    np.testing.assert_allclose(p.switch_times, to.switch_times)
    # just above T*: coasts appear, fuel drops below u_max T* but stays close
    q = plan_min_fuel(problem, to.duration * (1 + 1e-4), to)
    assert q.certified and 0.9 * to.duration < q.fuel < to.duration
    assert np.count_nonzero(q.levels == 0.0) == 3


def test_move_time_below_optimum_is_rejected():
    problem = rest_to_rest(WB, 1.0, 1.0)
    with pytest.raises(GoalError, match="move_time"):
        plan_min_fuel(problem, 4.0)
    with pytest.raises(GoalError, match="move_time"):
        plan_min_fuel_zoh(problem, 100.0, 4.0)


# ---------------------------------------------------------------- sampled
@pytest.mark.parametrize(
    "problem, K",
    [(rest_to_rest(WB, 1.0, 1.0), 60), (rest_to_rest(DAMPED, 2.0, 1.5), 45), (motion_to_rest(DAMPED, 2.0, 1.5), 30)],
    ids=["wie-bernstein", "damped", "motion-to-rest"],
)
def test_sampled_optimum_equals_state_space_lp(problem, K):
    rate = 10.0
    z = plan_time_optimal_zoh(problem, rate)
    K = max(K, z.samples)
    s = plan_min_fuel_zoh(problem, rate, K / rate)
    assert s.samples == K
    ref = state_space_fuel(
        problem.model, problem.x0, problem.target, problem.u_max, K, 1.0 / rate, problem.target is not None
    )
    assert s.extra["fuel"] == pytest.approx(ref, rel=1e-8)
    assert s.extra["fuel"] - s.extra["fuel_lower_bound"] <= 1e-9 * s.extra["fuel"]
    states = simulate_samples(problem.model, problem.x0, s.commands, 1.0 / rate)
    np.testing.assert_allclose(states[-1][1:], 0.0, atol=1e-10)
    assert np.max(np.abs(s.commands)) <= problem.u_max


def test_sampled_optimum_equals_brute_force_vertices():
    """Rigid body, 6 samples: an LP vertex has at most 2 fractional samples, the rest at 0 or +-u_max."""
    model = ModalModel(b0=1.0)
    problem = rest_to_rest(model, 1.0, 4.0)
    K, dt = 6, 1.0
    s = plan_min_fuel_zoh(problem, 1.0 / dt, K * dt)
    Phi, Gam = step_matrices(model.A(), model.B(), dt)
    # final state = sum_k Phi^(K-1-k) Gam u_k
    cols = np.column_stack([np.linalg.matrix_power(Phi, K - 1 - k) @ Gam for k in range(K)])
    target = np.array([4.0, 0.0])
    best = math.inf
    for i, j in itertools.combinations(range(K), 2):
        others = [k for k in range(K) if k not in (i, j)]
        for pattern in itertools.product((-1.0, 0.0, 1.0), repeat=K - 2):
            rhs = target - cols[:, others] @ np.array(pattern)
            M = cols[:, [i, j]]
            if abs(np.linalg.det(M)) < 1e-12:
                continue
            uij = np.linalg.solve(M, rhs)
            if np.all(np.abs(uij) <= 1.0 + 1e-12):
                best = min(best, dt * (np.sum(np.abs(pattern)) + np.sum(np.abs(uij))))
    assert s.extra["fuel"] == pytest.approx(best, rel=1e-10)


# ------------------------------------------------------------------ curve
def test_curve_monotone_with_exact_end_points():
    problem = rest_to_rest(WB, 1.0, 1.0)
    to = plan_time_optimal(problem)
    longest = round(2.0 * to.duration, 2)  # a whole number of samples at 500 Hz
    curve = fuel_time_curve(problem, longest, points=6, time_optimal=to)
    assert curve.fuel[0] == pytest.approx(problem.u_max * to.duration, rel=1e-12)
    assert np.all(np.diff(curve.fuel) < 0.0)
    # far end: the free-arrival-time optimum within [T*, longest], computed independently as the
    # minimum over every sample count of the state-space LP (fine rate -> continuous value)
    rate = 20.0
    sampled = sampled_fuel_curve(problem, rate, longest, points=5, time_optimal=to)
    assert np.all(np.diff(sampled.fuel) <= 1e-12 * sampled.fuel[0])
    K_max = math.floor(longest * rate + 1e-9)
    z = plan_time_optimal_zoh(problem, rate, to)
    free_time = min(state_space_fuel(WB, problem.x0, 1.0, 1.0, K, 1.0 / rate) for K in range(z.samples, K_max + 1, 7))
    last = state_space_fuel(WB, problem.x0, 1.0, 1.0, K_max, 1.0 / rate)
    assert sampled.fuel[-1] == pytest.approx(last, rel=1e-8)
    assert last <= free_time * (1 + 1e-9)
    # sampled first point: fewest samples; its fuel lies between the continuous optimum at K dt and u_max K dt
    K0 = z.samples
    assert sampled.move_times[0] == pytest.approx(K0 / rate)
    c0 = plan_min_fuel(problem, K0 / rate, to).fuel
    assert c0 * (1 - 1e-9) <= sampled.fuel[0] <= K0 / rate
    # continuous end point approaches the sampled one at a fine rate
    fine = plan_min_fuel_zoh(problem, 500.0, longest, to)
    assert fine.extra["fuel"] >= curve.fuel[-1] * (1 - 1e-9)
    assert fine.extra["fuel"] == pytest.approx(curve.fuel[-1], rel=2e-3)


# ------------------------------------------------------------- properties
@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    w=st.floats(0.6, 4.0),
    z=st.floats(0.0, 0.1),
    b=st.floats(0.3, 1.5),
    b0=st.floats(0.3, 2.0),
    gamma=st.floats(0.2, 2.0),
    factor=st.floats(1.05, 2.5),
)
def test_property_sampled_fuel(w, z, b, b0, gamma, factor):
    model = ModalModel(b0=b0, omega=[w], zeta=[z], b=[b])
    problem = rest_to_rest(model, 1.0, gamma)
    to = plan_time_optimal(problem)
    rate = 10.0
    K = max(plan_time_optimal_zoh(problem, rate, to).samples, math.ceil(factor * to.duration * rate))
    s1 = plan_min_fuel_zoh(problem, rate, K / rate, to)
    s2 = plan_min_fuel_zoh(problem, rate, (K + 3) / rate, to)
    for s in (s1, s2):
        x = simulate_samples(model, problem.x0, s.commands, 1.0 / rate)[-1]
        assert abs(x[0] - gamma) <= 1e-9 * max(1.0, gamma) and np.max(np.abs(x[1:])) <= 1e-9
        assert np.max(np.abs(s.commands)) <= 1.0
        assert s.extra["fuel"] - s.extra["fuel_lower_bound"] <= 1e-8 * s.extra["fuel"]
        assert s.extra["fuel"] <= s.duration * (1 + 1e-12)
    assert s2.extra["fuel"] <= s1.extra["fuel"] * (1 + 1e-9)  # more time never costs more fuel
    try:
        c = plan_min_fuel(problem, K / rate, to)
    except SolverError:
        return  # no continuous bang-off-bang found: allowed, never a wrong one
    check_arrival(problem, c)
    assert c.fuel <= s1.extra["fuel"] * (1 + 1e-9)


# --------------------------------------------------------- method and CLI
def params(**extra):
    p = {
        "model.b0": 0.5,
        "model.omega": [math.sqrt(2.0)],
        "model.zeta": [0.0],
        "model.b": [1.0],
        "u_max": 1.0,
        "rate_hz": 50.0,
        "method": "min_fuel",
    }
    p.update(extra)
    return p


def test_method_defaults_and_config_rate():
    config = config_from_parameters(params())
    problem = rest_to_rest(config.model, 1.0, 1.0)
    r = plan_move(config, problem)  # no rate: the config's
    assert r.sampled is not None and r.sampled.dt == pytest.approx(1.0 / 50.0)
    assert r.info["move_time"] == pytest.approx(1.2 * r.info["time_optimal_duration"])
    assert "config.rate_hz" in r.info["rate_source"]
    assert r.info["fuel"] < r.info["fuel_time_optimal"]
    out = r.summary()
    assert out["method"] == "min_fuel" and out["fuel"] == r.info["fuel"]


@pytest.mark.parametrize(
    "extra, name",
    [
        ({"move_time": 3.0}, "move_time"),
        ({"move_time": "x"}, "move_time"),
        ({"fuel_curve.points": 1}, "fuel_curve.points"),
        ({"fuel_curve.longest_time": 1.0}, "fuel_curve.longest_time"),
    ],
)
def test_method_rejects_bad_options(extra, name):
    config = config_from_parameters(params(**extra))
    with pytest.raises(ConfigError) as info:
        plan_move(config, rest_to_rest(config.model, 1.0, 1.0))
    assert info.value.parameter == name


def test_cli_plan_min_fuel(tmp_path, capsys):
    cfg = tmp_path / "p.yaml"
    cfg.write_text(
        "/**:\n  ros__parameters:\n    model: {b0: 0.5, c: 0.0, omega: [1.4142135623730951], zeta: [0.0], b: [1.0]}\n"
        "    u_max: 1.0\n    rate_hz: 50.0\n    method: min_fuel\n    move_time: 5.0\n"
        "    fuel_curve: {longest_time: 8.0, points: 3}\n"
    )
    assert cli_main(["plan", "--config", str(cfg), "--goal", "1.0", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["method"] == "min_fuel" and out["duration"] == 5.0 and out["samples"] == 250
    assert len(out["fuel_curve"]["fuel"]) == 3 and out["fuel_curve"]["fuel"][0] == pytest.approx(
        out["time_optimal_duration"]
    )
    assert cli_main(["plan", "--config", str(cfg), "--goal", "1.0"]) == 0
    assert "min_fuel" in capsys.readouterr().out
