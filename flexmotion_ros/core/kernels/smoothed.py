"""Compiled kernel of the lean warm start's smoothed inner problem (numba).

:func:`smoothed_newton` is the Newton iteration of
:func:`~flexmotion_ros.core.time_optimal.lean._inner` (damped Newton on
``u_max sum wq (sqrt(S^2 + eps^2) - eps)`` over the hyperplane's null
space, with its parabolic backtracking), the same formulas in the same
order, in one call instead of ~15 numpy calls per step and ~4 per
line-search try.  The reductions are the same BLAS and LAPACK calls (numba calls SciPy's
``dot``, ``gemv``, ``gemm``, ``gesv``): the switch-time Newton this seeds
ends within its tolerance wherever it starts, so a warm start that differs
in the last bits can move the final switch times by ~1e-12 of ``T``.
"""

from __future__ import annotations

import numpy as np

from .backend import njit


@njit
def smoothed_newton(
    GZ: np.ndarray,
    Z: np.ndarray,
    uw: np.ndarray,
    nuh: np.ndarray,
    S: np.ndarray,
    sq: np.ndarray,
    f: float,
    eps: float,
    shift: float,
    rtol: float,
    steps: int,
):
    """The Newton steps of ``lean._inner`` from ``nuh`` (normalised on the hyperplane).

    ``GZ``: the scaled responses on the grid times the hyperplane's null
    basis ``Z`` (``(points, n - 1)``, ``(n, n - 1)``); ``uw``: ``u_max``
    times the trapezoid weights; ``S``, ``sq = hypot(S, eps)``, ``f``: the
    start's switching function, its smoothed magnitude and objective;
    ``shift``: ``eps sum uw``.  Returns ``(nuh, S, sq, f)`` at the last
    accepted step.  The reductions are the BLAS calls numpy makes
    (``dot``, ``gemv``, ``gemm``) and the solve LAPACK's ``gesv`` (numba
    calls SciPy's), so that the iterates match the reference's.
    """
    GZt = GZ.T
    uwe2 = uw * (eps * eps)
    for _ in range(steps):
        g = GZt @ (uw * S / sq)
        # (GZ w).T: the Fortran-ordered operand numpy's ``GZt * w`` is (same gemm, same sums)
        Hr = (GZ * (uwe2 / (sq * sq * sq)).reshape(-1, 1)).T @ GZ
        dy, ok = solve_or_none(Hr, g)
        dy = -(dy if ok else g)
        dec = -np.dot(g, dy)
        if dec <= rtol * f:
            break
        dS = GZ @ dy
        t = 1.0
        accepted = False
        Sc, sqc, fc = S, sq, f
        for _ in range(40):
            Sc = S + t * dS
            sqc = np.hypot(Sc, eps)
            fc = np.dot(uw, sqc) - shift
            if fc <= f - 0.25 * t * dec:
                accepted = True
                break
            curv = fc - f + t * dec
            t = min(0.5 * t, max(0.1 * t, 0.5 * dec * t * t / curv)) if curv > 0.0 else 0.5 * t
        if not accepted:
            break
        nuh = nuh + t * (Z @ dy)
        S, sq, f = Sc, sqc, fc
    return nuh, S, sq, f


@njit
def solve_or_none(A: np.ndarray, b: np.ndarray):
    """``(x, ok)``: ``A x = b`` by LAPACK's ``gesv`` (``np.linalg.solve``); ``ok`` False if ``A`` is singular."""
    try:
        return np.linalg.solve(A, b), True
    except Exception:  # noqa: BLE001 - numba raises LinAlgError on an exactly zero pivot, as gesv's info > 0
        return b.copy(), False
