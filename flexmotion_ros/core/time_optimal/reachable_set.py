"""The convex dual of time-optimal reachability: the shooting map, the iteration on ``T``.

In time-to-go ``tau = T - t``, a co-state direction ``nu`` (``nu = -lambda(T)``
up to a positive factor) gives the Pontryagin input
``u(tau) = u_max sgn(nu^T e^{A tau} B)`` and the final state::

    F(nu, T) = e^{A T} x0 + grad h_T(nu),   h_T(nu) = u_max int_0^T |nu^T e^{A tau} B| dtau

``h_T`` is the support function of the set reachable in time ``T``: convex in
``nu``.  ``x0`` can be brought to rest in time ``T`` iff
``m(T) = min {h_T(nu) : nu^T w = 1} >= 1`` with ``w = -e^{A T} x0``, and ``m``
is non-decreasing in ``T``: the optimal time is the root of ``m(T) = 1``.

This module holds the shooting map and its derivatives (:class:`Shooting`),
the outer iteration on ``T`` (:func:`outer_newton`, :func:`bracketed_step`)
and a joint Newton polish on ``(nu, T)`` (:func:`polish`).  The inner
problem at a fixed ``T``: exactly, by a trust-region Newton method
(:func:`~.trust_region.inner_exact`), or smoothed and discretised for cold
starts (:func:`~.smoothed_dual.inner_smooth`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..simulation.error_scale import state_scale  # re-exported: the error scale lives with the simulation
from .switching import find_roots, root_grid

__all__ = [
    "Evaluation",
    "Shooting",
    "bracketed_step",
    "next_time",
    "null_basis",
    "outer_newton",
    "polish",
    "rescale",
    "state_scale",
]


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
        #: Newton steps of undamped smoothed solves that their line search cut short (or rejected):
        #: where a damped solve would differ (:func:`~.smoothed_dual.inner_smooth`).
        self.short_steps = 0

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
