"""Exact simulation: matrix-exponential propagation vs closed forms, vs an ODE
integrator (rtol 1e-12, a sanity check only), states at arbitrary times, residual
modal amplitudes; and the planners' closed-form fast path vs expm."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from flexmotion_ros.core import (
    ModalModel,
    PiecewiseConstant,
    chain,
    final_state,
    modal_amplitudes,
    simulate,
    simulate_samples,
)
from flexmotion_ros.core.simulation.exact import SAMPLE_BLOCK, step_matrices
from flexmotion_ros.core.simulation.modal_response import ModalResponse

MODEL = ModalModel(b0=0.8, c=-0.3, omega=(1.3, 4.7, 11.0), zeta=(0.0, 0.05, 0.3), b=(1.2, -0.4, 2.5))
RIGID_C0 = ModalModel(b0=-1.7)
U = PiecewiseConstant(np.array([0.0, 0.4, 1.3, 1.35, 2.9]), np.array([1.0, -2.0, 0.5, -0.75]))
X0 = np.array([0.3, -0.2, 0.05, 0.4, -0.1, 0.2, 0.01, -0.3])


# ---------------------------------------------------------------- closed forms
def rigid_closed_form(b0, c, p0, v0, u, t):
    """p'' = c p' + b0 u, u constant, from (p0, v0)."""
    if c == 0.0:
        return p0 + v0 * t + 0.5 * b0 * u * t * t, v0 + b0 * u * t
    e = math.exp(c * t)
    v = v0 * e + b0 * u * (e - 1.0) / c
    p = p0 + v0 * (e - 1.0) / c + b0 * u / c * ((e - 1.0) / c - t)
    return p, v


def mode_closed_form(w, z, b, q0, qd0, u, t):
    """q'' + 2 z w q' + w^2 q = b u, u constant, from (q0, qd0)."""
    s = z * w
    wd = w * math.sqrt(1.0 - z * z)
    E, C, S = math.exp(-s * t), math.cos(wd * t), math.sin(wd * t)
    qs = b * u / (w * w)  # static deflection
    q = E * (q0 * C + (qd0 + s * q0) / wd * S) + qs * (1.0 - E * (C + s / wd * S))
    qd = E * (qd0 * C - (w * w * q0 + s * qd0) / wd * S) + qs * E * (w * w / wd) * S
    return q, qd


def closed_form_state(model, x0, u_level, t):
    p, v = rigid_closed_form(model.b0, model.c, x0[0], x0[1], u_level, t)
    out = [p, v]
    for i, (w, z, b) in enumerate(zip(model.omega, model.zeta, model.b)):
        out += mode_closed_form(w, z, b, x0[2 + 2 * i], x0[3 + 2 * i], u_level, t)
    return np.array(out)


def closed_form_piecewise(model, x0, u, t):
    x = np.array(x0, float)
    for a, b, level in zip(u.breaks[:-1], u.breaks[1:], u.levels):
        if t <= a:
            break
        x = closed_form_state(model, x, level, min(b, t) - a)
    if t > u.duration:
        x = closed_form_state(model, x, 0.0, t - u.duration)
    return x


@pytest.mark.parametrize("model", [MODEL, RIGID_C0, MODEL.with_changes(c=0.0)])
def test_constant_input_matches_closed_form(model):
    x0 = X0[: model.n_states]
    for t in (0.0, 1e-9, 0.01, 0.7, 3.0, 25.0):
        u = PiecewiseConstant(np.array([0.0, t]), np.array([1.3]))
        x = final_state(model, x0, u)
        ref = closed_form_state(model, x0, 1.3, t)
        np.testing.assert_allclose(x, ref, rtol=1e-11, atol=1e-12 * (1 + np.max(np.abs(ref))))


def test_piecewise_input_at_arbitrary_times_matches_closed_form():
    times = np.array([2.0, 0.0, 0.4, 0.41, 1.3, 5.5, 1.349, 2.9, 0.4, 10.0, 1e-7])  # unsorted, repeated, past the end
    X = simulate(MODEL, X0, U, times=times)
    assert X.shape == (times.size, MODEL.n_states)
    for t, x in zip(times, X):
        ref = closed_form_piecewise(MODEL, X0, U, t)
        np.testing.assert_allclose(x, ref, rtol=1e-11, atol=1e-12)


def test_default_times_are_the_breaks_and_final_state_is_the_last():
    X = simulate(MODEL, X0, U)
    assert X.shape == (U.breaks.size, MODEL.n_states)
    np.testing.assert_array_equal(X[0], X0)
    for t, x in zip(U.breaks, X):
        np.testing.assert_allclose(x, closed_form_piecewise(MODEL, X0, U, t), rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(final_state(MODEL, X0, U), X[-1], rtol=1e-14, atol=1e-15)


def test_include_position_false_drops_the_position():
    X = simulate(MODEL, X0[1:], U, times=[0.9, 3.1], include_position=False)
    full = simulate(MODEL, X0, U, times=[0.9, 3.1])
    np.testing.assert_allclose(X, full[:, 1:], rtol=1e-13, atol=1e-14)


def test_accepts_an_A_B_pair():
    X = simulate((MODEL.A(), MODEL.B()), X0, U, times=[2.2])
    np.testing.assert_allclose(X, simulate(MODEL, X0, U, times=[2.2]), rtol=1e-15, atol=0)


def test_step_matrices_are_the_exponential_and_its_integral():
    A, B = MODEL.A(), MODEL.B()
    h = 0.37
    Phi, Gam = step_matrices(A, B, h)
    np.testing.assert_allclose(Phi, expm(A * h), rtol=1e-13, atol=1e-15)
    # Gamma = int_0^h e^{A s} B ds by composite Gauss-Legendre (smooth integrand)
    nodes, weights = np.polynomial.legendre.leggauss(30)
    s = 0.5 * h * (nodes + 1.0)
    ref = sum(0.5 * h * wt * expm(A * si) @ B for si, wt in zip(s, weights))
    np.testing.assert_allclose(Gam, ref, rtol=1e-12, atol=1e-15)


# ------------------------------------------------------------------ vs an ODE
def test_matches_solve_ivp_sanity_check():
    A, B = MODEL.A(), MODEL.B()
    x = X0.copy()
    times = []
    ref = []
    for a, b, level in zip(U.breaks[:-1], U.breaks[1:], U.levels):  # one solve per interval
        sol = solve_ivp(
            lambda t, y, level=level: A @ y + B * level,
            (a, b),
            x,
            method="DOP853",
            rtol=1e-12,
            atol=1e-14,
            dense_output=True,
        )
        ts = np.linspace(a, b, 5)
        times += list(ts)
        ref += list(sol.sol(ts).T)
        x = sol.y[:, -1]
    X = simulate(MODEL, X0, U, times=times)
    np.testing.assert_allclose(X, np.array(ref), rtol=1e-9, atol=1e-11)


# ------------------------------------------------------------------ samples
def test_simulate_samples_equals_simulate_at_the_sample_instants():
    samples = np.array([0.3, -1.0, 1.0, 0.25, 0.0, -0.6])
    dt = 0.13
    X = simulate_samples(MODEL, X0, samples, dt)
    assert X.shape == (samples.size + 1, MODEL.n_states)
    u = PiecewiseConstant.from_samples(samples, dt)
    ref = simulate(MODEL, X0, u, times=dt * np.arange(samples.size + 1))
    np.testing.assert_allclose(X, ref, rtol=1e-12, atol=1e-14)
    for k in range(samples.size + 1):
        np.testing.assert_allclose(X[k], closed_form_piecewise(MODEL, X0, u, k * dt), rtol=1e-11, atol=1e-12)


# ------------------------------------------------------- piecewise-constant
def test_piecewise_constant_evaluation_and_construction():
    u = PiecewiseConstant.from_switches([1.0, 2.5], [1.0, -1.0, 0.5], 3.0)
    np.testing.assert_array_equal(u.breaks, [0.0, 1.0, 2.5, 3.0])
    assert u.duration == 3.0 and u.max_abs() == 1.0
    np.testing.assert_array_equal(u([-0.1, 0.0, 0.99, 1.0, 2.6, 3.0, 9.0]), [0, 1, 1, -1, 0.5, 0, 0])
    s = PiecewiseConstant.from_samples([0.2, -0.4], 0.5)
    np.testing.assert_array_equal(s.breaks, [0.0, 0.5, 1.0])
    assert s.max_abs() == 0.4
    with pytest.raises(ValueError):
        PiecewiseConstant(np.array([0.0, 1.0]), np.array([1.0, 2.0]))
    with pytest.raises(ValueError):
        PiecewiseConstant(np.array([0.0, 2.0, 1.0]), np.array([1.0, 2.0]))


# --------------------------------------------------------- modal amplitudes
def test_modal_amplitude_is_the_free_vibration_envelope():
    # after the input ends, each mode vibrates freely: |q(t)| peaks at the envelope, which decays as e^{-zeta w t}
    x_end = final_state(MODEL, X0, U)
    amp = modal_amplitudes(MODEL, x_end)
    assert amp.shape == (3,)
    for i, (w, z) in enumerate(zip(MODEL.omega, MODEL.zeta)):
        wd = w * math.sqrt(1 - z * z)
        period = 2 * math.pi / wd
        ts = U.duration + np.linspace(0.0, period, 4001)
        X = simulate(MODEL, X0, U, times=ts)
        q = X[:, 2 + 2 * i]
        envelope = amp[i] * np.exp(-z * w * (ts - U.duration))
        assert np.all(np.abs(q) <= envelope * (1 + 1e-9) + 1e-15)
        assert np.max(np.abs(q) / envelope) == pytest.approx(1.0, abs=1e-5)
        # the amplitude itself decays exactly as e^{-zeta w t} along the free motion
        later = modal_amplitudes(MODEL, X[-1])[i]
        assert later == pytest.approx(amp[i] * math.exp(-z * w * period), rel=1e-10)


def test_residual_amplitude_of_a_naive_rigid_move_and_of_rest():
    """A rigid bang-bang move of the Wie-Bernstein system leaves a vibration given in closed form."""
    wb = ModalModel(b0=0.5, omega=(math.sqrt(2.0),), zeta=(0.0,), b=(1.0,))
    T = 2.0 * math.sqrt(1.0 / 0.5)  # rigid optimum for a unit move
    u = PiecewiseConstant.from_switches([T / 2], [1.0, -1.0], T)
    x = final_state(wb, wb.rest_state(), u)
    assert x[0] == pytest.approx(1.0, rel=1e-13) and abs(x[1]) < 1e-14
    q = closed_form_piecewise(wb, wb.rest_state(), u, T)[2:]
    expected = math.hypot(q[0], q[1] / math.sqrt(2.0))
    assert expected > 0.1
    assert modal_amplitudes(wb, x)[0] == pytest.approx(expected, rel=1e-12)
    np.testing.assert_array_equal(modal_amplitudes(MODEL, MODEL.rest_state(3.0)), np.zeros(3))
    # vectorised over states
    assert modal_amplitudes(MODEL, np.stack([X0, X0])).shape == (2, 3)


# ------------------------------------------- the planners' fast path vs expm
@pytest.mark.parametrize("include_position", [True, False])
@pytest.mark.parametrize("model", [MODEL, MODEL.with_changes(c=0.0), RIGID_C0])
def test_modal_response_closed_forms_vs_expm(model, include_position):
    R = ModalResponse(model, include_position)
    A, B = R.A(), R.B()
    x = X0[: model.n_states][(0 if include_position else 1) :]
    taus = np.array([0.0, 1e-8, 0.003, 0.9, 4.0, 17.0])
    nu = np.linspace(-1.0, 1.3, R.n)
    for tau, eB, AeB, G, ex, S in zip(
        taus,
        R.expm_B(taus),
        R.A_expm_B(taus),
        R.input_integral(taus),
        R.expm_x_many(taus, x),
        R.switching(nu, taus),
    ):
        E = expm(A * tau)
        _, Gam = step_matrices(A, B, tau)
        scale = 1e-12 * (1.0 + np.max(np.abs(E)))
        np.testing.assert_allclose(eB, E @ B, rtol=1e-11, atol=scale)
        np.testing.assert_allclose(AeB, A @ E @ B, rtol=1e-11, atol=scale)
        np.testing.assert_allclose(G, Gam, rtol=1e-10, atol=scale)
        np.testing.assert_allclose(ex, E @ x, rtol=1e-11, atol=scale)
        np.testing.assert_allclose(R.expm_x(tau, x), E @ x, rtol=1e-11, atol=scale)
        assert S == pytest.approx(nu @ E @ B, rel=1e-10, abs=scale * np.max(np.abs(nu)))
    np.testing.assert_allclose(R.A_x(x), A @ x, rtol=1e-14, atol=0)
    # derivatives of S by central differences of the expm value
    S, dS, d2S = R.switching(nu, np.array([0.8]), order=2)
    h = 1e-4
    f = [nu @ expm(A * t) @ B for t in (0.8 - h, 0.8, 0.8 + h)]
    assert dS[0] == pytest.approx((f[2] - f[0]) / (2 * h), rel=1e-6, abs=1e-9)
    assert d2S[0] == pytest.approx((f[2] - 2 * f[1] + f[0]) / h**2, rel=1e-4, abs=1e-6)


def test_blocked_sample_propagation_equals_the_step_by_step_recursion():
    """``simulate_samples`` propagates long sequences in blocks (powers of one expm): same states to rounding."""
    model = chain([0.5] * 4, [400.0] * 3, [0.4] * 3, force_on=0).model
    rng = np.random.default_rng(7)
    for K in (4 * SAMPLE_BLOCK - 1, 4 * SAMPLE_BLOCK, 1000 * SAMPLE_BLOCK // 32 + 17):
        u = rng.uniform(-10.0, 10.0, K)
        x0 = rng.normal(size=model.n_states)
        X = simulate_samples(model, x0, u, 1e-3)
        Phi, Gam = step_matrices(model.A(), model.B(), 1e-3)
        x = x0.copy()
        Y = [x]
        for uk in u:
            x = Phi @ x + Gam * uk
            Y.append(x)
        Y = np.array(Y)
        assert X.shape == Y.shape
        assert np.max(np.abs(X - Y) / np.max(np.abs(Y), axis=0)) <= 1e-12
