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

import functools
import math
from dataclasses import dataclass

import numpy as np

from ..model.modal_model import ModalModel
from ..simulation.modal_response import ModalResponse


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
    T, switches, levels, nu = _rigid_solution(model, u_max, x0, include_position)
    return RigidProfile(T, switches, levels, nu if nu is not None else _rigid_nu(model, T, switches, levels))


def _rigid_solution(
    model: ModalModel, u_max: float, x0: np.ndarray, include_position: bool
) -> tuple[float, np.ndarray, np.ndarray, np.ndarray | None]:
    """``(T, switch_times, levels, nu)`` of :func:`rigid_profile`; ``nu`` None where it takes a response to find.

    Split from :func:`rigid_profile` so that :func:`rigid_time` (twice per plan: the move budget
    and the short-move test) does not build the dual direction it does not return.
    """
    a = abs(model.b0) * u_max
    c = model.c
    sb = 1.0 if model.b0 > 0.0 else -1.0
    if not include_position:
        v = float(x0[0])
        if v == 0.0:
            return 0.0, np.empty(0), np.empty(0), np.zeros(1)
        T = abs(v) / a if c == 0.0 else math.log1p(-c * abs(v) / a) / -c
        level = -u_max * sb * math.copysign(1.0, v)
        return T, np.empty(0), np.array([level]), np.array([math.copysign(1.0, level) * sb])
    # work in the frame where the input gain is positive: p'' = |b0| u
    p, v = float(x0[0]) * sb, float(x0[1]) * sb
    if p == 0.0 and v == 0.0:
        return 0.0, np.empty(0), np.empty(0), np.zeros(2)
    X, V = p / a, v / a
    first = -1.0 if X > -V * abs(V) / 2.0 else 1.0  # first level (normalised), c = 0
    T = first * -V + 2.0 * math.sqrt(max(-first * X + V * V / 2.0, 0.0))
    t1 = 0.5 * (T - first * V)
    if c != 0.0:
        T, t1, first = _viscous_solution(c, a, p, v, first, T, t1)
    if abs(t1) <= 1e-12 * T or abs(T - t1) <= 1e-12 * T:  # on the switching curve, to rounding
        t1 = 0.0 if abs(t1) <= abs(T - t1) else T
    if t1 <= 0.0 or t1 >= T:  # starts on the switching curve: one bang, the second (or the first)
        levels = np.array([(-first if t1 <= 0.0 else first) * u_max])
        switches = np.empty(0)
    else:
        levels = np.array([first, -first]) * u_max
        switches = np.array([t1])
    return T, switches, levels, None


#: A braking arc from the start that ends this close to the target (relative to the move's
#: position scale) starts on the switching curve (:func:`_viscous_solution`): the
#: replans along a plan's last arc start there to the simulation's rounding (a 3-mode
#: replan 4e-14 off it got a two-arc "rigid bound" of 0.574 s for a 0.304 s optimum).
ON_CURVE_RTOL = 1e-12


def _viscous_solution(
    c: float, a: float, p: float, v: float, first: float, T: float, t1: float
) -> tuple[float, float, float]:
    """Switch time and duration with viscous damping (``p'' = c p' + a u``, ``c < 0``).

    The last arc (level ``s a``) must end at rest at the origin: its velocity
    tends to the terminal velocity ``vs = -s a/c``, so it must start on the
    other side of zero (``v1/vs <= 0``: it brakes) and lasts
    ``h = -ln(1 - v1/vs)/c``, covering a known distance.
    So the first arc's duration ``t1`` solves one scalar equation (position at
    the switch equals the position the last arc needs), found by scanning and
    bracketing for both orders of levels; the shortest solution is optimal
    (the rigid body has one switch at most).  ``first``, ``T`` and ``t1`` (the
    frictionless answer) only set the scan range.  Returns ``(T, t1, first)``.
    """
    best: tuple[float, float, float] | None = None
    for s in (1.0, -1.0):  # level of the last arc
        vs = -s * a / c
        w = -vs  # velocity the first arc (level -s) tends to

        def gap(t):
            """Position at the switch minus what the last arc needs, and its length (arrays)."""
            t = np.asarray(t, dtype=float)
            x = w + (v - w) * np.exp(c * t)
            with np.errstate(invalid="ignore", divide="ignore"):
                h = -np.log1p(-x / vs) / c
                p1 = p + w * t + (v - w) * np.expm1(c * t) / c
                p_needed = -vs * h - (x - vs) * np.expm1(c * h) / c
            return p1 - p_needed, h, x / vs <= 0.0  # admissible: the last arc brakes

        # beyond settling (~1/|c|) p1 drifts at |w|: the switch is within reach of that
        horizon = max(T, t1, 1.0) + 50.0 / -c + 2.0 * (abs(p) + abs(v) / -c) / abs(w)
        # uniform and geometric points: short moves switch within a tiny window; the switch is admissible
        # only once the first arc's velocity has crossed zero (at ``t0``), and the root can lie a tiny time
        # after it (a target just short of where full braking stops: 0.017 m of a 6380 m stop from 812 m/s,
        # 0.05 s past t0 = 25.6 s; the grid's 0.47 s steps straddled t0 and the root, and the scan took a
        # 276 s root of the other order, which missed the target): geometric points after t0 too
        after = np.empty(0)
        if v != w and 0.0 < w / (w - v) < 1.0:
            after = math.log(w / (w - v)) / c + np.geomspace(horizon * 1e-15, horizon, 201)
        ts = np.unique(
            np.concatenate([np.linspace(0.0, horizon, 2001), np.geomspace(horizon * 1e-12, horizon, 2001), after])
        )
        g, _, adm = gap(ts)
        ok = adm[:-1] & adm[1:] & ((g[:-1] == 0.0) | (g[:-1] * g[1:] < 0.0))
        for i in np.flatnonzero(ok):
            lo, hi, glo = ts[i], ts[i + 1], g[i]
            for _ in range(200):  # bisection to rounding
                mid = 0.5 * (lo + hi)
                gm = float(gap(mid)[0])
                if gm == 0.0 or mid in (lo, hi):
                    break
                if (gm < 0.0) == (glo < 0.0):
                    lo, glo = mid, gm
                else:
                    hi = mid
            t_sw = 0.5 * (lo + hi)
            total = t_sw + float(gap(t_sw)[1])
            if best is None or total < best[0]:
                best = (float(total), float(t_sw), -s)
        # a start on the switching curve (one braking arc lands on the target): its root is at t = 0,
        # within rounding, and the scan brackets none when rounding puts it at t < 0; the stop time is
        # then the optimum (no move to rest is shorter than braking at full force)
        g0, h0, braking = (float(z) for z in gap(0.0))
        if braking and abs(g0) <= ON_CURVE_RTOL * max(abs(p), abs(v) * h0, a * h0 * h0):
            if best is None or h0 < best[0]:
                best = (h0, 0.0, -s)
    if best is None:
        return T, t1, first
    return best


@functools.lru_cache(maxsize=32)
def _rigid_response(b0: float, c: float) -> ModalResponse:
    """The closed-form responses of the rigid body ``p'' = c p' + b0 u`` (position kept), built once per ``(b0, c)``.

    Why cached: building the rigid model (validation) and its responses cost
    more than the rest of :func:`rigid_profile` (80 us of a 3-mode replan's
    95 us, three times per plan), and they depend on ``b0`` and ``c`` alone.
    A rigid response holds no per-grid caches (those are the modes').
    """
    return ModalResponse(ModalModel(b0=b0, c=c), True)


def _rigid_nu(model: ModalModel, T: float, switches: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """A dual direction whose switching function vanishes at the switch (rigid states only)."""
    rigid = _rigid_response(float(model.b0), float(model.c))
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
    return _rigid_solution(model, u_max, x0, include_position)[0]
