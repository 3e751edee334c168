"""A proved lower bound on the time of any move under rigid-body Coulomb friction (the rigid body alone)."""

from __future__ import annotations

import math

import numpy as np

from ..model.modal_model import ModalModel


def rigid_friction_time(
    model: ModalModel, u_max: float, coulomb_force: float, x0, target: float | None
) -> float | None:
    """Proved lower bound (s) on any rest-to-rest move under rigid-body friction, or None.

    From rest, while ``v > 0``: ``v' <= c v + a1`` and ``v' >= c v - a2``
    (``a1 = |b0| (u_max - F)``, ``a2 = |b0| (u_max + F)``), so by comparison
    ``v(t) <= min(w(t), z(t))`` with ``w`` the full-force rise from rest and
    ``z`` the full-brake fall to rest at ``T`` (``c = 0``: ``min(a1 t, a2 (T - t))``;
    ``c = -k < 0``: ``a1 (1 - e^{-k t}) / k`` and ``a2 (e^{k (T - t)} - 1) / k``).
    The distance ``|gamma|`` is at most the integral of that envelope, which
    increases with ``T``; the bound is the ``T`` where it equals ``|gamma|``.
    Intervals with ``v <= 0`` only lose distance, and the modes add
    constraints only, so the full model is never faster.
    """
    x0 = np.asarray(x0, float)
    if target is None or np.any(x0[1:]):
        return None
    gamma = abs(target - x0[0])
    a1 = abs(model.b0) * (u_max - coulomb_force)
    a2 = abs(model.b0) * (u_max + coulomb_force)
    if model.c == 0.0:
        return math.sqrt(2.0 * gamma * (a1 + a2) / (a1 * a2))
    if gamma == 0.0:
        return 0.0
    k = -float(model.c)

    def reach(T: float) -> float:
        # the envelope's crossing t*: a1 (1 - e^{-k t*}) = a2 (e^{k (T - t*)} - 1); r = T - t* (no overflow)
        e = math.exp(-k * T)
        r = math.log1p(-a1 * math.expm1(-k * T) / (a2 + a1 * e)) / k
        return (a1 * _expm1_minus_x(-k * (T - r)) + a2 * _expm1_minus_x(k * r)) / (k * k)

    hi = math.sqrt(2.0 * gamma * (a1 + a2) / (a1 * a2))  # the undamped bound: the damped one is longer
    while reach(hi) < gamma:
        hi *= 2.0
    lo = 0.5 * hi if reach(0.5 * hi) < gamma else 0.0
    for _ in range(200):  # bisection to rounding; the bound returned is the lower end (never too long)
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            break
        if reach(mid) < gamma:
            lo = mid
        else:
            hi = mid
    return lo


def _expm1_minus_x(x: float) -> float:
    """``e^x - 1 - x`` without cancellation for small ``|x|``."""
    if abs(x) < 1e-3:
        return x * x * (0.5 + x * (1.0 / 6.0 + x / 24.0))
    return math.expm1(x) - x
