"""Time-optimal moves of the rigid body alone.

The rigid block of the modal model (eq. 2.2) is decoupled from the modes, so
its time-optimal move is a lower bound for the whole machine: the modes add
constraints but no freedom.  It has real eigenvalues (``0`` and ``c``), hence
at most one switch (two states), and closed forms for ``c = 0``.

When the rigid optimum happens to leave every mode at rest (a structure tuned
so that the move time is a multiple of each period), it is the optimum of the
whole machine; :func:`rigid_profile` gives what is needed to check that.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .modal_response import ModalResponse
from .model import ModalModel


@dataclass(frozen=True)
class RigidProfile:
    """The rigid body's time-optimal bang-bang move.

    Attributes
    ----------
    duration : float
        Move time (s).
    switch_times : ndarray
        Forward switching times (s): none or one.
    levels : ndarray
        Input on each interval (``+-u_max``).
    nu : ndarray
        Dual direction of the rigid states (``-lambda(T)`` up to a positive
        factor): ``u(tau) = u_max sgn(nu^T e^{A tau} B)``.
    """

    duration: float
    switch_times: np.ndarray
    levels: np.ndarray
    nu: np.ndarray


def rigid_profile(model: ModalModel, u_max: float, x0: np.ndarray, include_position: bool) -> RigidProfile:
    """Time-optimal move of the rigid body from (shifted) ``x0`` to the origin.

    Parameters
    ----------
    model : ModalModel
        Only ``b0`` and ``c`` are used.
    u_max : float
        Input bound.
    x0 : ndarray
        Shifted initial state (``[p, v, ...]`` or ``[v, ...]``); only the rigid
        entries are used.
    include_position : bool
        Whether the position is constrained.
    """
    a = abs(model.b0) * u_max
    c = model.c
    sb = 1.0 if model.b0 > 0.0 else -1.0
    if not include_position:
        v = float(x0[0])
        if v == 0.0:
            return RigidProfile(0.0, np.empty(0), np.empty(0), np.zeros(1))
        T = abs(v) / a if c == 0.0 else math.log1p(-c * abs(v) / a) / -c
        level = -u_max * sb * math.copysign(1.0, v)
        return RigidProfile(T, np.empty(0), np.array([level]), np.array([math.copysign(1.0, level) * sb]))
    # work in the frame where the input gain is positive: p'' = |b0| u
    p, v = float(x0[0]) * sb, float(x0[1]) * sb
    if p == 0.0 and v == 0.0:
        return RigidProfile(0.0, np.empty(0), np.empty(0), np.zeros(2))
    X, V = p / a, v / a
    first = -1.0 if X > -V * abs(V) / 2.0 else 1.0  # first level (normalised), c = 0
    T = first * -V + 2.0 * math.sqrt(max(-first * X + V * V / 2.0, 0.0))
    t1 = 0.5 * (T - first * V)
    if c != 0.0:
        T, t1 = _viscous_switch(c, a, p, v, first, T, t1)
    if t1 <= 0.0 or t1 >= T:  # starts on the switching curve: one bang
        levels = np.array([first * u_max])
        switches = np.empty(0)
    else:
        levels = np.array([first, -first]) * u_max
        switches = np.array([t1])
    return RigidProfile(T, switches, levels, _rigid_nu(model, T, switches, levels))


def _viscous_switch(c: float, a: float, p: float, v: float, first: float, T: float, t1: float) -> tuple[float, float]:
    """Switch time and duration with viscous damping (``p'' = c p' + a u``), by Newton.

    Starts from the frictionless solution; the structure (one switch,
    ``first`` then ``-first``) is the same.
    """
    def final(t1: float, T: float) -> tuple[np.ndarray, np.ndarray]:
        # exact solution of v' = c v + a s on each interval
        def step(p0, v0, s, h):
            e = math.exp(c * h)
            vs = -a * s / c  # equilibrium velocity
            v1 = vs + (v0 - vs) * e
            p1 = p0 + vs * h + (v0 - vs) * math.expm1(c * h) / c
            return p1, v1

        p1, v1 = step(p, v, first, t1)
        p2, v2 = step(p1, v1, -first, T - t1)
        # derivatives: d/dt1 and d/dT of (p2, v2)
        e2 = math.exp(c * (T - t1))
        dv1_dt1 = c * v1 + a * first
        dp1_dt1 = v1
        # d(p2, v2)/dt1 through (p1, v1) and through the second interval length
        dv2 = dv1_dt1 * e2 - (c * v2 - a * first)
        dp2 = dp1_dt1 + dv1_dt1 * math.expm1(c * (T - t1)) / c - v2
        J = np.array([[dp2, v2], [dv2, c * v2 - a * first]])
        return np.array([p2, v2]), J

    for _ in range(60):
        F, J = final(t1, T)
        if np.max(np.abs(F)) <= 1e-15 * (abs(p) + abs(v) * T + a * T * T):
            break
        try:
            d = np.linalg.solve(J, -F)
        except np.linalg.LinAlgError:
            break
        step = 1.0
        while step > 1e-6:
            t1n, Tn = t1 + step * d[0], T + step * d[1]
            if 0.0 <= t1n <= Tn and np.max(np.abs(final(t1n, Tn)[0])) < np.max(np.abs(F)):
                break
            step *= 0.5
        else:
            break  # no progress: converged to rounding
        t1, T = t1n, Tn
    return T, t1


def _rigid_nu(model: ModalModel, T: float, switches: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """A dual direction whose switching function vanishes at the switch (rigid states only)."""
    rigid = ModalResponse(model.with_changes(omega=(), zeta=(), b=()), True)
    if switches.size == 0:
        nu = np.array([0.0, 1.0])
    else:
        tau1 = T - switches[0]
        # S(tau) = nu_p g_p(tau) + nu_v g_v(tau) with S(tau1) = 0
        g = rigid.expm_B(np.array([tau1]))[0]
        nu = np.array([g[1], -g[0]])
    S0 = float(rigid.switching(nu, np.array([0.0]))[0]) if T > 0.0 else 1.0
    if np.sign(S0) != np.sign(levels[-1]):
        nu = -nu
    return nu


def rigid_time(model: ModalModel, u_max: float, x0: np.ndarray, include_position: bool) -> float:
    """Time-optimal move time of the rigid body alone (s): a lower bound for the full model."""
    return rigid_profile(model, u_max, x0, include_position).duration
