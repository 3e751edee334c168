"""The lean path of the time-optimal planner: the fast path's guess and Newton on fused closed forms.

The fast path (:mod:`.structure_guess`) spends most of a small plan in numpy
call overheads: its smoothed warm start brings the duration to within 1e-3
of the optimum over two smoothing levels (five or six convex solves), and
each Newton step asks :class:`~flexmotion_ros.core.simulation.modal_response.ModalResponse`
five separate questions at the same times.  This module does the same
mathematics with less:

* :func:`smoothed_guess`: one smoothing level on a coarser grid (4 points
  per half period of the fastest mode), entered through one loose, smoother
  level (:data:`CONTINUATION`: Newton from the cold start needs a third fewer
  steps that way), the duration only to within 1 %
  (the switch-time Newton corrects it), every response on the grid from one
  :class:`~flexmotion_ros.core.simulation.modal_kernel.ModalKernel` call, the
  hyperplane's null basis from one Householder reflection;
* :func:`structure_from_samples`: the switch structure of the smoothed
  co-state on that grid (sign changes, and narrow pairs where ``|S|`` nearly
  touches zero), as :func:`~.structure_guess.guess_structure` does on its own grid;
* :func:`refine`: the switch-time Newton of
  :func:`~.switch_newton.refine_switches` (same unknowns, equations, scaling,
  line search and convergence test), each iterate's responses from one kernel call.

Nothing here is trusted: the planner hands every converged candidate to the
same exact simulation and Pontryagin certificate as the full solver's, and
runs the fast path and the full solver when this path finds nothing.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg.lapack import dgesv

from ..kernels import backend
from ..kernels import smoothed as kernel_smoothed
from ..simulation.error_scale import state_scale
from ..simulation.modal_kernel import ModalKernel
from ..tolerances import POLISH_TOL
from .reachable_set import bracketed_step
from .switch_newton import DENSE_UP_TO, MERGE_AFTER, MERGE_RTOL, ROUNDING_FLOOR, damped_step, merging_pair

#: A local minimum of ``|S|`` below this fraction of its maximum is a near-zero
#: (the value of ``structure_guess.NEAR_ZERO``; not imported from there so that
#: this module sits beside it, not above it, in the import graph).
NEAR_ZERO = 1e-2
#: ... and below this, one even if the switches are not too few (``structure_guess.VERY_NEAR_ZERO``).
VERY_NEAR_ZERO = 1e-3
#: Smoothing of ``|S|`` (relative to its mean) of the one warm-start level.
SMOOTHING = 0.005
#: Steps on the duration of the warm start; it stops within :data:`LOG_TOL` of ``m = 1``.  Eight, not four:
#: where ``m`` is flat at the first duration (``dm/dT`` 4e-3 at a 3-mode replan's ``T_init``) the first step
#: overshoots 4x and the bracket needs 5-6 steps back; stopped after four, the guess was 11 % short and the
#: lean Newton failed (the fast path then took ~12 ms more: 5 of the 200 3-mode replans of
#: ``bench/replan_latency.py``, 1 and 2 of the 1- and 2-mode ones; the others stop where they did).
OUTER_STEPS = 8
#: ``|log m(T)|`` below which the warm start's duration is close enough for the switch-time Newton.
LOG_TOL = 1e-2
#: Grid points per half period of the fastest mode of the warm start (the planners' grid has 8).
POINTS_PER_HALF_PERIOD = 4
#: ... and at least this many.
MIN_POINTS = 32
#: The lean path is for models with at most this many modes: with 5-8 modes its
#: coarse guess often misses the structure, and the failed attempt cost more than
#: it saved (``bench/planner_latency.py --lean-ab``: the 8-mode 0.56 m move took
#: 8.9 ms without it, 21.6 ms with it, the fast path answering either way).
MAX_MODES = 3
#: The lean path is for moves whose warm-start grid has at most this many points
#: (longer moves: the fast path's own grid rules apply).
MAX_POINTS = 4096
#: Newton on the smoothed problem stops when the predicted decrease is below this (relative).
INNER_RTOL = 1e-9
#: Smoothing levels (relative to the mean ``|S|``) solved first, loosely, from the cold start:
#: a smoother objective that Newton crosses in few steps, and from its minimiser the
#: :data:`SMOOTHING` level converges in fewer (the 9 bench moves: 660 objective evaluations
#: of the warm start -> 453, smoothed_guess 8.5 -> 5.8 ms summed, same optima).
CONTINUATION = (0.1,)
#: Newton decrement (relative) at which a :data:`CONTINUATION` level stops.
CONTINUATION_RTOL = 1e-3
#: Newton steps on the smoothed problem per duration.
INNER_STEPS = 50
#: :func:`refine` merges the closest pair of switches (closer than ``MERGE_RTOL T``) once its
#: gap has shrunk to at most this fraction of the last on :data:`SHRINK_STEPS` accepted steps
#: in a row: a blip closing (Newton on it converges linearly, the gap halving per step; the
#: 3-mode 1 m bench move took 25 steps to a pair 1.7e-12 T wide, which the planner then dropped).
SHRINK_RATIO = 0.6
#: ... see :data:`SHRINK_RATIO`.
SHRINK_STEPS = 4
#: Merges are looked for only after a step that cut the residual by less than this factor (a closing
#: pair halves it per step; Newton near a simple root cuts it far more): the bookkeeping cost ~1.5 %
#: of a plan whose run converges quadratically.
SLOW_STEP = 0.25


class LeanMove:
    """One move's data for the lean path: responses, scaled state, bound.

    Parameters
    ----------
    response : ModalResponse
        Closed-form responses of the model (the planner's state).
    x0 : ndarray
        Shifted initial state (the response's state).
    u_max : float
        Input bound (N).
    T_scale : float
        Duration (s) whose state scale (:func:`state_scale`) makes the
        unknowns of order one (kept fixed: a lean plan does not rescale).
    """

    def __init__(self, response, x0: np.ndarray, u_max: float, T_scale: float) -> None:
        self.response = response
        self.kernel = ModalKernel(response, x0)
        self.x0 = x0
        self.u_max = u_max
        self.n = response.n
        self.s = state_scale(response, x0, u_max, T_scale)
        self.evaluations = 0
        #: The last smoothed step's grid data, ``(T, cells, tau, G, w, A e^{AT} x0, weights, null basis)``.
        self.grid = None

    def grid_points(self, T: float) -> int:
        """Cells of the warm-start grid on ``[0, T]``."""
        wmax = self.kernel.fastest
        cells = MIN_POINTS
        if wmax > 0.0:
            cells = max(cells, math.ceil(T * wmax / math.pi * POINTS_PER_HALF_PERIOD))
        return cells


def _solve(A: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """``A^{-1} b`` by LAPACK's ``gesv`` (LU with partial pivoting, as ``np.linalg.solve``); None if singular.

    Called directly: ``np.linalg.solve`` spends ~20 times the factorisation of
    these 3-20 unknowns in its Python wrapper (measured, 5 x 5: 21 us against 0.8 us).
    """
    x, info = dgesv(A, b)[2:]
    return x if info == 0 else None


def _null_basis(w: np.ndarray) -> np.ndarray:
    """Orthonormal basis (columns) of the complement of ``w``: a Householder reflection's last columns."""
    v = w / math.sqrt(float(w @ w))
    u = v.copy()
    u[0] += 1.0 if v[0] >= 0.0 else -1.0
    return np.eye(v.size)[:, 1:] - np.outer(u, u[1:] * (2.0 / float(u @ u)))


def _inner(lm: LeanMove, T: float, nuh: np.ndarray | None, eps_rel: float, rtol: float = INNER_RTOL):
    """Smoothed inner problem at ``T`` (as :func:`~.smoothed_dual.inner_smooth`, on the lean grid).

    Returns ``(nuh, m, dm/dT, tau, S)``: the scaled co-state direction, the
    smoothed ``m(T)`` and its derivative, the grid (time-to-go, s) and the
    switching function of ``nuh`` on it (scaled).  The objective is
    ``u_max sum wq (sqrt(S^2 + eps^2) - eps)``, evaluated as ``sum (u_max wq)
    hypot(S, eps)`` less the constant ``u_max eps sum wq`` (one numpy call
    per term instead of four: the line search evaluates it ~3 times a step).
    """
    um, s = lm.u_max, lm.s
    if lm.grid is not None and lm.grid[0] == T:  # a continuation level at the same duration: same grid
        _, cells, tau, Gm, w, AeAx, uw, Z = lm.grid
    else:
        cells = lm.grid_points(T)
        tau = np.linspace(0.0, T, cells + 1)
        eB, eAx, AeAx = lm.kernel.input_response(tau)
        lm.evaluations += 1
        Gm = eB / s
        w = -eAx / s
        uw = np.full(tau.size, um * (T / cells))  # u_max times the trapezoid weights
        uw[0] *= 0.5
        uw[-1] *= 0.5
        Z = _null_basis(w)
        lm.grid = (T, cells, tau, Gm, w, AeAx, uw, Z)
    if nuh is None or float(nuh @ w) <= 0.0:
        nuh = w / float(w @ w)
    else:
        nuh = nuh / float(nuh @ w)
    S = Gm @ nuh
    GZ = Gm @ Z
    GZt = GZ.T
    eps = eps_rel * max(float(uw @ np.abs(S)) / (um * T), 1e-300)
    shift = eps * float(uw.sum())  # u_max eps sum wq
    uwe2 = uw * (eps * eps)
    sq = np.hypot(S, eps)
    f = float(uw @ sq) - shift
    if backend.ACTIVE:  # the same steps, compiled: one call instead of ~15 numpy calls a step
        nuh, S, sq, f = kernel_smoothed.smoothed_newton(GZ, Z, uw, nuh, S, sq, f, eps, shift, rtol, INNER_STEPS)
    for _ in range(0 if backend.ACTIVE else INNER_STEPS):
        g = GZt @ (uw * S / sq)
        Hr = (GZt * (uwe2 / (sq * sq * sq))) @ GZ
        dy = _solve(Hr, g)
        dy = -(g if dy is None else dy)
        dec = -float(g @ dy)
        if dec <= rtol * f:
            break
        dS = GZ @ dy
        t = 1.0
        for _ in range(40):
            Sc = S + t * dS
            sqc = np.hypot(Sc, eps)
            fc = float(uw @ sqc) - shift
            if fc <= f - 0.25 * t * dec:
                break
            # backtrack to the minimum of the parabola through f, its slope -dec and fc, within [t/10, t/2]:
            # the full Newton step of this nearly non-smooth objective overshoots by 4-8x, halving took ~2.4 tries
            curv = fc - f + t * dec
            t = min(0.5 * t, max(0.1 * t, 0.5 * dec * t * t / curv)) if curv > 0.0 else 0.5 * t
        else:
            break
        nuh = nuh + t * (Z @ dy)
        S, sq, f = Sc, sqc, fc
    mu = float(uw @ (S * S / sq))
    dm = um * (float(sq[-1]) - eps) + mu * float((nuh / s) @ AeAx)
    return nuh, f, dm, tau, S


def smoothed_guess(lm: LeanMove, T_low: float, T_init: float):
    """Co-state direction and duration from one smoothed level (see the module docstring).

    Returns ``(nuh, T, tau, S)``: the scaled co-state direction and the
    duration (s) of the last smoothed solve, its grid (time-to-go, s) and the
    switching function of ``nuh`` on it.
    """
    T = max(T_init, T_low, 1e-300)
    lo, hi = T_low, math.inf
    nuh = None
    for eps_rel in CONTINUATION:
        nuh = _inner(lm, T, nuh, eps_rel, CONTINUATION_RTOL)[0]
    for k in range(OUTER_STEPS):
        nuh, m, dm, tau, S = _inner(lm, T, nuh, SMOOTHING)
        if (m > 0.0 and abs(math.log(m)) < LOG_TOL) or k == OUTER_STEPS - 1:
            break
        T, lo, hi = bracketed_step(T, m, dm, lo, hi)
    return nuh, float(tau[-1]), tau, S


def structure_from_samples(tau: np.ndarray, S: np.ndarray, n: int) -> tuple[np.ndarray, float]:
    """Switch structure (times-to-go, s, and the first sign) guessed from ``S`` sampled on ``tau``.

    Sign changes (linear interpolation), plus a narrow pair at each local
    minimum of ``|S|`` below :data:`VERY_NEAR_ZERO` of its
    maximum, and at the deepest ones below :data:`NEAR_ZERO`
    while the switches are fewer than ``n - 1`` (the rule of
    :func:`~.structure_guess.guess_structure`).  Nothing is proved.
    """
    sg = np.sign(S)
    nz = np.flatnonzero(sg)
    if nz.size == 0:
        return np.empty(0), 1.0
    k = np.flatnonzero(sg[nz[:-1]] != sg[nz[1:]])
    i, j = nz[k], nz[k + 1]
    roots = tau[i] + (tau[j] - tau[i]) * S[i] / (S[i] - S[j])
    sign0 = float(sg[nz[0]])
    missing = (n - roots.size) // 2
    a = np.abs(S)
    top = float(np.max(a))
    m = np.flatnonzero((a[1:-1] < a[:-2]) & (a[1:-1] <= a[2:]) & (sg[:-2] == sg[2:])) + 1
    if m.size == 0:
        return roots, sign0
    m = m[np.argsort(a[m])]
    deep = int(np.count_nonzero(a[m] < VERY_NEAR_ZERO * top))
    m = m[a[m] < NEAR_ZERO * top][: max(missing, deep)]
    if m.size == 0:
        return roots, sign0
    h = 0.25 * (tau[1] - tau[0])
    c = tau[m]
    pairs = np.stack([c - h, c + h], axis=1)
    pairs = pairs[(pairs[:, 0] > 0.0) & (pairs[:, 1] < tau[-1])].ravel()
    return np.sort(np.concatenate([roots, pairs])), sign0


def refine(
    lm: LeanMove, roots: np.ndarray, sign0: float, nuh: np.ndarray, T: float, max_iter: int = 30, halvings: int = 12
):
    """Switch-time Newton for a fixed structure: :func:`~.switch_newton.refine_switches` on the kernel.

    Unknowns ``(tau_1..tau_L, nu, T)``; equations: final state zero (``n``),
    switching function zero at each switch (``L``), one normalisation of
    ``nu``.  Returns ``(ok, roots, nuh, T, residual)``; ``ok`` is False if
    the structure broke (switches crossed or left ``(0, T)``) or Newton stalled
    (no step of the line search, at most ``halvings`` tries, lowered the residual),
    or at once for more than :data:`~.switch_newton.DENSE_UP_TO` switches (the
    whole system is solved densely here; the fast path eliminates).

    A pair of neighbouring switches closer than ``MERGE_RTOL T`` is merged
    (removed, Newton goes on with ``L - 2`` switches from where it is; the
    returned ``roots`` then has that size) when full steps carry it past
    itself :data:`~.switch_newton.MERGE_AFTER` times in a row (as
    :func:`~.switch_newton.refine_switches` with ``merge``), or when its gap
    shrinks geometrically (:data:`SHRINK_RATIO`, :data:`SHRINK_STEPS`): a blip
    closing, which Newton would only halve step by step.
    """
    kern, s, um, n = lm.kernel, lm.s, lm.u_max, lm.n
    L = roots.size
    if L > DENSE_UP_TO:
        return False, roots, nuh, T, math.inf
    signs = sign0 * (1.0 - 2.0 * (np.arange(L + 1) % 2))
    jump = 2.0 * um * signs[:-1]
    sl = um * float(signs[-1])
    weights = np.append(jump, sl)  # F = e^{AT} x0 + weights . Gamma(tau_1..tau_L, T)
    inv_s = 1.0 / s
    nuh = nuh / math.sqrt(float(nuh @ nuh))
    anchor = nuh.copy()
    eps = np.finfo(float).eps
    J = np.zeros((n + L + 1, L + n + 1))
    J[-1, L : L + n] = anchor
    diag = (np.arange(n, n + L), np.arange(L))  # the switch rows' own time columns

    def residual(tau, nuh, T):
        kv = kern.evaluate(np.append(tau, T))
        lm.evaluations += 1
        g = kv.eB[:L] * inv_s
        r = np.empty(n + L + 1)
        r[:n] = (kv.eAx + weights @ kv.G) * inv_s
        r[n : n + L] = (g @ nuh) * gscale
        r[-1] = anchor @ nuh - 1.0
        return r, g, kv

    gscale = 1.0
    tau = roots.copy()
    r, g, kv = residual(tau, nuh, T)
    if L:
        gscale = 1.0 / max(math.sqrt(float(np.max(np.einsum("ij,ij->i", g, g)))), 1e-300)
        r[n : n + L] *= gscale
    rn = float(np.max(np.abs(r)))
    floor = 0.0
    blocked, blocked_pair = 0, None  # full steps in a row that the same closing pair blocked
    shrunk, last_gap = 0, math.inf  # accepted steps in a row that shrank the closest pair geometrically
    slow = True  # the last step cut the residual by less than 1 / SLOW_STEP (merges are looked for only then)
    for it in range(max_iter):
        if rn <= 16.0 * eps:
            break
        J[:n, :L] = g.T * jump
        J[:n, -1] = (kv.AeAx + sl * kv.eB[L]) * inv_s
        if L:
            J[diag] = (kv.AeB[:L] @ (nuh * inv_s)) * gscale
            J[n : n + L, L : L + n] = g * gscale
        step = _solve(J, -r)
        if step is None:
            step = np.linalg.lstsq(J, -r, rcond=None)[0]
        if max(float(np.max(np.abs(step[:L]), initial=0.0)), abs(float(step[-1]))) <= 4.0 * eps * T:
            # below rounding of the times: converged to what they can resolve (as in refine_switches)
            slope = max(float(np.max(np.abs(J[: n + L, :L]), initial=0.0)), float(np.max(np.abs(J[:n, -1]))))
            floor = ROUNDING_FLOOR * eps * T * slope
            break
        if slow and L >= 2:  # (a run converging quadratically skips the bookkeeping)
            k = merging_pair(tau, step[:L], T)
            blocked = blocked + 1 if k is not None and k == blocked_pair else int(k is not None)
            blocked_pair = k
            if blocked >= MERGE_AFTER and it + 1 < max_iter:
                return refine(lm, np.delete(tau, [k, k + 1]), sign0, nuh, T, max_iter - it - 1, halvings)
        else:
            blocked, blocked_pair = 0, None
        accepted = damped_step(tau, nuh, T, step, rn, residual, halvings)
        if accepted is None:
            break
        rn_before = rn
        tau, nuh, T, r, g, kv, rn = accepted
        slow = rn > SLOW_STEP * rn_before
        if not slow:
            shrunk, last_gap = 0, math.inf
        elif L >= 2 and rn > POLISH_TOL:
            gaps = np.diff(tau)
            k = int(np.argmin(gaps))
            gap = float(gaps[k])
            shrunk = shrunk + 1 if gap <= SHRINK_RATIO * last_gap and gap <= MERGE_RTOL * T else 0
            last_gap = gap
            if shrunk >= SHRINK_STEPS and it + 1 < max_iter:
                return refine(lm, np.delete(tau, [k, k + 1]), sign0, nuh, T, max_iter - it - 1, halvings)
    if L:  # nu and -nu both vanish at the switches: take the one whose signs match
        first = lm.response.switching(nuh / s, np.array([0.5 * tau[0]]))[0]
        if np.sign(first) != sign0:
            nuh = -nuh
    return rn <= max(POLISH_TOL, floor), tau, nuh, T, rn
