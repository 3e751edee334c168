"""The convex dual of time-optimal reachability, and Newton methods on it.

In time-to-go ``tau = T - t``, a co-state direction ``nu`` (``nu = -lambda(T)``
up to a positive factor) gives the Pontryagin input
``u(tau) = u_max sgn(nu^T e^{A tau} B)`` and the final state::

    F(nu, T) = e^{A T} x0 + grad h_T(nu),   h_T(nu) = u_max int_0^T |nu^T e^{A tau} B| dtau

``h_T`` is the support function of the set reachable in time ``T``: convex in
``nu``.  ``x0`` can be brought to rest in time ``T`` iff
``m(T) = min {h_T(nu) : nu^T w = 1} >= 1`` with ``w = -e^{A T} x0``, and ``m``
is non-decreasing in ``T``: the optimal time is the root of ``m(T) = 1``.

This module holds the pieces: the shooting map and its derivatives
(:class:`Shooting`), the exact inner problem by a trust-region Newton method
(:func:`inner_exact`), a smoothed discretised version for cold starts
(:func:`inner_smooth`), the outer iteration on ``T`` (:func:`outer_newton`)
and a joint Newton polish on ``(nu, T)`` (:func:`polish`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..simulation.error_scale import state_scale  # re-exported: the error scale lives with the simulation
from .switching import MIN_GRID_POINTS, POINTS_PER_HALF_PERIOD, find_roots, root_grid, sample_grid


@dataclass
class Evaluation:
    roots: np.ndarray  # switching times-to-go
    signs: np.ndarray  # sign of S on each tau-interval (len(roots) + 1)
    F: np.ndarray  # scaled final state
    grad: np.ndarray  # scaled grad h
    h: float
    eAx: np.ndarray  # e^{A T} x0 (unscaled)
    H: np.ndarray | None = None  # scaled Hessian of h
    FT: np.ndarray | None = None  # scaled dF/dT


class Shooting:
    """The final-state map and its derivatives for one problem."""

    def __init__(self, system, x0: np.ndarray, u_max: float, T_scale: float) -> None:
        self.sys = system
        self.x0 = x0
        self.u_max = u_max
        self.set_scale(T_scale)
        self.evaluations = 0

    def set_scale(self, T: float) -> None:
        """Per-state scale: how large each state gets during a move of length ``T``."""
        self.s = state_scale(self.sys, self.x0, self.u_max, T)

    def evaluate(self, nuh: np.ndarray, T: float, jac: bool = True) -> Evaluation:
        self.evaluations += 1
        sys, s, um = self.sys, self.s, self.u_max
        nu = nuh / s
        roots, sign0 = find_roots(sys, nu, T, root_grid(sys, T))
        L = roots.size
        signs = sign0 * (1.0 - 2.0 * (np.arange(L + 1) % 2))
        G = sys.input_integral(np.append(roots, T))
        grad = um * (signs[-1] * G[-1] + 2.0 * (signs[:-1, None] * G[:-1]).sum(axis=0))
        eAx = sys.expm_x(T, self.x0)
        e = Evaluation(roots, signs, (eAx + grad) / s, grad / s, float(nu @ grad), eAx)
        if jac:
            g = sys.expm_B(roots) / s if L else np.zeros((0, s.size))
            if L:
                _, dS = sys.switching(nu, roots, derivative=True)
                wts = 2.0 * um / np.maximum(np.abs(dS), 1e-300)
                e.H = (g.T * wts) @ g
            else:
                e.H = np.zeros((s.size, s.size))
            e.FT = (sys.A_x(eAx) + um * signs[-1] * sys.expm_B(np.array([T]))[0]) / s
        return e


def null_basis(v: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the complement of ``v`` (columns)."""
    Q, _ = np.linalg.qr(v.reshape(-1, 1), mode="complete")
    return Q[:, 1:]


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


def inner_exact(sh: Shooting, T: float, nuh: np.ndarray | None, max_iter: int = 100, rtol: float = 1e-14):
    """Minimise ``h_T`` on ``{nu : nu^T w = 1}`` (convex), by a trust-region Newton method.

    The trust region bounds the change in the switching function
    (:func:`gram_metric`).  Returns ``(nuh, m, dm/dT, eval)``.
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


def polish(sh: Shooting, nuh: np.ndarray, T: float, max_iter: int = 40):
    """Newton on ``F(nu, T) = 0`` jointly; ``nu`` kept on the unit sphere."""
    nuh = nuh / np.linalg.norm(nuh)
    e = sh.evaluate(nuh, T)
    r = float(np.max(np.abs(e.F)))
    for _ in range(max_iter):
        if r <= 4.0 * np.finfo(float).eps:
            break
        Z = null_basis(nuh)
        J = np.column_stack([e.H @ Z, e.FT])
        step, *_ = np.linalg.lstsq(J, -e.F, rcond=1e-14)
        t = 1.0
        improved = False
        for _ in range(12):
            cand = nuh + t * (Z @ step[:-1])
            cand /= np.linalg.norm(cand)
            Tc = T + t * step[-1]
            if Tc > 0.0:
                ec = sh.evaluate(cand, Tc)
                rc = float(np.max(np.abs(ec.F)))
                if rc < r:
                    improved = True
                    break
            t *= 0.5
        if not improved:
            break
        nuh, T, e, r = cand, Tc, ec, rc
    return nuh, T, e, r


#: The trust region's norms of ``S`` on the graded grid (:func:`_quadrature`; False: the uniform one, as before).
GRADED_NORMS = True
#: Up to this many grid points the smoothed problem uses the planners' grid
#: (8 points per half period of the fastest mode) ...
SMOOTH_FULL_GRID = 4096
#: ... beyond, this fraction of it (2 points per half period): the smoothed
#: problem only gives a warm start, and on a move of thousands of periods it
#: was most of the planning time (measured: 2.3 of 4.0 s on a 1641 s move).
SMOOTH_LONG_DENSITY = 0.25
#: ... and on a long move, a mode whose response has decayed by ``e^-SMOOTH_DECAY``
#: (about 2e-16) no longer sets the rule's spacing: the grid is graded
#: (:func:`graded_grid`), so a damped long move's warm start samples the fast
#: modes only while they ring, not over the whole move.  Inf: never (the uniform rule).
SMOOTH_DECAY = 36.0
#: Newton on the smoothed problem stops when the predicted decrease is below
#: this (relative): a warm start whose duration is wanted to 1e-3 needs no
#: more (1e-14 took twice the iterations for the same guesses).
SMOOTH_RTOL = 1e-9


def inner_smooth(
    sh: Shooting, T: float, nuh: np.ndarray | None, eps_rel: float, max_iter: int = 50, smoothing: float | None = None
):
    """Smoothed, discretised inner problem: a warm start for the exact one.

    ``|S|`` is replaced by ``sqrt(S^2 + eps^2) - eps`` and the integral by the
    trapezoidal rule on the bracketing grid: a smooth, strictly convex
    function of ``nu``, so Newton's method with a line search converges fast
    from any start, whatever the number of switches.  ``eps``: ``eps_rel``
    times the mean ``|S|`` at the start, or ``smoothing`` (scaled) if given.
    """
    sys, s, um = sh.sys, sh.s, sh.u_max
    grid = sample_grid(sys, T)
    graded = None
    if grid.size > SMOOTH_FULL_GRID:  # a long move: a warm start needs no proof, a coarser rule will do
        grid = sample_grid(sys, T, density=SMOOTH_LONG_DENSITY)
        graded = graded_grid(sys, T, SMOOTH_LONG_DENSITY * POINTS_PER_HALF_PERIOD)
    if graded is not None and graded.size < 0.5 * grid.size:
        grid = graded
        h = np.diff(grid)
        wq = 0.5 * (np.concatenate([h, [0.0]]) + np.concatenate([[0.0], h]))  # the trapezoidal rule's weights
    else:
        wq = np.full(grid.size, grid[1] - grid[0])
        wq[[0, -1]] *= 0.5
    Gm = sys.expm_B(grid) / s
    eAx = sys.expm_x(T, sh.x0)
    w = -eAx / s
    if nuh is None or float(nuh @ w) <= 0.0:
        nuh = w / float(w @ w)
    else:
        nuh = nuh / float(nuh @ w)
    Z = null_basis(w)
    S = Gm @ nuh
    GZ = Gm @ Z  # the search space's columns on the grid: one product per solve, not per step
    # smoothing scale: a fraction of the mean |S| at the start (fixed during this solve), or the caller's
    eps = smoothing if smoothing is not None else eps_rel * max(float(wq @ np.abs(S)) / T, 1e-300)

    def value(S):
        return um * float(wq @ (np.sqrt(S * S + eps * eps) - eps))

    f = value(S)
    for _ in range(max_iter):
        sq = np.sqrt(S * S + eps * eps)
        g = um * (GZ.T @ (wq * S / sq))
        Hr = um * ((GZ.T * (wq * eps * eps / sq**3)) @ GZ)
        try:
            dy = -np.linalg.solve(Hr, g)
        except np.linalg.LinAlgError:
            dy = -g
        dec = -float(g @ dy)
        if dec <= SMOOTH_RTOL * f:
            break
        t = 1.0
        step = Z @ dy
        dS = GZ @ dy
        for _ in range(40):
            fc = value(S + t * dS)
            if fc <= f - 0.25 * t * dec:
                break
            t *= 0.5
        else:
            break
        nuh = nuh + t * step
        S = S + t * dS
        f = fc
    nu = nuh / s
    mu = um * float(wq @ (S * S / np.sqrt(S * S + eps * eps)))  # Lagrange multiplier nu.grad h
    dm = um * (math.sqrt(S[-1] ** 2 + eps * eps) - eps) + mu * float(nu @ sys.A_x(eAx))
    return nuh, f, dm


def graded_grid(system, T: float, per_half_period: float) -> np.ndarray | None:
    """Points on ``[0, T]`` (s) spaced by the fastest mode still ringing, for the smoothed problem.

    Mode ``i``'s response decays like ``e^{-zeta_i omega_i tau}``; past
    ``tau = SMOOTH_DECAY / (zeta_i omega_i)`` it is below rounding of its
    start and the rule's spacing follows the next slower mode (a rigid tail:
    the rigid body's own time scale).  ``per_half_period`` points per half
    period of the fastest mode alive in each stretch.  None for a system
    without ``sig`` (decay rates) or if no mode decays within ``T``.
    """
    sig, wd = getattr(system, "sig", None), getattr(system, "wd", None)
    if sig is None or wd is None or not np.size(wd) or not math.isfinite(SMOOTH_DECAY):
        return None
    with np.errstate(divide="ignore"):
        life = np.where(sig > 0.0, SMOOTH_DECAY / np.maximum(sig, 1e-300), math.inf)
    ends = np.unique(np.concatenate([life[life < T], [T]]))
    if ends.size == 1:
        return None
    c = abs(float(getattr(system, "c", 0.0)))
    pieces, a = [], 0.0
    for b in ends:
        alive = wd[life > a]
        w = float(np.max(alive)) if alive.size else 0.0
        n = max(MIN_GRID_POINTS // 2, math.ceil((b - a) * w / math.pi * per_half_period), math.ceil(8.0 * c * (b - a)))
        pieces.append(np.linspace(a, b, n + 1)[:-1])
        a = b
    pieces.append(np.array([T]))
    return np.concatenate(pieces)


def bracketed_step(T: float, m: float, dm: float, lo: float, hi: float) -> tuple[float, float, float]:
    """Narrow the bracket ``[lo, hi]`` of the optimal time with ``m(T)``, then take :func:`next_time`.

    ``m`` is non-decreasing in ``T``: ``m(T) < 1`` puts the root above ``T``,
    otherwise at or below it.  Returns ``(T_next, lo, hi)`` (s).
    """
    if m < 1.0:
        lo = max(lo, T)
    else:
        hi = min(hi, T)
    return next_time(T, m, dm, lo, hi), lo, hi


def next_time(T: float, m: float, dm: float, lo: float, hi: float) -> float:
    """One safeguarded Newton step on ``log m(T) = 0`` in ``log T``.

    ``m`` behaves like a power of ``T`` (for short moves a high one: the
    reachable set of an integrator chain grows like ``T^k``), so Newton in
    logarithms converges where Newton on ``m - 1`` would jump far; steps are
    capped at a factor 4 and kept inside the bracket ``(lo, hi)``.
    """
    if m > 0.0 and dm > 0.0:
        elasticity = T * dm / m  # d log m / d log T
        Tn = T * math.exp(max(-math.log(4.0), min(math.log(4.0), -math.log(m) / elasticity)))
    else:
        Tn = math.nan
    if not (lo < Tn < hi):
        Tn = 2.0 * T if math.isinf(hi) else (0.5 * (lo + hi) if lo > 0.0 else 0.5 * hi)
    return Tn


def outer_newton(inner, T_low: float, T: float, nuh, tol: float, max_outer: int = 100):
    """Solve ``m(T) = 1`` (``m`` non-decreasing) by :func:`next_time` steps.

    ``inner(T, nuh) -> (nuh, m, dm/dT)``.  Returns ``(nuh, T)``.
    """
    lo, hi = T_low, math.inf
    for _ in range(max_outer):
        nuh, m, dm = inner(T, nuh)
        if abs(m - 1.0) <= tol:
            break
        Tn, lo, hi = bracketed_step(T, m, dm, lo, hi)
        if abs(Tn - T) <= 1e-15 * T:
            break
        T = Tn
    return nuh, T


def rescale(sh: Shooting, nuh: np.ndarray, T: float) -> np.ndarray:
    nu = nuh / sh.s
    sh.set_scale(T)
    return nu * sh.s
