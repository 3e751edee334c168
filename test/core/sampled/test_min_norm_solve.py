"""The least-norm corrections of the sampled planners on very long moves (um_zvd fuzz case 875).

``np.linalg.lstsq`` (LAPACK ``gelsd``) segfaulted on a 16 x 4.8 million system, a 13-hour move at
100 Hz, killing the process; past :data:`lp_tools.LSTSQ_MAX_COLUMNS` columns the solve goes through
a QR factorisation of the tall transpose.  Checked here against ``lstsq`` itself.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexmotion_ros.core.sampled import lp_tools


@pytest.mark.parametrize("rank_deficient", [False, True])
def test_the_qr_path_gives_lstsqs_least_norm_solution(monkeypatch, rank_deficient):
    rng = np.random.default_rng(7)
    M = rng.standard_normal((6, 400))
    if rank_deficient:
        M[5] = M[4] * 2.0  # two rows alike: least squares, least norm
    r = rng.standard_normal(6)
    expected = np.linalg.lstsq(M, r, rcond=None)[0]
    monkeypatch.setattr(lp_tools, "LSTSQ_MAX_COLUMNS", 10)
    got = lp_tools.min_norm_solve(M, r)
    np.testing.assert_allclose(got, expected, rtol=0.0, atol=1e-12 * np.max(np.abs(expected)))


def test_a_correction_wider_than_lstsq_takes_lands_exactly():
    """Past the column limit: ``least_norm_correction`` moves a sequence onto ``G^T u = w`` within the bound."""
    K = lp_tools.LSTSQ_MAX_COLUMNS + 1
    t = np.arange(K) / K
    G = np.stack([np.ones(K), t], axis=1) / K  # (K, 2): the mean and the first moment of u
    u = np.full(K, 0.25)
    w = np.array([0.3, 0.1])  # mean 0.3, first moment 0.1: a change within |u| <= 1
    fixed = lp_tools.least_norm_correction(G, w, u, 1.0)
    assert fixed is not None
    assert np.max(np.abs(fixed)) <= 1.0
    np.testing.assert_allclose(G.T @ fixed, w, rtol=0.0, atol=1e-12)
