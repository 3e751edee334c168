"""The exact inner problem of the reachable-set dual at a fixed ``T``, by a trust-region Newton method.

Minimise ``h_T(nu)`` on ``{nu : nu^T w = 1}`` (see :mod:`.reachable_set`)
with exact switching times; the trust region is measured by how much a step
changes the switching function (:func:`gram_metric`).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .reachable_set import Evaluation, Shooting, null_basis
from .switching import root_grid, sample_grid


def trust_step(g: np.ndarray, H: np.ndarray, radius: float) -> tuple[np.ndarray, bool]:
    """Minimise ``g.d + d.H.d/2`` over ``|d| <= radius`` (``H`` PSD, exact, by eigenvalues).

    Returns the step and whether it is the unconstrained Newton step.
    """
    if g.size == 0:  # nothing to optimise (a one-state system)
        return np.zeros(0), True
    lam, V = np.linalg.eigh(H)
    lam = np.maximum(lam, 0.0)
    gh = V.T @ g
    tiny = 1e-14 * max(float(lam[-1]), 1e-300)
    if lam[0] > tiny:
        d = -(gh / lam)
        if np.linalg.norm(d) <= radius:
            return V @ d, True
    # find mu > 0 with |d(mu)| = radius (More-Sorensen Newton on 1/|d|)
    mu = max(float(np.linalg.norm(g)) / radius - float(lam[0]), 1e-300)
    for _ in range(50):
        d = -(gh / (lam + mu))
        nd = float(np.linalg.norm(d))
        if abs(nd - radius) <= 1e-3 * radius:
            break
        dnd = -float(np.sum(gh**2 / (lam + mu) ** 3)) / nd  # d|d|/dmu
        mu_new = mu - (nd - radius) / dnd * (nd / radius)
        mu = mu_new if mu_new > 0.0 else 0.1 * mu
    return V @ d, False


def gram_metric(sh: Shooting, T: float, Z: np.ndarray) -> np.ndarray:
    """``P`` with ``|P^T d|`` = the L2 norm on ``[0, T]`` of the change ``Z d`` makes in ``S``.

    The trust region of :func:`inner_exact` is measured in this norm, i.e. by
    how much a step changes the switching function, not by the size of the
    co-state step.  For short moves (``omega T << 1``) the map from ``nu`` to
    ``S`` is as ill-conditioned as a Vandermonde matrix, and a Euclidean trust
    region would crawl along the weak directions.
    """
    grid, wq = _quadrature(sh.sys, T)
    GZ = (sh.sys.expm_B(grid) / sh.s) @ Z
    W = (GZ.T * wq) @ GZ
    lam, V = np.linalg.eigh(W)
    lam = np.maximum(lam, 1e-30 * max(float(lam[-1]), 1e-300))
    return V * np.sqrt(lam)  # W = P P^T


def inner_exact(
    sh: Shooting,
    T: float,
    nuh: np.ndarray | None,
    max_iter: int = 100,
    rtol: float = 1e-14,
    probe: Callable[[np.ndarray, Evaluation, float], bool] | None = None,
):
    """Minimise ``h_T`` on ``{nu : nu^T w = 1}`` (convex), by a trust-region Newton method.

    The trust region bounds the change in the switching function
    (:func:`gram_metric`).  Returns ``(nuh, m, dm/dT, eval)``.

    ``probe(nuh, e, pred)``: called at each iterate (scaled co-state ``nuh``,
    its evaluation ``e``, the step's predicted decrease of ``h`` relative to
    ``h``) before its step; the solve stops there if it returns True (the
    caller found what it wanted from the iterate: :func:`~.costate_solver.solve_costate`
    tries the switch-time Newton from each new switch structure).
    """
    w = -sh.sys.expm_x(T, sh.x0) / sh.s
    if nuh is None or float(nuh @ w) <= 0.0:
        nuh = w / float(w @ w)
    else:
        nuh = nuh / float(nuh @ w)
    Z = null_basis(w)
    P = gram_metric(sh, T, Z)
    Pinv = np.linalg.inv(P)  # coordinates y = P^T d: |y| = |change in S|
    e = sh.evaluate(nuh, T)
    radius = 0.5 * _s_norm(sh, nuh, T)
    for _ in range(max_iter):
        g = Pinv @ (Z.T @ e.grad)  # gradient and Hessian in y
        Hr = Pinv @ (Z.T @ e.H @ Z) @ Pinv.T
        y, newton = trust_step(g, Hr, radius)
        pred = -float(g @ y + 0.5 * y @ Hr @ y)
        if probe is not None and probe(nuh, e, pred / max(e.h, 1e-300)):
            break
        if pred <= rtol * max(e.h, 1e-300) or (
            radius <= _S_NORM_CAP * _s_bound(sh, nuh, T) and radius <= 1e-15 * _s_norm(sh, nuh, T)
        ):
            break
        cand = nuh + Z @ (Pinv.T @ y)
        ec = sh.evaluate(cand, T)
        rho = (e.h - ec.h) / pred
        if rho < 0.25:
            radius = 0.25 * float(np.linalg.norm(y))
        elif rho > 0.75 and not newton:
            radius *= 2.0
        if ec.h < e.h:
            nuh, e = cand, ec
    nu = nuh / sh.s
    S_T = float(sh.sys.switching(nu, np.array([T]))[0])
    dm = sh.u_max * abs(S_T) + e.h * float(nu @ sh.sys.A_x(e.eAx))
    return nuh, e.h, dm, e


#: 1e-15 with a margin for rounding: ``radius`` above this times :func:`_s_bound` is
#: above 1e-15 times :func:`_s_norm` (the stopping test then skips sampling ``S``).
_S_NORM_CAP = 1.0001e-15


def _s_bound(sh: Shooting, nuh: np.ndarray, T: float) -> float:
    """An upper bound on :func:`_s_norm`: ``sqrt(T)`` times the sum of the magnitudes of the terms of ``S``."""
    return math.sqrt(T) * float(sh.sys.switching_magnitude(nuh / sh.s, T)[0])


def _s_norm(sh: Shooting, nuh: np.ndarray, T: float) -> float:
    """L2 norm of the switching function of ``nuh`` on ``[0, T]`` (trapezoidal rule)."""
    grid, wq = _quadrature(sh.sys, T)
    S = sh.sys.switching(nuh / sh.s, grid)
    return math.sqrt(float(wq @ (S * S)))


def _quadrature(system, T: float) -> tuple[np.ndarray, np.ndarray]:
    """Points (s) and trapezoidal weights for the L2 norms of ``S`` on ``[0, T]`` (:func:`gram_metric`, :func:`_s_norm`).

    On :func:`~.switching.root_grid` (graded by the modes still ringing): a
    norm for the trust region's shape and its stopping test, not a proof,
    and on a long move of a fast, damped mode the uniform grid made the
    metric most of the solve (an 8-mode 2198 s stop: 290,000 responses per
    duration, over half of its 11 s).
    """
    grid = root_grid(system, T) if GRADED_NORMS else sample_grid(system, T)
    h = np.diff(grid)
    wq = np.empty(grid.size)
    wq[:-1] = 0.5 * h
    wq[-1] = 0.0
    wq[1:] += 0.5 * h
    return grid, wq


#: The trust region's norms of ``S`` on the graded grid (:func:`_quadrature`; False: the uniform one, as before).
GRADED_NORMS = True
