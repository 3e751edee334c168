"""The friction fast path's one-step closed forms (:class:`ClosedForm`) are ``ModalResponse``'s numbers to the bit.

:meth:`ClosedForm.steps` computes ``e^{A h}``, ``Gamma(h)`` and the friction term for one ``h`` with
scalar and per-mode operations instead of ``ModalResponse``'s array versions (a speed change only):
the same operations in the same order, so every planner that steps with it gives the same numbers.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm

from flexmotion_ros.core import ModalModel
from flexmotion_ros.core.friction.closed_form import ClosedForm
from flexmotion_ros.core.simulation.modal_response import ModalResponse


def _reference_phi(resp: ModalResponse, h: float) -> np.ndarray:
    """``e^{A h}`` as ``ClosedForm.steps`` formed it from ``ModalResponse``'s arrays (2-D, one time)."""
    n = resp.n
    Phi = np.zeros((n, n))
    ch = resp.c * h
    Phi[0, 0] = 1.0
    Phi[0, 1] = h * (math.expm1(ch) / ch if ch != 0.0 else 1.0)
    Phi[1, 1] = math.exp(ch)
    if resp.w.size:
        t = np.array([h])[:, None]
        E, C, S = np.exp(-resp.sig * t)[0], np.cos(resp.wd * t)[0], np.sin(resp.wd * t)[0]
        s_wd = resp.sig / resp.wd
        i = 2 + 2 * np.arange(resp.w.size)
        Phi[i, i] = E * (C + s_wd * S)
        Phi[i, i + 1] = E * S / resp.wd
        Phi[i + 1, i] = -E * resp.w**2 / resp.wd * S
        Phi[i + 1, i + 1] = E * (C - s_wd * S)
    return Phi


def _models():
    rng = np.random.default_rng(20261205)
    for index in range(60):
        N = index % 5
        omega = np.sort(np.exp(rng.uniform(math.log(0.3), math.log(60.0), N)))
        c = -float(rng.uniform(0.0, 1.5)) if index % 2 else 0.0
        b0 = float(rng.choice([-1.0, 1.0]) * np.exp(rng.uniform(-2.3, 1.6)))
        yield ModalModel(
            b0=b0, c=c, omega=tuple(omega), zeta=tuple(rng.uniform(0.0, 0.3, N)), b=tuple(rng.uniform(-2, 2, N))
        )


@pytest.mark.parametrize("model", list(_models()), ids=lambda m: f"N{m.n_modes}_c{m.c:.2f}")
def test_steps_are_modal_response_to_the_bit(model):
    cf = ClosedForm(model)
    resp = ModalResponse(model, True)
    # both sides of phi2's series threshold (|c h| = 0.1) and phi1's (1e-12), tiny to long steps
    hs = np.concatenate([np.geomspace(1e-14, 1e3, 37), [0.0, 0.01, 0.1 / abs(model.c) if model.c else 1.0]])
    for h in hs.tolist():
        Phi, Gam, Gg = cf.steps(h)
        ref_gam = resp.input_integral(np.array([h]))[0]
        assert np.array_equal(Gam, ref_gam), h
        assert np.array_equal(Phi, _reference_phi(resp, h)), h
        assert np.array_equal(Gg[:2], ref_gam[:2] * np.sign(model.b0)) and not np.any(Gg[2:]), h


def test_steps_match_matrix_exponentials():
    """Independently of ``ModalResponse``: the augmented matrix exponential (scipy ``expm``)."""
    for model in list(_models())[:20]:
        A, B = model.A(), model.B()
        n = A.shape[0]
        cf = ClosedForm(model)
        for h in (1e-3, 0.37, 2.5):
            M = np.zeros((n + 1, n + 1))
            M[:n, :n], M[:n, n] = A * h, B * h
            E = expm(M)
            Phi, Gam, _ = cf.steps(h)
            assert np.allclose(Phi, E[:n, :n], rtol=1e-9, atol=1e-12 * np.max(np.abs(E[:n, :n])))
            assert np.allclose(Gam, E[:n, n], rtol=1e-9, atol=1e-12 * max(np.max(np.abs(E[:n, n])), 1e-300))
