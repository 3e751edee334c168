"""Root isolation from a grid's shared trigonometric basis gives what the per-point evaluation gives."""

from __future__ import annotations

import numpy as np

from flexmotion_ros.core import ModalModel
from flexmotion_ros.core.simulation.modal_response import ModalResponse
from flexmotion_ros.core.time_optimal import switching
from flexmotion_ros.core.time_optimal.switching import isolate_roots, sample_grid

MODEL = ModalModel(b0=0.8, c=0.0, omega=(0.7, 3.1, 23.0), zeta=(0.002, 0.05, 0.005), b=(1.2, -0.6, 0.4))


def test_switching_on_rows_of_a_grid_is_the_switching_function_there():
    system = ModalResponse(MODEL)
    grid = sample_grid(system, 40.0)
    rows = np.flatnonzero(np.arange(grid.size) % 3 != 1)
    nu = np.array([0.3, -1.0, 0.2, 0.05, -0.4, 0.1, 0.02, -0.03])
    full = np.array(system.switching(nu, grid, order=4, rows=rows))
    direct = np.array(system.switching(nu, grid[rows], order=4))
    scale = np.max(np.abs(direct), axis=1, keepdims=True)
    assert np.all(np.abs(full - direct) <= 1e-13 * scale)


def test_isolation_from_the_shared_basis_finds_the_same_zeros(monkeypatch):
    system = ModalResponse(MODEL)
    T = 60.0
    grid = sample_grid(system, T)
    # a co-state whose modes ring over the whole move: most cells are examined
    nu = np.array([0.01, -0.3, 0.8, -0.2, 0.5, 0.3, 0.6, -0.4])
    monkeypatch.setattr(switching, "SHARED_BASIS_SHARE", 2.0)  # never
    per_point = isolate_roots(system, nu, T, grid)
    monkeypatch.setattr(switching, "SHARED_BASIS_SHARE", 0.0)  # always
    shared = isolate_roots(system, nu, T, grid)
    assert per_point.roots.size > 10 and per_point.unproved == shared.unproved == 0
    assert per_point.sign0 == shared.sign0
    np.testing.assert_allclose(shared.roots, per_point.roots, rtol=0.0, atol=1e-12 * T)
