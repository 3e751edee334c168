"""Event location on the exact solution of an affine system (the friction simulator's events).

Used by :class:`~.contact.FrictionSystem` where the sliding velocity does not
obey a scalar ODE (a contact inside the structure): the first zero of a linear
function of the state is bracketed on a grid of 1/16 of the fastest period
with a cubic Hermite dip test and refined by Brent's method on the
matrix-exponential solution.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm
from scipy.optimize import brentq


def affine_apply(M: np.ndarray, m: np.ndarray, x: np.ndarray, h: float) -> np.ndarray:
    """Exact ``x(h)`` for one odd step length (uncached: keeps the shared cache for sample periods)."""
    n = M.shape[0]
    Z = np.zeros((n + 1, n + 1))
    Z[:n, :n] = M
    Z[:n, n] = m
    E = expm(Z * h)
    return E[:n, :n] @ x + E[:n, n]


def first_root(M, m, x0, w, k, h: float, wmax: float, step, start_sign=None) -> float | None:
    """First zero in ``(0, h]`` (s) of ``r(t) = w.x(t) + k``, ``x' = M x + m`` (exact solution).

    ``wmax``: the largest imaginary part of ``M``'s eigenvalues (rad/s), the bracketing grid's scale;
    ``step(M, m, d) -> (Phi, Gam)``: the exact step ``x(d) = Phi x + Gam`` (the simulator's cached one).
    """
    cells = max(4, math.ceil(h * wmax * 16.0 / (2.0 * math.pi))) if wmax > 0.0 else 4
    cells = min(cells, 100000)
    d = h / cells
    Phi, Gam = step(M, m, d)
    xs = np.empty((cells + 1, x0.size))
    xs[0] = x0
    for i in range(cells):
        xs[i + 1] = Phi @ xs[i] + Gam
    r = xs @ w + k
    dr = (xs @ M.T + m) @ w
    s0 = start_sign if start_sign is not None else (np.sign(r[0]) or np.sign(dr[0]))
    if r[0] * s0 <= 0.0:
        # starting on the surface (an event just happened) with a rounding residue of the
        # wrong sign: remove the residue, so the motion away from the surface is no root
        k = k - r[0]
        r = r - r[0]
        r[0] = s0 * 1e-300
    scale = float(np.max(np.abs(r))) + 1e-300
    for i in range(cells):
        a, b = r[i], r[i + 1]
        if a * b <= 0.0:
            lo_t, hi_t = 0.0, d
        else:
            # cubic Hermite dip: a double zero hidden between two samples
            ss = np.linspace(0.0, 1.0, 9)[1:-1]
            h00, h10 = 2 * ss**3 - 3 * ss**2 + 1, ss**3 - 2 * ss**2 + ss
            h01, h11 = -2 * ss**3 + 3 * ss**2, ss**3 - ss**2
            cub = h00 * a + h10 * d * dr[i] + h01 * b + h11 * d * dr[i + 1]
            j = int(np.argmin(cub * np.sign(a)))
            if cub[j] * np.sign(a) > 0.05 * scale:
                continue
            tm = ss[j] * d
            xm = affine_apply(M, m, xs[i], tm)
            if (xm @ w + k) * a > 0.0:
                continue
            lo_t, hi_t = 0.0, tm
        xi = xs[i]

        def f(t, xi=xi):
            return float(affine_apply(M, m, xi, t) @ w + k)

        fb = f(hi_t)
        if lo_t == 0.0 and i == 0:
            # leaving the surface at t = 0: step back from hi_t until f has the start sign
            t1, f1 = hi_t, fb
            while f1 * s0 <= 0.0 and t1 > 1e-12 * d:
                hi_t, fb = t1, f1
                t1 *= 0.5
                f1 = f(t1)
            if f1 * s0 <= 0.0:
                continue  # no excursion away from the surface: nothing to find here
            lo_t, fa = t1, f1
        else:
            fa = f(lo_t) if lo_t > 0.0 else a
        if fb == 0.0:
            return i * d + hi_t
        if fa * fb > 0.0:
            continue
        t = lo_t if fa == 0.0 else brentq(f, lo_t, hi_t, xtol=4e-16 * max(h, 1e-300), rtol=8.9e-16)
        tau = i * d + t
        if tau > 0.0:
            return tau
    return None
