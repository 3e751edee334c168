"""The switching function and its derivatives (``ModalResponse.switching``) against the matrix exponential.

``S^(j)(tau) = nu^T A^j e^{A tau} B``: every order the certificate's Taylor
bounds use (up to 8) is compared with ``nu^T A^j expm(A tau) B`` from scipy
(an independent computation), on random models with and without the
rigid-body position, damped, undamped, with friction and a rigid body alone;
and ``input_integral`` with ``c = 0`` (no phi series) against the augmented
matrix exponential.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm

from flexmotion_ros.core import ModalModel
from flexmotion_ros.core.simulation.modal_response import ModalResponse


@st.composite
def models(draw):
    n = draw(st.integers(0, 3))
    w = sorted(draw(st.floats(0.3, 40.0)) for _ in range(n))
    w = [wi * (1.0 + 0.1 * i) for i, wi in enumerate(w)]  # distinct
    zeta = [draw(st.floats(0.0, 0.3)) for _ in w]
    b = [draw(st.floats(0.1, 2.0)) * draw(st.sampled_from([-1.0, 1.0])) for _ in w]
    b0 = draw(st.floats(0.1, 3.0)) * draw(st.sampled_from([-1.0, 1.0]))
    c = -draw(st.floats(0.01, 2.0)) if draw(st.booleans()) else 0.0
    return ModalModel(b0=b0, c=c, omega=tuple(w), zeta=tuple(zeta), b=tuple(b))


@settings(max_examples=40, deadline=None)
@given(models(), st.booleans(), st.integers(0, 2**31 - 1))
def test_every_derivative_order_equals_the_matrix_exponential(model, include_position, seed):
    response = ModalResponse(model, include_position)
    rng = np.random.default_rng(seed)
    nu = rng.normal(size=response.n)
    tau = np.array([0.0, 1e-7, 0.031, 0.7, 2.9])
    A, B = response.A(), response.B()
    K = 8
    D = np.array(response.switching(nu, tau, order=K))
    assert D.shape == (K + 1, tau.size)
    for j in range(K + 1):
        Aj = np.linalg.matrix_power(A, j)
        ref = np.array([nu @ Aj @ expm(A * t) @ B for t in tau])
        # rounding relative to the order's size: |nu| |A|^j |B|
        size = np.linalg.norm(nu) * np.linalg.norm(A, 2) ** j * np.linalg.norm(B)
        np.testing.assert_allclose(D[j], ref, rtol=0.0, atol=1e-11 * size, err_msg=f"order {j}")
    S, dS = response.switching(nu, tau, derivative=True)
    np.testing.assert_array_equal(S, D[0])
    np.testing.assert_allclose(dS, D[1], rtol=0.0, atol=1e-14 * (np.max(np.abs(D[1])) + 1.0))
    np.testing.assert_allclose(response.switching(nu, tau), D[0], rtol=0.0, atol=1e-14 * (np.max(np.abs(D[0])) + 1.0))


@settings(max_examples=20, deadline=None)
@given(models(), st.booleans())
def test_input_integral_equals_the_augmented_exponential(model, include_position):
    response = ModalResponse(model, include_position)
    A, B = response.A(), response.B()
    n = A.shape[0]
    aug = np.zeros((n + 1, n + 1))
    aug[:n, :n] = A
    aug[:n, n] = B
    tau = np.array([0.0, 1e-9, 0.02, 0.9, 3.7])
    G = response.input_integral(tau)
    ref = np.array([expm(aug * t)[:n, n] for t in tau])
    np.testing.assert_allclose(G, ref, rtol=0.0, atol=1e-12 * max(1.0, float(np.max(np.abs(ref)))))
