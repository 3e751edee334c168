"""The multi-input demo figure: every drive, axis and sway; the continuation after the move is the exact free motion."""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from flexmotion_ros.core.multi_input import gantry
from flexmotion_ros.plots.multi_demo import continuation, plot_multi_demo, sway


def test_continuation_is_the_exact_zero_input_motion():
    g = gantry(10.0, 40.0, 5.0, 2.0, trolley_force=30.0, bridge_force=50.0)
    x = np.array([1.0, 0.2, -0.5, 0.0, 0.1, -0.3, 0.02, 0.05])
    t, X = continuation(g.model, 2.0, x, periods=1.0, n=50)
    A = g.model.A()
    for i in (0, 17, 49):  # scipy's expm, independent of the core's propagation
        np.testing.assert_allclose(X[i], expm(A * (t[i] - 2.0)) @ x, rtol=0, atol=1e-12)
    # a free undamped sway keeps its amplitude
    np.testing.assert_allclose(sway(g.model, X), np.broadcast_to(sway(g.model, x[None])[0], (50, 2)), rtol=1e-9)


def test_the_figure_is_written(tmp_path):
    g = gantry(10.0, 40.0, 5.0, 2.0, trolley_force=30.0, bridge_force=50.0)
    t = np.linspace(0.0, 1.0, 11)
    X = np.zeros((11, 8))
    X[:, 0], X[:, 2] = t, 0.5 * t
    u = np.zeros((11, 2))
    path = tmp_path / "multi.png"
    plot_multi_demo(str(path), t, u, [30.0, 50.0], t, X, [1.0, 0.5], [0.0, 0.0], g.model, "test", 1.0)
    assert path.stat().st_size > 10_000
