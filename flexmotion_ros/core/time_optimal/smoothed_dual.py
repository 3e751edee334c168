"""The smoothed, discretised inner problem of the reachable-set dual: a warm start for the exact one.

``|S|`` replaced by ``sqrt(S^2 + eps^2) - eps`` and the integral by the
trapezoidal rule (:func:`inner_smooth`); on a long move the rule's grid is
coarser and graded by the modes still ringing (:func:`graded_grid`).
"""

from __future__ import annotations

import math
from functools import partial

import numpy as np
from scipy.linalg import solve_triangular

from .reachable_set import Shooting, null_basis
from .switching import MIN_GRID_POINTS, POINTS_PER_HALF_PERIOD, sample_grid

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
#: ... and so does the rigid body's own ``e^{c tau}`` (``c < 0``) past ``tau = SMOOTH_DECAY / |c|``
#: (False: its spacing ``1 / (8 |c|)`` over the whole move, as before issue 15's second tail pass).
RIGID_DECAY = True
#: Newton on the smoothed problem stops when the predicted decrease is below
#: this (relative): a warm start whose duration is wanted to 1e-3 needs no
#: more (1e-14 took twice the iterations for the same guesses).
SMOOTH_RTOL = 1e-9


def inner_smooth(
    sh: Shooting,
    T: float,
    nuh: np.ndarray | None,
    eps_rel: float,
    max_iter: int = 50,
    smoothing: float | None = None,
    damping: bool = False,
):
    """Smoothed, discretised inner problem: a warm start for the exact one.

    ``|S|`` is replaced by ``sqrt(S^2 + eps^2) - eps`` and the integral by the
    trapezoidal rule on the bracketing grid: a smooth, strictly convex
    function of ``nu``, so Newton's method with a line search converges fast
    from any start, whatever the number of switches.  ``eps``: ``eps_rel``
    times the mean ``|S|`` at the start, or ``smoothing`` (scaled) if given.

    ``damping``: a Newton step the line search cuts below
    :data:`DAMP_BELOW_STEP` is damped (Levenberg-Marquardt) and tried again.
    On a coarse grid the curvature sits at fewer grid points than there are
    unknowns (a short move of 6-8 modes: the reduced Hessian singular to
    rounding, condition 1e17), Newton's steps are cut to 1e-11 and the solve
    stops far from its minimum; its ``m`` (an upper bound) then closes the
    bracket on ``T`` far below the optimum (fuzz case 3476, 8 modes: the warm
    start at 2.3 s, ``T*`` = 11.59 s).
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
    Z, GZ = _orthonormal_columns(Z, GZ)
    # smoothing scale: a fraction of the mean |S| at the start (fixed during this solve), or the caller's
    eps = smoothing if smoothing is not None else eps_rel * max(float(wq @ np.abs(S)) / T, 1e-300)

    def value(S):
        return um * float(wq @ (np.sqrt(S * S + eps * eps) - eps))

    def values(S, dS, ts):
        """``value(S + t dS)`` for each ``t`` of ``ts``, in one pass over the grid."""
        X = S[:, None] + dS[:, None] * ts
        return um * (wq @ (np.sqrt(X * X + eps * eps) - eps))

    f = value(S)
    damp = 0.0  # Levenberg-Marquardt damping (relative to the largest curvature), 0 while Newton works
    for _ in range(max_iter):
        sq = np.sqrt(S * S + eps * eps)
        g = um * (GZ.T @ (wq * S / sq))
        Hr = um * ((GZ.T * (wq * eps * eps / sq**3)) @ GZ)
        t = None
        while True:
            H = Hr + (damp * float(np.max(np.diag(Hr)))) * np.eye(Hr.shape[0]) if damp else Hr
            try:
                dy = -np.linalg.solve(H, g)
            except np.linalg.LinAlgError:
                dy = -g
            dec = -float(g @ dy)
            if dec <= SMOOTH_RTOL * f:
                break
            dS = GZ @ dy
            if damping and damp < MAX_DAMPING:
                # only the steps down to DAMP_BELOW_STEP, in one pass; none: the curvature sits at
                # fewer grid points than there are unknowns (Hr singular to rounding) and Newton
                # would crawl: damp it, as Levenberg-Marquardt does, and try again
                t = _long_step(partial(values, S, dS), f, dec)
                if t is not None:
                    break
                damp = max(MIN_DAMPING, 10.0 * damp)
                continue
            t = armijo_step(partial(values, S, dS), f, dec)
            if t is None or t < DAMP_BELOW_STEP:
                sh.short_steps += 1
            break
        if dec <= SMOOTH_RTOL * f or t is None:
            break
        damp = 0.0 if damp <= MIN_DAMPING else 0.1 * damp
        fc = value(S + t * dS)
        nuh = nuh + t * (Z @ dy)
        S = S + t * dS
        f = fc
    nu = nuh / s
    mu = um * float(wq @ (S * S / np.sqrt(S * S + eps * eps)))  # Lagrange multiplier nu.grad h
    dm = um * (math.sqrt(S[-1] ** 2 + eps * eps) - eps) + mu * float(nu @ sys.A_x(eAx))
    return nuh, f, dm


#: Search-space columns on the grid whose condition (estimated by the diagonal of their QR factor) exceeds
#: this are orthonormalised first (:func:`_orthonormal_columns`); inf: never (as before issue 15's tail5 pass).
ORTHONORMALISE_ABOVE = 1e6


def _orthonormal_columns(Z: np.ndarray, GZ: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The search space ``Z`` and its columns on the grid ``GZ``, with ``GZ`` orthonormal if ill-conditioned.

    Newton's step is affine invariant, but its Hessian ``GZ^T D GZ`` squares the condition of ``GZ``: on a
    short move of a slow rigid body and slow modes the columns are nearly polynomial (``1, t, t^2, ...``),
    condition 1e11-1e13 (a 4-mode vibration-only stop, 0.02-0.05 s: the Hessian singular to rounding, the
    steps garbage, ``m(T)`` jumping by 1e4 between neighbouring ``T``).  With ``GZ = Q R`` the same problem
    in the coordinates ``R y`` has the Hessian ``Q^T D Q``: conditioned by the smoothing alone.
    """
    if not math.isfinite(ORTHONORMALISE_ABOVE) or GZ.shape[1] == 0:
        return Z, GZ
    d = np.abs(np.diag(np.linalg.qr(GZ, mode="r")))  # R alone first: most grids are well conditioned
    if d.min() * ORTHONORMALISE_ABOVE >= d.max() or d.min() <= 1e-300:
        return Z, GZ
    Q, R = np.linalg.qr(GZ)
    return solve_triangular(R, Z.T, trans="T", lower=False).T, Q


#: A Newton step of the smoothed problem cut below this length by the line search is damped
#: (Levenberg-Marquardt, :func:`inner_smooth`) and tried again.
DAMP_BELOW_STEP = 2.0**-12
#: The damping's first value, relative to the largest diagonal entry of the Hessian ...
MIN_DAMPING = 1e-10
#: ... and its largest (the step is then nearly a scaled gradient step).
MAX_DAMPING = 1e-1
#: Step lengths ``1, 1/2, ..., 2^-(LINE_SEARCH_STEPS - 1)`` tried by the line search of :func:`inner_smooth`.
LINE_SEARCH_STEPS = 40
#: After a full step fails, this many halvings are evaluated per pass over the grid.
LINE_SEARCH_BATCH = 8


def armijo_step(values, f: float, dec: float) -> float | None:
    """The longest step ``t = 2^-k`` (``k < LINE_SEARCH_STEPS``) with ``values(t) <= f - dec t / 4``; None if none.

    ``values(ts)`` evaluates the objective at an array of step lengths.  The
    full step is tried alone (Newton's step, accepted near the minimiser),
    then :data:`LINE_SEARCH_BATCH` halvings per call: the smoothed problem's
    Newton steps on a coarse grid are often cut 10-20 times (its curvature
    sits at the few grid points near the zeros of ``S``), and one call per
    halving made the line search most of a chattering stop's warm start.
    The step chosen is the one halving one at a time would choose.
    """
    k = 0
    while k < LINE_SEARCH_STEPS:
        size = 1 if k == 0 else min(LINE_SEARCH_BATCH, LINE_SEARCH_STEPS - k)
        ts = 0.5 ** np.arange(k, k + size, dtype=float)
        ok = np.flatnonzero(values(ts) <= f - 0.25 * ts * dec)
        if ok.size:
            return float(ts[ok[0]])
        k += size
    return None


def _long_step(values, f: float, dec: float) -> float | None:
    """The longest step ``t = 2^-k >= DAMP_BELOW_STEP`` with ``values(t) <= f - dec t / 4`` (one call), or None."""
    ts = 0.5 ** np.arange(round(-math.log2(DAMP_BELOW_STEP)) + 1, dtype=float)
    ok = np.flatnonzero(values(ts) <= f - 0.25 * ts * dec)
    return float(ts[ok[0]]) if ok.size else None


def graded_grid(system, T: float, per_half_period: float) -> np.ndarray | None:
    """Points on ``[0, T]`` (s) spaced by the fastest mode still ringing, for the smoothed problem.

    Mode ``i``'s response decays like ``e^{-zeta_i omega_i tau}``; past
    ``tau = SMOOTH_DECAY / (zeta_i omega_i)`` it is below rounding of its
    start and the rule's spacing follows the next slower mode (a rigid tail:
    the rigid body's own time scale).  ``per_half_period`` points per half
    period of the fastest mode alive in each stretch.  The rigid body's own
    terms ``e^{c tau}`` (``c < 0``: viscous damping) get 8 points per time
    constant ``1 / |c|`` while they last, up to ``tau = SMOOTH_DECAY / |c|``:
    past it the rigid part of ``S`` is a constant to rounding, integrated
    exactly on any grid.  (Spaced ``1 / (8 |c|)`` over the whole move, the
    rigid tail of a long cruise was most of the grid: fuzz case 1476, a
    2,285 s move with ``c = -0.89``: 27,536 points, every mode rung out
    after 1,200 s.)  None for a system without ``sig`` (decay rates) or if
    nothing decays within ``T``.
    """
    sig, wd = getattr(system, "sig", None), getattr(system, "wd", None)
    if sig is None or wd is None or not np.size(wd) or not math.isfinite(SMOOTH_DECAY):
        return None
    with np.errstate(divide="ignore"):
        life = np.where(sig > 0.0, SMOOTH_DECAY / np.maximum(sig, 1e-300), math.inf)
    c = float(getattr(system, "c", 0.0))
    # the life of e^{c tau}; c > 0 grows: the whole move
    rigid_life = SMOOTH_DECAY / -c if c < 0.0 and RIGID_DECAY else math.inf
    ends = np.unique(np.concatenate([life[life < T], [rigid_life] if rigid_life < T else [], [T]]))
    if ends.size == 1:
        return None
    pieces, a = [], 0.0
    for b in ends:
        alive = wd[life > a]
        w = float(np.max(alive)) if alive.size else 0.0
        rigid = 8.0 * abs(c) * (min(b, rigid_life) - a) if a < rigid_life else 0.0
        n = max(MIN_GRID_POINTS // 2, math.ceil((b - a) * w / math.pi * per_half_period), math.ceil(rigid))
        pieces.append(np.linspace(a, b, n + 1)[:-1])
        a = b
    pieces.append(np.array([T]))
    return np.concatenate(pieces)
