"""Proved bounds on a modal model's switching function ``S(tau) = nu^T e^{A tau} B``, in closed form.

What the certificate and the root isolation need to prove that ``S`` has no
zero where it is not sampled: the sum of its terms' magnitudes (the rounding
unit of ``S``), bounds on its derivatives over ``[0, tau_max]`` or over
``[tau, inf)``, and intervals proved zero-free (the rigid part monotone and
larger than every mode's decaying amplitude).  Each mode's term
``e^{-sigma tau} (a sin + b cos)`` is bounded by its amplitude ``hypot(a, b)``.
:class:`~.modal_response.ModalResponse` offers these as its methods
(``switching_magnitude``, ``switching_derivative_bound(s)``,
``switching_derivative_bound_from``, ``switching_zero_free``).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from .phi_functions import phi1


class SwitchingTerms(Protocol):
    """The closed-form terms of ``S`` these bounds read (a :class:`~.modal_response.ModalResponse`)."""

    #: Rigid-block size: 2 with the position, 1 without.
    r: int
    include_position: bool
    #: Rigid-body input gain and damping (1/s).
    b0: float
    c: float
    #: Modes' natural and damped frequencies (rad/s), decay rates (1/s), input gains.
    w: np.ndarray
    wd: np.ndarray
    sig: np.ndarray
    bm: np.ndarray


def switching_magnitude(resp: SwitchingTerms, nu: np.ndarray, tau_max: float) -> tuple[float, float]:
    """Sums of the magnitudes of the terms of ``S`` and ``S'`` on ``[0, tau_max]``.

    Rounding errors in evaluating ``S`` are about ``eps`` times this, which
    may be far above ``|S|`` when the terms cancel (short moves).
    """
    nu = np.asarray(nu, dtype=float)
    nv = abs(nu[resp.r - 1])
    b0 = abs(resp.b0)
    if resp.include_position:
        # the position term nu_p (e^{c tau} - 1) / c grows like tau only for c = 0: with
        # friction it stays below nu_p / |c| (a bound T |nu_p| hid every zero-free block of a
        # long move behind a margin a thousand times |S|: 0.4 s of sampling per guess)
        reach = tau_max if resp.c == 0.0 else tau_max * float(phi1(np.array([resp.c * tau_max]))[0])
        m0 = b0 * (abs(nu[0]) * reach + nv)
        m1 = b0 * (abs(nu[0]) + nv * abs(resp.c))
    else:
        m0 = b0 * nv
        m1 = b0 * abs(resp.c) * nv
    if resp.w.size:
        bm = np.abs(resp.bm)
        q = np.abs(nu[resp.r :: 2]) * bm / resp.wd
        qd = np.abs(nu[resp.r + 1 :: 2]) * bm * (1.0 + resp.sig / resp.wd)
        m0 += float(np.sum(q + qd))
        m1 += float(np.sum((q + qd) * resp.w))
    return m0, m1


def switching_derivative_bound(resp: SwitchingTerms, nu: np.ndarray, order: int) -> float:
    """Upper bound on ``|d^order S / dtau^order|`` over ``tau >= 0`` (``order >= 1``)."""
    nu = np.asarray(nu, dtype=float)
    c = abs(resp.c)
    nv = abs(nu[resp.r - 1])
    if resp.include_position:
        bound = abs(resp.b0) * (abs(nu[0]) + nv * c) * c ** (order - 1)
    else:
        bound = abs(resp.b0) * nv * c**order
    if resp.w.size:
        a = nu[resp.r :: 2] * resp.bm / resp.wd - nu[resp.r + 1 :: 2] * resp.bm * resp.sig / resp.wd
        amp = np.hypot(a, nu[resp.r + 1 :: 2] * resp.bm)
        bound += float(np.sum(amp * resp.w**order))
    return bound


def switching_derivative_bound_from(resp: SwitchingTerms, nu: np.ndarray, order: int, tau: np.ndarray) -> np.ndarray:
    """Upper bound on ``|d^order S / dtau^order|`` over ``[tau, inf)``, for each ``tau``.

    Every term of ``S`` decays (``e^{c tau}``, ``e^{-zeta omega tau}``), so
    its bound at the start of an interval holds on the whole interval;
    far from ``tau = 0`` on long, damped moves this is much tighter than
    :func:`switching_derivative_bound`.
    """
    tau = np.asarray(tau, dtype=float)
    rigid, amp = derivative_bound_terms(resp, nu, order)
    bound = rigid * np.exp(resp.c * tau)
    if resp.w.size:
        bound = bound + np.exp(-np.outer(tau, resp.sig)) @ amp
    return bound


def derivative_bound_terms(resp: SwitchingTerms, nu: np.ndarray, order: int) -> tuple[float, np.ndarray]:
    """The terms of :func:`switching_derivative_bound_from`: ``(rigid, amp)``, the bound being ``rigid e^{c tau} + amp . e^{-sigma tau}``."""
    nu = np.asarray(nu, dtype=float)
    c = abs(resp.c)
    nv = abs(nu[resp.r - 1])
    if resp.include_position:
        rigid = abs(resp.b0) * (abs(nu[0]) + nv * c) * c ** (order - 1)
    else:
        rigid = abs(resp.b0) * nv * c**order
    amp = np.empty(0)
    if resp.w.size:
        a = nu[resp.r :: 2] * resp.bm / resp.wd - nu[resp.r + 1 :: 2] * resp.bm * resp.sig / resp.wd
        amp = np.hypot(a, nu[resp.r + 1 :: 2] * resp.bm) * resp.w**order
    return float(rigid), amp


def switching_zero_free(
    resp: SwitchingTerms, nu: np.ndarray, a: np.ndarray, b: np.ndarray, margin: float
) -> np.ndarray:
    """Which intervals ``[a, b]`` are proved to hold no zero of ``S`` (bool per interval).

    ``S`` is the rigid part ``R`` (monotone in ``tau``: its derivative
    ``b0 (nu_p + c nu_v) e^{c tau}`` keeps one sign) plus the modes, each
    bounded by its amplitude ``|a_i sin + b_i cos| e^{-sigma_i tau} <=
    amp_i e^{-sigma_i a}`` on ``[a, inf)``.  Where ``R`` keeps one sign and
    ``min(|R(a)|, |R(b)|)`` exceeds the modes' bound plus ``margin`` (the
    rounding noise of ``S``), ``S`` cannot vanish, however fast the modes
    oscillate.  On a long move this proves most of ``[0, T]`` zero-free
    without sampling the fastest mode there.
    """
    nu = np.asarray(nu, dtype=float)
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)

    def rigid(tau: np.ndarray) -> np.ndarray:
        ect = np.exp(resp.c * tau)
        if resp.include_position:
            return resp.b0 * (nu[0] * tau * phi1(resp.c * tau) + nu[1] * ect)
        return resp.b0 * nu[0] * ect

    Ra, Rb = rigid(a), rigid(b)
    low = np.minimum(np.abs(Ra), np.abs(Rb))
    if resp.w.size:
        am = nu[resp.r :: 2] * resp.bm / resp.wd - nu[resp.r + 1 :: 2] * resp.bm * resp.sig / resp.wd
        amp = np.hypot(am, nu[resp.r + 1 :: 2] * resp.bm)
        modal = np.exp(-np.outer(a, resp.sig)) @ amp
    else:
        modal = np.zeros(a.shape)
    return (np.sign(Ra) * np.sign(Rb) > 0) & (low > modal * (1.0 + 1e-12) + margin)


def switching_derivative_bounds(resp: SwitchingTerms, nu: np.ndarray, tau_max: float) -> tuple[float, float]:
    """Upper bounds on ``|S'|`` and ``|S''|`` over ``[0, tau_max]``.

    Used by the certificate to prove that the switching function has no
    zeros between sample points (a Lipschitz argument).
    """
    nu = np.asarray(nu, dtype=float)
    b0, c = abs(resp.b0), resp.c
    nv = abs(nu[resp.r - 1])
    if resp.include_position:
        npos = abs(nu[0])
        d1 = b0 * (npos + nv * abs(c))
        d2 = b0 * abs(c) * (npos + nv * abs(c))
    else:
        d1 = b0 * abs(c) * nv
        d2 = b0 * c * c * nv
    if resp.w.size:
        nq = nu[resp.r :: 2] * resp.bm
        nqd = nu[resp.r + 1 :: 2] * resp.bm
        a = nq / resp.wd - nqd * resp.sig / resp.wd
        amp = np.hypot(a, nqd)  # |a sin + b cos| <= amp; damping only shrinks it
        d1 += float(np.sum(amp * resp.w))  # |(sig + i wd)| = omega
        d2 += float(np.sum(amp * resp.w**2))
    return d1, d2
