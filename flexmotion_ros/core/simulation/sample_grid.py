"""Free responses of a modal model on a uniform sample grid, from complex power products.

The sampled planners need ``e^{A m dt} x`` for every ``m = 0..K-1`` (``K``: a
few thousand at 1 kHz).  :meth:`ModalResponse.expm_x_many` evaluates an
exponential, a cosine and a sine per mode and time.  On a uniform grid a
mode's complex amplitude is ``z_m = e^{lambda dt m}`` (``lambda = -sigma +
i omega_d``), and with ``m = a B + b`` (``B ~ sqrt(K)``) it is the product
``e^{lambda dt B a} e^{lambda dt b}`` of two short tables: one complex
multiplication per mode and sample instead of three transcendental
functions (2.5-3x faster for 1-8 modes at ``K = 5000``).  Each ``z_m`` is a
product of two correctly rounded exponentials (a few ulp, no accumulation
over ``m``).  Both columns of a mode are ``Re(c z_m)`` for a complex ``c``
fixed by ``x``: ``E (C + s S) q + E S / wd q' = Re(z (q - i (s q + q' / wd)))``
with ``s = sigma / omega_d``.

As everything in the planners' fast path, nothing computed here is trusted:
every sequence is checked by the matrix exponentials of
:mod:`flexmotion_ros.core.simulation.exact` (``sampled.check.verified_samples``).
"""

from __future__ import annotations

import math

import numpy as np

from .modal_response import ModalResponse, phi1


def expm_x_grid(response: ModalResponse, dt: float, K: int, x: np.ndarray) -> np.ndarray:
    """``e^{A m dt} x`` for ``m = 0..K-1``, shape ``(K, n)`` (as ``response.expm_x_many(dt * arange(K), x)``).

    Parameters
    ----------
    response : ModalResponse
        The model's closed-form responses (its state order, with or without
        the position).
    dt : float
        Grid step (s), ``> 0``.
    K : int
        Number of grid points, ``>= 0``.
    x : ndarray
        State (the response's order).
    """
    x = np.asarray(x, dtype=float)
    out = np.empty((K, response.n))
    if K == 0:
        return out
    tau = dt * np.arange(K)
    r = response.r
    if response.c == 0.0:  # phi1(0) = e^0 = 1 exactly
        if response.include_position:
            out[:, 0] = x[0] + x[1] * tau
        out[:, r - 1] = x[r - 1]
    else:
        ct = response.c * tau
        if response.include_position:
            out[:, 0] = x[0] + x[1] * tau * phi1(ct)
        out[:, r - 1] = x[r - 1] * np.exp(ct)
    if response.w.size:
        lam = (-response.sig + 1j * response.wd) * dt  # per-sample exponent of each mode
        block = max(1, math.isqrt(K))
        n_blocks = -(-K // block)
        inner = np.exp(np.arange(block)[:, None] * lam)  # (block, N): e^{lam b}
        outer = np.exp((block * np.arange(n_blocks))[:, None] * lam)  # (n_blocks, N): e^{lam B a}
        z = (outer[:, None, :] * inner[None, :, :]).reshape(n_blocks * block, -1)[:K]
        q = x[r::2]
        qd = x[r + 1 :: 2]
        s_wd = response.sig / response.wd
        c_q = q - 1j * (s_wd * q + qd / response.wd)
        c_qd = qd + 1j * (response.w**2 / response.wd * q + s_wd * qd)
        out[:, r::2] = (z * c_q).real
        out[:, r + 1 :: 2] = (z * c_qd).real
    return out
