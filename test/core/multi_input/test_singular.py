"""Unit tests of :mod:`flexmotion_ros.core.multi_input.singular`'s subspace helpers."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from flexmotion_ros.core.multi_input.singular import complement_within


def _orthonormal(rng: np.random.Generator, n: int, k: int) -> np.ndarray:
    return np.linalg.qr(rng.standard_normal((n, k)))[0]


@settings(max_examples=30)
@given(st.integers(0, 2**32 - 1), st.integers(2, 8), st.data())
def test_complement_of_a_subspace_inside_R_is_empty_and_of_the_whole_space_is_R_perp(seed, n, data):
    """``span(V)`` inside ``span(R)`` leaves nothing, however the bases are rotated (issue 15: a relative
    threshold kept the rounding of ``V - R R^T V`` as spurious directions); the whole space leaves ``R``'s
    orthogonal complement."""
    rng = np.random.default_rng(seed)
    k = data.draw(st.integers(1, n - 1))
    R = _orthonormal(rng, n, k)
    V = R @ _orthonormal(rng, k, data.draw(st.integers(1, k)))  # another basis of a subspace of span(R)
    assert complement_within(V, R, n).shape == (n, 0)
    P = complement_within(None, R, n)
    assert P.shape == (n, n - k)
    assert np.allclose(P.T @ P, np.eye(n - k), atol=1e-12)
    assert np.max(np.abs(R.T @ P)) < 1e-12
