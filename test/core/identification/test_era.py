"""Markov parameters and ERA: our numpy implementation against python-control's ``markov`` and
``eigensys_realization`` on the same data, and against the exact ``C A^(k-1) B`` of a known system."""

import numpy as np
import pytest

from flexmotion_ros.core.identification.era import era, fir_markov, observer_markov

control = pytest.importorskip("control")


def discrete_system(poles_s, dt, seed=0):
    """A random real discrete system ``(A, B, C)`` with the given continuous poles (conjugate pairs)."""
    rng = np.random.default_rng(seed)
    blocks = []
    for s in poles_s:
        z = np.exp(s * dt)
        blocks.append(np.array([[z.real, z.imag], [-z.imag, z.real]]))
    n = 2 * len(blocks)
    A = np.zeros((n, n))
    for i, b in enumerate(blocks):
        A[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = b
    return A, rng.standard_normal((n, 1)), rng.standard_normal((1, n))


def respond(A, B, C, u):
    x = np.zeros(A.shape[0])
    y = np.empty(u.size)
    for k, uk in enumerate(u):
        y[k] = (C @ x)[0]
        x = A @ x + B[:, 0] * uk
    return y


def exact_markov(A, B, C, count):
    out = [0.0]
    v = B[:, 0]
    for _ in range(count):
        out.append(float((C @ v)[0]))
        v = A @ v
    return np.array(out)


def test_fir_markov_equals_control_markov():
    A, B, C = discrete_system([-2.0 + 3.0j, -3.0 + 8.0j], 0.1)
    u = np.random.default_rng(1).standard_normal(600)
    y = respond(A, B, C, u)
    ours = fir_markov(u, y, 60)
    theirs = np.asarray(control.markov(y, u, 60)).ravel()
    assert np.allclose(ours, theirs, rtol=1e-9, atol=1e-12)
    # and both are the system's (well damped: beyond 60 samples the response is below e^-12 of its start)
    exact = exact_markov(A, B, C, 59)
    assert np.max(np.abs(ours - exact)) < 1e-4 * np.max(np.abs(exact))


def test_era_equals_control_eigensys_realization():
    A, B, C = discrete_system([-0.05 + 2.0j, -0.2 + 7.0j], 0.1)
    markov = exact_markov(A, B, C, 60)
    A1, B1, C1, D1, S1 = era(markov, 4, 20, 20)
    sys2, S2 = control.eigensys_realization(markov, 4, 20, 20)
    assert np.allclose(S1, S2, rtol=1e-10)
    assert np.allclose(np.sort_complex(np.linalg.eigvals(A1)), np.sort_complex(np.linalg.eigvals(sys2.A)), atol=1e-10)
    # same transfer function: same Markov parameters from both realizations
    for k in range(1, 10):
        ours = float((C1 @ np.linalg.matrix_power(A1, k - 1) @ B1)[0, 0])
        theirs = float(
            (np.asarray(sys2.C) @ np.linalg.matrix_power(np.asarray(sys2.A), k - 1) @ np.asarray(sys2.B))[0, 0]
        )
        assert ours == pytest.approx(theirs, rel=1e-8, abs=1e-12)
    # and the poles are the system's
    assert np.allclose(np.sort_complex(np.linalg.eigvals(A1)), np.sort_complex(np.linalg.eigvals(A)), atol=1e-9)


def test_observer_markov_recovers_a_lightly_damped_system_from_arbitrary_input():
    """zeta = 0.005: the impulse response rings for thousands of samples, far beyond any FIR window;
    the observer (ARX) form needs only its order."""
    A, B, C = discrete_system([-0.01 + 2.0j, -0.03 + 6.0j], 0.05, seed=4)
    u = np.random.default_rng(5).standard_normal(3000)
    y = respond(A, B, C, u) + 0.7  # a sensor offset: absorbed by the constant regressor
    markov = observer_markov(u, y[:, None], 8, 200)[:, 0]
    exact = exact_markov(A, B, C, 200)
    assert np.max(np.abs(markov - exact)) < 1e-8 * np.max(np.abs(exact))
    Ar, *_ = era(markov, 4, 40, 40)
    assert np.allclose(np.sort_complex(np.linalg.eigvals(Ar)), np.sort_complex(np.linalg.eigvals(A)), atol=1e-8)
    # the FIR estimate with the same number of parameters cannot: the truncated ring biases it
    fir = fir_markov(u, y - 0.7, 17)
    assert np.max(np.abs(fir - exact[:17])) > 1e-3 * np.max(np.abs(exact))


def test_observer_markov_several_outputs_matches_single_output():
    A, B, C = discrete_system([-0.02 + 1.5j, -0.05 + 4.0j], 0.05, seed=6)
    C2 = np.vstack([C, np.random.default_rng(7).standard_normal((1, 4))])
    u = np.random.default_rng(8).standard_normal(2000)
    y0 = respond(A, B, C2[:1], u)
    y1 = respond(A, B, C2[1:], u)
    both = observer_markov(u, np.column_stack([y0, y1]), 6, 50)
    assert np.allclose(both[:, 0], exact_markov(A, B, C2[:1], 50), atol=1e-8)
    assert np.allclose(both[:, 1], exact_markov(A, B, C2[1:], 50), atol=1e-8)
