"""The phi-functions of the rigid body's closed forms: ``(e^z - 1) / z`` and ``(e^z - 1 - z) / z^2``, accurate near 0.

``e^{c tau}`` integrated once and twice is ``tau phi1(c tau)`` and
``tau^2 phi2(c tau)``: the rigid body's responses with a damping ``c``
(:mod:`.modal_response`, :mod:`.modal_kernel`, :mod:`.sample_grid`), without
the cancellation of ``(e^z - 1) / z`` at small ``z``.
"""

from __future__ import annotations

import math

import numpy as np

_SERIES_Z = 0.1  # |c tau| below which phi-functions use their Taylor series


def phi1(z: np.ndarray) -> np.ndarray:
    """``(e^z - 1) / z`` with the removable singularity at 0 filled in."""
    z = np.asarray(z, dtype=float)
    out = np.ones_like(z)
    big = np.abs(z) >= 1e-12
    out[big] = np.expm1(z[big]) / z[big]
    small = ~big
    out[small] = 1.0 + 0.5 * z[small]
    return out


def phi2(z: np.ndarray) -> np.ndarray:
    """``(e^z - 1 - z) / z^2`` accurately near 0 (Taylor series below |z| = 0.1)."""
    z = np.asarray(z, dtype=float)
    out = np.empty_like(z)
    big = np.abs(z) >= _SERIES_Z
    zb = z[big]
    out[big] = (np.expm1(zb) - zb) / (zb * zb)
    zs = z[~big]
    # sum_{k>=0} z^k / (k+2)!, 9 terms: truncation < 0.1^9/11! ~ 3e-17
    acc = np.zeros_like(zs)
    for k in range(8, -1, -1):
        acc = acc * zs + 1.0 / math.factorial(k + 2)
    out[~big] = acc
    return out
