"""Compiled kernels of the switching function's proved root isolation (numba).

The same formulas, in the same order, as the numpy reference:
:meth:`~flexmotion_ros.core.simulation.modal_response.ModalResponse.switching`
(:func:`switching_orders`), the Taylor-bound bisection of
:func:`~flexmotion_ros.core.time_optimal.switching.isolate_roots`
(:func:`isolate_cells`), the Hermite start and safeguarded Newton of
:mod:`~flexmotion_ros.core.time_optimal.root_refine` (:func:`hermite_start`,
:func:`refine_bracket`), and :func:`isolate_and_refine`, all of it in one
call.  One compiled call replaces the ~25 numpy calls per bisection level
and ~15 per Newton step of the reference, each 1-50 us on a handful of
cells.  Results agree with the reference to the last bits of ``exp``,
``sin``, ``cos`` and the order of sums.

The switching function of a modal model (time-to-go ``tau``, s) is a rigid
part ``b0 (nu_p tau phi1(c tau) + nu_v e^{c tau})`` (without ``nu_p`` when
the position is free) plus, per mode, ``e^{-sigma tau} (a sin(wd tau) + b
cos(wd tau))``; its derivatives of order ``j`` have the coefficients
``coef[:, j]`` on the basis ``[e^{-sigma tau} sin, e^{-sigma tau} cos]``
(``ModalResponse._switching_coefficients``).  The rigid part is passed as
``rigid = (b0, c, nu_p, nu_v, has_position)``.
"""

from __future__ import annotations

import math

import numpy as np

from .backend import njit

#: Machine epsilon of float64.
EPS = float(np.finfo(float).eps)


@njit
def phi1_scalar(z: float) -> float:
    """``(e^z - 1) / z`` (``phi_functions.phi1`` for one value)."""
    if abs(z) >= 1e-12:
        return math.expm1(z) / z
    return 1.0 + 0.5 * z


@njit
def switching_orders(
    tau: np.ndarray,
    k: int,
    b0: float,
    c: float,
    nu_p: float,
    nu_v: float,
    has_position: bool,
    sig: np.ndarray,
    wd: np.ndarray,
    coef: np.ndarray,
) -> np.ndarray:
    """``S, S', ..., S^(k)`` at each ``tau`` (s), shape ``(k + 1, len(tau))``.

    ``coef``: the modes' coefficients, shape ``(2 N, >= k + 1)`` (rows: sine
    terms then cosine terms).
    """
    n = tau.size
    N = sig.size
    out = np.empty((k + 1, n))
    if has_position:
        d1c = b0 * (nu_p + nu_v * c)
    else:
        d1c = b0 * c * nu_v
    cpow = np.empty(k)
    es, ec = np.empty(N), np.empty(N)
    for j in range(k):
        cpow[j] = d1c * c ** float(j)
    for i in range(n):
        t = tau[i]
        if c != 0.0:
            ect = math.exp(c * t)
            lin = t * phi1_scalar(c * t)
            if has_position:
                out[0, i] = b0 * (nu_p * lin + nu_v * ect)
            else:
                out[0, i] = b0 * nu_v * ect
            for j in range(k):
                out[j + 1, i] = cpow[j] * ect
        else:
            if has_position:
                out[0, i] = b0 * (nu_p * t + nu_v)
            else:
                out[0, i] = b0 * nu_v * 1.0
            if k:
                out[1, i] = d1c
            for j in range(1, k):
                out[j + 1, i] = 0.0
        if N:
            for m in range(N):
                e = math.exp(-sig[m] * t)
                arg = wd[m] * t
                es[m] = e * math.sin(arg)
                ec[m] = e * math.cos(arg)
            for j in range(k + 1):
                acc = 0.0
                for m in range(N):
                    acc += es[m] * coef[m, j]
                for m in range(N):
                    acc += ec[m] * coef[N + m, j]
                out[j, i] += acc
    return out


@njit
def derivative_bound_from(a: np.ndarray, rigid_bound: float, c: float, sig: np.ndarray, amp: np.ndarray) -> np.ndarray:
    """``switching_bounds.switching_derivative_bound_from`` from its terms: ``rigid e^{c a} + sum amp e^{-sig a}``."""
    out = np.empty(a.size)
    for i in range(a.size):
        acc = 0.0
        for m in range(sig.size):
            acc += math.exp(-a[i] * sig[m]) * amp[m]
        out[i] = rigid_bound * math.exp(c * a[i]) + acc if sig.size else rigid_bound * math.exp(c * a[i])
    return out


@njit
def isolate_cells(
    a: np.ndarray,
    b: np.ndarray,
    Da: np.ndarray,
    Sb: np.ndarray,
    dSb: np.ndarray,
    b0: float,
    c: float,
    nu_p: float,
    nu_v: float,
    has_position: bool,
    sig: np.ndarray,
    wd: np.ndarray,
    coef: np.ndarray,
    rigid_bound: float,
    amp: np.ndarray,
    noise: float,
    budget: int,
    max_depth: int,
    inv_fact: np.ndarray,
    inv_fact_K: float,
):
    """The bisection of ``isolate_roots``: brackets of exactly one sign change each, and the unproved cells.

    ``Da``: ``S, ..., S^(K)`` at the cells' starts ``a`` (``K = Da.shape[0] - 1``),
    ``Sb``, ``dSb``: ``S``, ``S'`` at their ends ``b``; ``rigid_bound``, ``amp``:
    the terms of the bound on ``|S^(K+1)|`` over ``[a, inf)``;
    ``inv_fact``: ``1 / (j - 1)!`` for ``j = 2..K``.  Returns ``(brackets,
    unproved)`` with ``brackets`` of shape ``(6, m)``: ``a, b, S(a), S(b),
    S'(a), S'(b)`` (the order of the reference: by depth, then cell).
    """
    K = Da.shape[0] - 1
    cap = 16
    br = np.empty((6, cap))
    nb = 0
    unproved = 0
    for depth in range(max_depth + 1):
        m = a.size
        h = b - a
        bnd = derivative_bound_from(a, rigid_bound, c, sig, amp)
        todo = np.zeros(m, dtype=np.bool_)
        ntodo = 0
        for i in range(m):
            hi = h[i]
            hp = hi
            R = 0.0
            for j in range(K - 1):
                R += abs(Da[2 + j, i]) * hp * inv_fact[j]
                hp *= hi
            R += bnd[i] * hp * inv_fact_K
            Sa, dSa = Da[0, i], Da[1, i]
            change = np.sign(Sa) * np.sign(Sb[i]) < 0
            free = (not change) and (abs(Sa) + abs(Sb[i]) > (abs(dSa) + R) * hi)
            mono = abs(dSa) > R
            if change and mono:
                if nb == cap:
                    cap *= 2
                    grown = np.empty((6, cap))
                    grown[:, :nb] = br[:, :nb]
                    br = grown
                br[0, nb], br[1, nb], br[2, nb] = a[i], b[i], Sa
                br[3, nb], br[4, nb], br[5, nb] = Sb[i], dSa, dSb[i]
                nb += 1
            if not (free or mono):
                todo[i] = True
                ntodo += 1
        if ntodo == 0:
            break
        idx = np.flatnonzero(todo)
        a, b, Da, Sb, dSb = a[idx], b[idx], Da[:, idx], Sb[idx], dSb[idx]
        if depth == max_depth or a.size > budget:
            unproved = a.size
            for i in range(a.size):
                if np.sign(Da[0, i]) * np.sign(Sb[i]) < 0:
                    if nb == cap:
                        cap *= 2
                        grown = np.empty((6, cap))
                        grown[:, :nb] = br[:, :nb]
                        br = grown
                    br[0, nb], br[1, nb], br[2, nb] = a[i], b[i], Da[0, i]
                    br[3, nb], br[4, nb], br[5, nb] = Sb[i], Da[1, i], dSb[i]
                    nb += 1
            break
        mid = 0.5 * (a + b)
        Dm = switching_orders(mid, K, b0, c, nu_p, nu_v, has_position, sig, wd, coef)
        # a midpoint on a zero: S(mid) may round to exactly 0, hiding the sign change from both halves
        for frac in (1.0 / 3.0, 2.0 / 3.0):
            on_zero = np.flatnonzero(np.abs(Dm[0]) <= noise)
            if on_zero.size == 0:
                break
            for i in on_zero:
                mid[i] = a[i] + frac * (b[i] - a[i])
            Dz = switching_orders(mid[on_zero], K, b0, c, nu_p, nu_v, has_position, sig, wd, coef)
            for q in range(on_zero.size):
                Dm[:, on_zero[q]] = Dz[:, q]
        n = a.size
        a2, b2 = np.empty(2 * n), np.empty(2 * n)
        Da2 = np.empty((K + 1, 2 * n))
        Sb2, dSb2 = np.empty(2 * n), np.empty(2 * n)
        a2[:n], a2[n:] = a, mid
        b2[:n], b2[n:] = mid, b
        Da2[:, :n], Da2[:, n:] = Da, Dm
        Sb2[:n], Sb2[n:] = Dm[0], Sb
        dSb2[:n], dSb2[n:] = Dm[1], dSb
        a, b, Da, Sb, dSb = a2, b2, Da2, Sb2, dSb2
    return br[:, :nb].copy(), unproved


@njit
def hermite_start(a: float, b: float, fa: float, fb: float, da: float, db: float) -> float:
    """``root_refine.hermite_root`` for one bracket: the zero of the cubic Hermite interpolant."""
    h = b - a
    hda, hdb = h * da, h * db
    c1 = hda
    c2 = 3.0 * (fb - fa) - 2.0 * hda - hdb
    c3 = 2.0 * (fa - fb) + hda + hdb
    d2, d3 = 2.0 * c2, 3.0 * c3
    x = fa / (fa - fb)
    if x < 0.0:
        x = 0.0
    elif x > 1.0:
        x = 1.0
    for _ in range(4):
        p = ((c3 * x + c2) * x + c1) * x + fa
        dp = (d3 * x + d2) * x + c1
        x = x - p / dp
        if x < 0.0:
            x = 0.0
        elif x > 1.0:
            x = 1.0
    if not math.isfinite(x):
        x = 0.5
    return a + x * h


@njit
def refine_bracket(
    a: float,
    b: float,
    fa: float,
    start: float,
    noise: float,
    b0: float,
    c: float,
    nu_p: float,
    nu_v: float,
    has_position: bool,
    sig: np.ndarray,
    wd: np.ndarray,
    coef: np.ndarray,
) -> float:
    """``root_refine.refine_roots`` for one bracket: Newton, bisection when a step leaves ``[a, b]``."""
    if math.isfinite(start):
        t = min(max(start, a), b)
    else:
        t = 0.5 * (a + b)
    one = np.empty(1)
    for _ in range(100):
        one[0] = t
        D = switching_orders(one, 1, b0, c, nu_p, nu_v, has_position, sig, wd, coef)
        v, dv = D[0, 0], D[1, 0]
        if np.sign(v) == np.sign(fa):
            a, fa = t, v
        else:
            b = t
        step = v / dv
        tol = 4.0 * EPS * max(abs(t), 1e-300)
        if abs(v) <= noise or abs(step) <= tol or (b - a) <= tol:
            return t - (step if math.isfinite(step) else 0.0)
        tn = t - step
        if not math.isfinite(tn) or tn < a or tn > b:
            tn = 0.5 * (a + b)
        t = tn
    return t


@njit
def isolate_and_refine(
    a: np.ndarray,
    b: np.ndarray,
    Da: np.ndarray,
    Sb: np.ndarray,
    dSb: np.ndarray,
    b0: float,
    c: float,
    nu_p: float,
    nu_v: float,
    has_position: bool,
    sig: np.ndarray,
    wd: np.ndarray,
    coef: np.ndarray,
    rigid_bound: float,
    amp: np.ndarray,
    noise: float,
    budget: int,
    max_depth: int,
    inv_fact: np.ndarray,
    inv_fact_K: float,
    refine_noise: float,
):
    """:func:`isolate_cells`, then every bracket refined (:func:`hermite_start`, :func:`refine_bracket`).

    Returns ``(roots, unproved)``, ``roots`` sorted (time-to-go, s).
    """
    br, unproved = isolate_cells(
        a, b, Da, Sb, dSb, b0, c, nu_p, nu_v, has_position, sig, wd, coef,
        rigid_bound, amp, noise, budget, max_depth, inv_fact, inv_fact_K,
    )  # fmt: skip
    roots = np.empty(br.shape[1])
    for i in range(roots.size):
        start = hermite_start(br[0, i], br[1, i], br[2, i], br[3, i], br[4, i], br[5, i])
        roots[i] = refine_bracket(
            br[0, i], br[1, i], br[2, i], start, refine_noise, b0, c, nu_p, nu_v, has_position, sig, wd, coef
        )
    return np.sort(roots), unproved
