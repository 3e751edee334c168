"""The switch structure of a friction extremal, found without continuing the frictionless one.

A sampled move under friction (the fewest-sample LP of :mod:`.sampled_lp` at a
coarse rate) shows the structure of the continuous optimum: samples at
``+-u_max`` are bang arcs, a sample in between holds a switch (or a short
pulse), and its value says where (:func:`bang_bang_guess`: the same mean
force on every sample).  With the levels and switch times guessed, the
final costate ``lambda(T)`` is linear in the conditions ``B^T lambda(t_j) = 0``
and ``H = 0`` (:func:`costate_guess`, least squares along the exact friction
trajectory, costate jumps at the reversals included).  Newton's method on the
extremal conditions (:class:`~.extremal.Extremal`) then polishes the guess,
and :func:`consistent_switches` makes the switches the sign changes of
``B^T lambda`` (a structure the guess got wrong is corrected, up to a few
times).  The result is checked and certified by the caller.
"""

from __future__ import annotations

import numpy as np

from ..model.boundary import MoveProblem
from ..simulation.exact import PiecewiseConstant
from .certificate import consistent_switches
from .extremal import Extremal, newton_solve


def bang_bang_guess(u: np.ndarray, dt: float, u_max: float) -> tuple[np.ndarray, np.ndarray, float]:
    """``(levels, switch_times, T)``: a bang-bang input (levels ``+-u_max``, the sequence's own peak)
    with the mean force of ``u`` on every sample.

    A sample between two arcs of opposite sign holds one switch; a sample
    inside an arc that is not at the bound holds a short pulse of the other
    sign, centred.  Arcs shorter than rounding are merged away.
    """
    x = np.clip(np.asarray(u, float) / u_max, -1.0, 1.0)
    K = x.size
    sat = np.abs(x) >= 1.0 - 1e-9
    sgn = np.where(x >= 0.0, 1.0, -1.0)
    pieces: list[tuple[float, float]] = []  # (end time, sign)
    for k in range(K):
        a, b = k * dt, (k + 1) * dt
        if sat[k]:
            pieces.append((b, sgn[k]))
            continue
        prev = pieces[-1][1] if pieces else None
        nxt = next((sgn[j] for j in range(k + 1, K) if sat[j]), None)
        prev = prev if prev is not None else (-nxt if nxt is not None else sgn[k])
        nxt = nxt if nxt is not None else -prev
        if prev == nxt:  # a pulse of the other sign, centred, of the width that gives the mean
            q = 0.5 * (1.0 - prev * x[k]) * dt
            c = 0.5 * (a + b)
            pieces += [(c - 0.5 * q, prev), (c + 0.5 * q, -prev), (b, prev)]
        else:  # one switch from prev to nxt
            pieces += [(a + 0.5 * (1.0 + prev * x[k]) * dt, prev), (b, nxt)]
    T = K * dt
    ends, signs = [], []
    start = 0.0
    for end, s in pieces:
        if end - start <= 1e-9 * T:
            continue  # a zero-length arc
        if signs and signs[-1] == s:
            ends[-1] = end
        else:
            ends.append(end)
            signs.append(s)
        start = end
    ends[-1] = T
    return u_max * np.array(signs), np.array(ends[:-1]), T


def costate_guess(ext: Extremal, t_sw: np.ndarray, T: float) -> np.ndarray | None:
    """``lambda(T)`` (its free components) by least squares on ``B^T lambda(t_j) = 0`` and ``H(T) = 0``."""
    u = PiecewiseConstant.from_switches(t_sw, ext.levels, T)
    run = ext.sys.run(ext.x0, u, [T], lock_after=float(t_sw[-1]) if t_sw.size else 0.0)
    Lams = ext.costates(run, None)
    if Lams is None:
        return None
    starts = np.array([seg[0] for seg in run.segments])
    rows = [ext.sys.B @ Lams[int(np.argmin(np.abs(starts - tj)))] for tj in t_sw]
    fT = ext.sys.field(run.states[0], float(ext.levels[-1]), run.segments[-1][2])
    M = np.vstack(rows + [fT])[:, ext.I]
    rhs = np.zeros(M.shape[0])
    rhs[-1] = -1.0
    lam, *_ = np.linalg.lstsq(M, rhs, rcond=None)
    return lam if np.all(np.isfinite(lam)) else None


def has_stick_arcs(u: np.ndarray, F: float, peak: float) -> bool:
    """Whether a sampled move holds ``|u| = F`` (not the peak) on two samples or more in a row: the
    rigid body rests there while the modes are steered (a stick arc, not a bang-bang arc)."""
    if F <= 0.0 or F >= peak * (1.0 - 1e-6):
        return False
    at_f = np.abs(np.abs(u) - F) <= 1e-6 * peak
    return bool(np.any(at_f[1:] & at_f[:-1]))


def extremal_from_samples(
    problem: MoveProblem,
    u: np.ndarray,
    dt: float,
    F: float,
    scale: np.ndarray,
    peak: float,
    budget: list[int] | None = None,
) -> tuple[Extremal, np.ndarray] | None:
    """An extremal (switch-consistent, Newton-converged) from a sampled move with least peak ``peak``, or None."""
    levels, t_sw, T = bang_bang_guess(u, dt, peak)
    levels = levels / peak * problem.u_max
    ext = Extremal(problem, levels, F, scale)
    if not ext.valid(np.concatenate([t_sw, [T]])):
        return None
    lam = costate_guess(ext, t_sw, T)
    if lam is None:
        return None
    ok, ext, y = newton_solve(problem, levels, F, scale, np.concatenate([t_sw, [T], lam]), budget=budget)
    if not ok:
        return None
    return consistent_switches(problem, ext, y, F, scale, budget)
