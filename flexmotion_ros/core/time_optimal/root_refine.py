"""Zeros of the switching function ``S`` refined to machine precision, and how precisely they are determined.

:func:`refine_roots`: safeguarded Newton on many brackets at once, started
from the zero of each bracket's cubic Hermite interpolant
(:func:`hermite_root`); :func:`root_tolerance`: the precision of a zero
given the rounding of ``S``.  The brackets come from the proved isolation
of :func:`~.switching.isolate_roots`.
"""

from __future__ import annotations

import numpy as np


def refine_roots(
    f, a: np.ndarray, b: np.ndarray, fa: np.ndarray, fb: np.ndarray, fscale: float | None = None, start=None
) -> np.ndarray:
    """Zeros of ``f`` in brackets ``[a, b]`` (``fa * fb <= 0``), to machine precision.

    ``f(t)`` returns ``(value, derivative)``.  Newton steps, with bisection
    whenever a step leaves the bracket; all brackets at once.  A value below
    ``16 eps fscale`` (rounding noise of ``f``: pass the magnitude of its
    terms) counts as zero.
    """
    noise = (
        16.0
        * np.finfo(float).eps
        * (fscale if fscale is not None else float(np.max(np.abs(np.concatenate([fa, fb])), initial=0.0)))
    )
    a = a.copy()
    b = b.copy()
    fa = fa.copy()
    eps = np.finfo(float).eps
    # every bracket is stepped in place, the converged ones frozen by ``active`` (a handful of
    # brackets: gathering and scattering the active ones cost more numpy calls than the steps)
    with np.errstate(divide="ignore", invalid="ignore"):
        if start is None:
            start = a - fa * (b - a) / (fb - fa)  # regula falsi start
        t = np.where(np.isfinite(start), np.clip(start, a, b), 0.5 * (a + b))
        active = np.ones(t.shape, dtype=bool)
        for _ in range(100):
            v, dv = f(t)
            same = np.sign(v) == np.sign(fa)
            a = np.where(active & same, t, a)
            fa = np.where(active & same, v, fa)
            b = np.where(active & ~same, t, b)
            step = v / dv
            tol = 4.0 * eps * np.maximum(np.abs(t), 1e-300)
            done = (np.abs(v) <= noise) | (np.abs(step) <= tol) | ((b - a) <= tol)
            tn = t - step
            bad = ~np.isfinite(tn) | (tn < a) | (tn > b)
            tn = np.where(done, t - np.where(np.isfinite(step), step, 0.0), np.where(bad, 0.5 * (a + b), tn))
            t = np.where(active, tn, t)
            active &= ~done
            left = int(np.count_nonzero(active))
            if left == 0:
                break
            if 2 * left < t.size and t.size > 16:  # many brackets, most done: go on with the others alone
                idx = np.flatnonzero(active)
                fs = noise / (16.0 * eps)
                t[idx] = refine_roots(f, a[idx], b[idx], fa[idx], fb[idx], fs, start=t[idx])
                break
    return t


def hermite_root(a, b, fa, fb, da, db) -> np.ndarray:
    """Zero of the cubic Hermite interpolant on each bracket: a close start for Newton.

    The interpolant on ``x = (t - a) / h`` in monomial form ``c0 + c1 x + c2
    x^2 + c3 x^3`` (Horner: a third of the numpy calls of the Hermite basis),
    four Newton steps from the secant's zero, clipped to the bracket.
    """
    h = b - a
    hda, hdb = h * da, h * db
    c1 = hda
    c2 = 3.0 * (fb - fa) - 2.0 * hda - hdb
    c3 = 2.0 * (fa - fb) + hda + hdb
    d2, d3 = 2.0 * c2, 3.0 * c3
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.clip(fa / (fa - fb), 0.0, 1.0)
        for _ in range(4):
            p = ((c3 * x + c2) * x + c1) * x + fa
            dp = (d3 * x + d2) * x + c1
            x = np.clip(x - p / dp, 0.0, 1.0)
    x = np.where(np.isfinite(x), x, 0.5)
    return a + x * h


def root_tolerance(
    system, nu: np.ndarray, T: float, roots: np.ndarray, rtol: float = 1e-9, magnitude: float | None = None
) -> np.ndarray:
    """How precisely each zero of ``S`` is determined (s).

    ``max(rtol T, noise / |S'(root)|)`` with ``noise`` a generous bound on the
    rounding error of ``S`` (terms that cancel); in a tight cluster of zeros
    ``|S'|`` is small and a zero's position is only known to that precision.
    ``magnitude``: ``system.switching_magnitude(nu, T)[0]`` if the caller has it.
    """
    if roots.size == 0:
        return np.empty(0)
    mag0 = system.switching_magnitude(nu, T)[0] if magnitude is None else magnitude
    _, dS = system.switching(nu, roots, derivative=True)
    noise = 1e3 * np.finfo(float).eps * mag0
    with np.errstate(divide="ignore"):
        return np.maximum(rtol * T, noise / np.abs(dS))
