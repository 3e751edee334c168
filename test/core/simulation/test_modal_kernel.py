"""The fused closed-form responses (``ModalKernel``) against scipy's matrix exponential.

Every column of ``e^{A t} B``, ``A e^{A t} B``, ``Gamma(t)`` and of
``e^{A T} x0``, ``A e^{A T} x0`` is compared with the exponential of the
augmented matrix ``[[A, B], [0, 0]]`` (an independent computation), with and
without the rigid-body position, with and without friction, damped and
undamped, and for a rigid body alone.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from flexmotion_ros.core import ModalModel
from flexmotion_ros.core.simulation.modal_kernel import ModalKernel
from flexmotion_ros.core.simulation.modal_response import ModalResponse

MODELS = [
    pytest.param(
        ModalModel(b0=0.8, c=-0.3, omega=(1.3, 4.7, 11.0), zeta=(0.0, 0.05, 0.3), b=(1.2, -0.4, 2.5)),
        id="friction-3-modes",
    ),
    pytest.param(ModalModel(b0=-1.7, c=0.0, omega=(2.0,), zeta=(0.0,), b=(0.6,)), id="undamped-1-mode"),
    pytest.param(ModalModel(b0=2.0, c=-1e-4, omega=(0.5, 9.0), zeta=(0.2, 0.01), b=(-1.0, 3.0)), id="tiny-friction"),
    pytest.param(ModalModel(b0=-1.7), id="rigid-only"),
    pytest.param(ModalModel(b0=1.1, c=-2.0), id="rigid-with-friction"),
]
TIMES = np.array([0.0, 1e-6, 0.013, 0.4, 1.7, 5.3])


def reference(response: ModalResponse, x0: np.ndarray, t: np.ndarray):
    """``e^{A t} B``, ``Gamma(t)`` per time and ``e^{A T} x0`` at the last, from expm of the augmented matrix."""
    A, B = response.A(), response.B()
    n = A.shape[0]
    aug = np.zeros((n + 1, n + 1))
    aug[:n, :n] = A
    aug[:n, n] = B
    E = [expm(aug * ti) for ti in t]
    eB = np.array([e[:n, :n] @ B for e in E])
    G = np.array([e[:n, n] for e in E])
    eAx = E[-1][:n, :n] @ x0
    return A, eB, G, eAx


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("include_position", [True, False], ids=["position", "no-position"])
def test_kernel_equals_the_matrix_exponential(model, include_position):
    response = ModalResponse(model, include_position)
    rng = np.random.default_rng(7)
    x0 = rng.uniform(-1.0, 1.0, response.n)
    kv = ModalKernel(response, x0).evaluate(TIMES)
    A, eB, G, eAx = reference(response, x0, TIMES)
    scale = max(1.0, float(np.max(np.abs(eB))), float(np.max(np.abs(G))))
    np.testing.assert_allclose(kv.eB, eB, rtol=0.0, atol=1e-12 * scale)
    np.testing.assert_allclose(kv.AeB, eB @ A.T, rtol=0.0, atol=1e-11 * scale * max(1.0, float(np.max(np.abs(A)))))
    np.testing.assert_allclose(kv.G, G, rtol=0.0, atol=1e-12 * scale)
    np.testing.assert_allclose(kv.eAx, eAx, rtol=0.0, atol=1e-12 * max(1.0, float(np.max(np.abs(eAx)))))
    np.testing.assert_allclose(kv.AeAx, A @ eAx, rtol=0.0, atol=1e-11 * max(1.0, float(np.max(np.abs(A @ eAx)))))


def test_kernel_agrees_with_the_responses_it_fuses():
    """Same formulas as ModalResponse, one call: equal to rounding."""
    model = MODELS[0].values[0]
    response = ModalResponse(model, True)
    x0 = np.linspace(-1.0, 1.0, response.n)
    kv = ModalKernel(response, x0).evaluate(TIMES)
    np.testing.assert_allclose(kv.eB, response.expm_B(TIMES), rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(kv.G, response.input_integral(TIMES), rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(kv.eAx, response.expm_x(TIMES[-1], x0), rtol=1e-13, atol=1e-15)


def test_without_an_initial_state_only_the_input_responses_are_given():
    kv = ModalKernel(ModalResponse(MODELS[0].values[0], True)).evaluate(TIMES)
    assert kv.eAx is None and kv.AeAx is None
    assert kv.eB.shape == kv.AeB.shape == kv.G.shape == (TIMES.size, 8)
