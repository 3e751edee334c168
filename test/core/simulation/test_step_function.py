"""``exact.step_function``: one system's step matrices with the cache key taken once (``simulate`` and the certificate).

The same matrices, bit for bit, as :func:`step_matrices`; :func:`simulate` builds the key once per
call, not once per piece.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexmotion_ros.core.model.modal_model import ModalModel
from flexmotion_ros.core.simulation import exact


def test_step_function_equals_step_matrices_and_simulate_takes_one_key():
    model = ModalModel(b0=1.5, c=-0.1, omega=(3.0, 17.0), zeta=(0.02, 0.05), b=(0.7, -1.2))
    A, B = model.A(), model.B()
    step = exact.step_function(A, B)
    for h in (1e-9, 0.013, 0.5, 2.0):
        P1, G1 = step(h)
        P2, G2 = exact.step_matrices(A, B, h)
        assert np.array_equal(P1, P2) and np.array_equal(G1, G2)
    u = exact.PiecewiseConstant.from_switches([0.1, 0.25, 0.4, 0.61, 0.7], [1.0, -1.0, 1.0, -1.0, 1.0, -1.0], 0.9)
    x0 = np.array([0.3, -0.1, 0.01, 0.0, 0.0, 0.2])
    built = []
    real = exact.step_function
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(exact, "step_function", lambda *a: built.append(1) or real(*a))
        X = exact.simulate(model, x0, u)
    assert len(built) == 1
    x = x0.copy()
    for k in range(u.levels.size):  # the piecewise propagation by step_matrices, piece by piece
        Phi, Gam = exact.step_matrices(A, B, u.breaks[k + 1] - u.breaks[k])
        x = Phi @ x + Gam * u.levels[k]
        assert np.array_equal(X[k + 1], x)
