"""Singular inputs inside one coupled part: ``B_i^T lambda = 0`` identically (not normal).

When an input reaches only a subspace ``R_i`` of the state (a mode only some
inputs reach, several rigid bodies), the optimal co-state may be orthogonal
to it: then ``S_i = nu^T e^{A tau} B_i`` vanishes identically, the input does
not set the minimum time, and any input of it that finishes the move is
optimal.  The planner then

1. solves the other inputs ``C`` with ``nu`` restricted to the orthogonal
   complement of ``R_J`` (``J``: the singular inputs) and only that component
   of the final state (:class:`~.newton.Setting`);
2. gives ``J`` the rest of the move inside ``R_J``, with the lowest peak
   fraction that arrives exactly at ``T*`` (:func:`peak_stages`: the same
   dual with ``nu`` restricted to ``R_J`` and the drive of ``C`` fixed);
   singular inputs inside that stage are handled the same way, recursively.

The time lower bound is unchanged (weak duality over every input: ``J``
contributes ``int |S_i| = 0``); each peak stage is proved by its own dual.
``R_J`` is the range of the controllability Gramian of ``J`` (scaled
states), over a horizon of at least two periods of the slowest mode.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import SolverError
from ..time_optimal.switching import sample_grid
from .dual import FINER, SMOOTHING, inner_smooth
from .newton import Extremal, Setting, drive_of, refine
from .response import MultiResponse
from .structure import structure, structure_newton

#: An input whose switching function stays below this, relative to the largest, is singular.
SINGULAR_RTOL = 1e-7
#: Gramian eigenvalues below this (relative to the largest) span no reachable direction.
GRAMIAN_RTOL = 1e-12
MAX_DEPTH = 3
#: Inputs whose ``|S_i|`` peak stays below this fraction of the largest are tried as singular when the
#: plain extremal fails: the smoothed dual only approaches a singular co-state (``B_i^T lambda -> 0``)
#: as its smoothing vanishes, so an exactly singular optimum can look merely small.
NEAR_SINGULAR_RTOL = 0.25
#: At most this many candidate sets of nearly singular inputs per warm start.
MAX_NEAR_SINGULAR = 4
#: A stage whose remaining (scaled) state is below this has nothing left to do (rounding of the earlier stages).
ZERO_REST = 1e-11


@dataclass
class Stage:
    """The inputs whose levels one stage sets: switch times (time-to-go) and first signs per input, ``nu``, ``rho``."""

    inputs: list
    roots: list
    sign0: list
    nuh: np.ndarray
    rho: float


def singular_inputs(resp: MultiResponse, nu: np.ndarray, T: float, active) -> list[int]:
    """Active inputs whose ``|S_i|`` on ``[0, T]`` stays below :data:`SINGULAR_RTOL` of the largest."""
    grid = sample_grid(resp, T)
    peak = np.max(np.abs(resp.switching_all(nu, grid)[0]), axis=1)
    idx = [i for i in range(resp.m) if active[i]]
    top = max((peak[i] for i in idx), default=0.0)
    if top <= 0.0:
        return []
    return [i for i in idx if peak[i] <= SINGULAR_RTOL * top]


def near_singular_candidates(resp: MultiResponse, s: np.ndarray, nu: np.ndarray, T: float) -> list[list[int]]:
    """Sets ``J`` of inputs to try as singular when neither the exact test nor the plain extremal succeeds.

    Each input whose ``|S_i|`` peak is below :data:`NEAR_SINGULAR_RTOL` of the
    largest and whose reachable subspace is not the whole state (else no
    co-state can be orthogonal to it), weakest first; then the weakest ones
    together.  A wrong guess is harmless: the others' minimum time is then a
    time at which ``J`` needs more than its bound (rejected by the caller),
    and every accepted plan is checked independently.
    """
    grid = sample_grid(resp, T)
    peak = np.max(np.abs(resp.switching_all(nu, grid)[0]), axis=1)
    top = float(np.max(peak, initial=0.0))
    if top <= 0.0:
        return []
    weak = [int(i) for i in np.argsort(peak) if peak[i] <= NEAR_SINGULAR_RTOL * top]
    weak = [i for i in weak if reachable_basis(resp, s, [i], T)[1].shape[1] > 0]
    out = [[i] for i in weak]
    for k in range(2, len(weak) + 1):
        J = sorted(weak[:k])
        if len(J) < resp.m and reachable_basis(resp, s, J, T)[1].shape[1] > 0:
            out.append(J)
    return out[:MAX_NEAR_SINGULAR]


def reachable_basis(resp: MultiResponse, s: np.ndarray, inputs, T: float) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal bases (scaled state ``x / s``) of the subspace ``inputs`` reach and of its complement."""
    horizon = T
    if resp.wd.size:
        horizon = max(T, 4.0 * math.pi / float(np.min(resp.wd)))
    grid = sample_grid(resp, horizon, density=2.0)
    E = resp.expm_B(grid)[:, :, list(inputs)] / s[None, :, None]  # (L, n, |J|)
    rows = np.transpose(E, (0, 2, 1)).reshape(-1, resp.n)
    lam, vecs = np.linalg.eigh(rows.T @ rows)
    keep = lam > GRAMIAN_RTOL * float(np.max(lam))
    return vecs[:, keep], vecs[:, ~keep]


def complement_within(V: np.ndarray | None, R: np.ndarray, n: int) -> np.ndarray:
    """Orthonormal basis of ``span(V)`` minus its components along ``span(R)`` (``V = None``: the whole space)."""
    P = np.eye(n) if V is None else V
    M = P - R @ (R.T @ P)
    U, sv, _ = np.linalg.svd(M, full_matrices=False)
    # absolute: the columns of P are orthonormal, so sv <= 1; when span(V) lies inside span(R), M is
    # rounding alone (~1e-16), and a threshold relative to its largest singular value would keep it
    return U[:, sv > 1e-9]


def peak_stages(
    resp: MultiResponse,
    x0: np.ndarray,
    u_max: np.ndarray,
    s: np.ndarray,
    T: float,
    active: np.ndarray,
    V: np.ndarray | None = None,
    base: np.ndarray | None = None,
    depth: int = 0,
) -> list[Stage]:
    """The lowest common peak fraction of the ``active`` inputs arriving exactly at ``T`` (s).

    ``nu`` restricted to ``span(V)``; ``base``: the fixed drive (unscaled
    state) of inputs solved before.  Singular inputs of this stage get the
    rest of the move with their own lowest peak (a further stage).
    """
    base = np.zeros(resp.n) if base is None else base
    w = -(resp.expm_x(T, x0) + base) / s
    if float(np.max(np.abs(w if V is None else V.T @ w))) <= ZERO_REST:
        # the earlier stages already bring this subspace to rest: these inputs stay at 0
        idx = [int(i) for i in np.flatnonzero(active)]
        return [Stage(idx, [np.empty(0)] * resp.m, [1.0] * resp.m, np.zeros(resp.n), 0.0)]
    duals = []
    nuh = None
    for eps in (*SMOOTHING, *(f[0] for f in FINER)):
        nuh, mval, _, _ = inner_smooth(resp, x0, u_max, s, T, nuh, eps, active=active, V=V, w_vec=w)
        if eps > SMOOTHING[-1]:
            continue
        duals.append((nuh, mval))
        J = singular_inputs(resp, nuh / s, T, active)
        if J and len(J) < int(np.count_nonzero(active)) and depth >= MAX_DEPTH:
            break
        if (found := _peak_attempt(resp, x0, u_max, s, T, active, V, base, depth, nuh, mval, J, False)) is not None:
            return found
    else:
        # a degenerate stage (e.g. an input mirroring another's drive on the modes: more final-state
        # equations than switches) has a family of co-states, and plain Newton steps leave the warm
        # start's sign pattern: minimum-norm steps from each warm start, only now (they slow wrong guesses)
        for nuh, mval in duals:
            J = singular_inputs(resp, nuh / s, T, active)
            if (found := _peak_attempt(resp, x0, u_max, s, T, active, V, base, depth, nuh, mval, J, True)) is not None:
                return found
    raise SolverError(
        f"multi-input planner: no lowest-peak extremal at T = {T:.6g} s for inputs {[int(i) for i in np.flatnonzero(active)]}; "
        "nothing is returned"
    )


def _peak_attempt(resp, x0, u_max, s, T, active, V, base, depth, nuh, mval, J, min_norm: bool) -> list[Stage] | None:
    """:func:`peak_stages` from one smoothed dual ``(nuh, mval)`` with its singular inputs ``J``; None if Newton fails."""
    if J and len(J) < int(np.count_nonzero(active)):
        Jmask = np.zeros(resp.m, dtype=bool)
        Jmask[J] = True
        C = active & ~Jmask
        R, _ = reachable_basis(resp, s, J, T)
        V2 = complement_within(V, R, resp.n)
        if V2.shape[1] == 0:  # J reaches all of span(V): no co-state there can be blind to it
            return None
        nuh2 = V2 @ (V2.T @ nuh)
        setting = Setting(C, V2, base, min_norm_steps=min_norm)
        ext = structure_newton(resp, x0, u_max, s, nuh2, T, 1.0 / mval, False, setting=setting)
        if ext is None:
            return None
        base2 = base + drive_of(resp, u_max, ext.roots, ext.sign0, T, ext.rho, C)
        head = Stage(list(np.flatnonzero(C)), ext.roots, ext.sign0, ext.nuh, ext.rho)
        return [head, *peak_stages(resp, x0, u_max, s, T, Jmask, R, base2, depth + 1)]
    setting = Setting(active, V, base, min_norm_steps=min_norm)
    ext = structure_newton(resp, x0, u_max, s, nuh, T, 1.0 / mval, False, setting=setting)
    if ext is None:
        return None
    return [Stage(list(np.flatnonzero(active)), ext.roots, ext.sign0, ext.nuh, ext.rho)]


def min_time_with_singular(resp, x0, u_max, s, nuh, T, J: list[int]):
    """Minimum time when the inputs ``J`` are singular: the others set ``T*``, then ``J`` by :func:`peak_stages`.

    Returns ``(extremal of the others, stages of J)`` or None if the Newton fails.
    """
    Jmask = np.zeros(resp.m, dtype=bool)
    Jmask[J] = True
    C = ~Jmask
    R, Q = reachable_basis(resp, s, J, T)
    nuh_c = Q @ (Q.T @ nuh)
    ext = structure_newton(resp, x0, u_max, s, nuh_c, T, 1.0, True, setting=Setting(C, Q))
    if ext is None:
        return None
    base = drive_of(resp, u_max, ext.roots, ext.sign0, ext.T, 1.0, C)
    stages = peak_stages(resp, x0, u_max, s, ext.T, Jmask, R, base)
    return ext, stages


def min_time_at_rigid_bound(resp: MultiResponse, x0, u_max, s, nuh, T):
    """Minimum time when the co-state sees only the rigid bodies (``T*`` the rigid-body bound).

    The inputs with a rigid-body gain (``C``) move the rigid bodies time-optimally
    with ``nu`` restricted to the rigid-body coordinates; the modes are then
    finished by the inputs without one (``J``, :func:`peak_stages`), or must
    already be at rest (``C``'s mode drives cancel).  Both leave the optimal
    co-state without a mode component, which the smoothed dual only
    approaches, and the plain Newton is singular there (e.g. two inputs
    switching together with opposite mode gains).

    Returns ``(extremal of C, stages of J)`` or None (Newton fails, or a
    mode direction ``J`` cannot reach is not at rest).
    """
    r, n = resp.r, resp.n
    if r == 0 or r == n:
        return None
    eye = np.eye(n)
    Q, R = eye[:, :r], eye[:, r:]
    Jmask = ~np.any(resp.B0 != 0.0, axis=0)
    C = ~Jmask
    if not C.any():
        return None
    ext = structure_newton(resp, x0, u_max, s, Q @ (Q.T @ nuh), T, 1.0, True, setting=Setting(C, Q))
    if ext is None:
        return None
    base = drive_of(resp, u_max, ext.roots, ext.sign0, ext.T, 1.0, C)
    R_J = reachable_basis(resp, s, np.flatnonzero(Jmask), ext.T)[0] if Jmask.any() else np.zeros((n, 0))
    # the modes J cannot reach must already be at rest
    w = (resp.expm_x(ext.T, x0) + base) / s
    out_of_reach = complement_within(R, R_J, n)
    if out_of_reach.shape[1] and float(np.max(np.abs(out_of_reach.T @ w))) > ZERO_REST:
        return None
    return ext, (peak_stages(resp, x0, u_max, s, ext.T, Jmask, R_J, base) if R_J.shape[1] else [])


#: The near-rigid-bound hypothesis is tried when the smoothed time is within this (relative) of the bound
#: (the finest smoothing leaves it ~1e-5 above a T* within GAP_RTOL of it).
NEAR_RIGID_RTOL = 1e-4


def min_time_near_rigid_bound(resp: MultiResponse, x0, u_max, s, nuh, T: float, T_low: float, gap_rtol: float):
    """A move within ``gap_rtol`` of the rigid-body bound ``T_low`` (s), whose modes are not quite at rest there.

    When the rigid-body bang-bang nearly leaves the modes at rest (e.g. a
    switch at a whole number of the mode's periods), ``T*`` lies a hair above
    ``T_low`` and the optimum finishes the modes with blips far shorter than
    the smoothing resolves, next to a switch (three switches where the warm
    start sees one).  Newton from each such structure; a converged extremal
    within ``gap_rtol`` of ``T_low`` is returned with the rigid-body bound's
    co-state (``nu`` on the rigid bodies only): its weak-duality bound proves
    the plan optimal within ``gap_rtol``, whether or not the blips' zeros can
    be isolated.  Returns the extremal (roots from the plan, ``nuh`` the
    rigid co-state) or None.
    """
    r, n = resp.r, resp.n
    if r == 0 or r == n or T > T_low * (1.0 + NEAR_RIGID_RTOL):
        return None
    Q = np.eye(n)[:, :r]
    C = np.any(resp.B0 != 0.0, axis=0)
    rigid = structure_newton(resp, x0, u_max, s, Q @ (Q.T @ nuh), T, 1.0, True, setting=Setting(C, Q))
    if rigid is None:
        return None
    roots, sign0 = structure(resp, nuh / s, T)
    for i in range(resp.m):
        for t0 in roots[i]:
            for side in (-1.0, 1.0):
                cand = [x.copy() for x in roots]
                w = side * 1e-4 * T
                cand[i] = np.sort(np.concatenate([cand[i], [t0 + w, t0 + 2.0 * w]]))
                if cand[i][0] <= 0.0 or cand[i][-1] >= T:
                    continue
                ok, r_out, _, T_out, _, _ = refine(resp, x0, u_max, s, cand, sign0, nuh, T, 1.0, True)
                if ok and T_out <= T_low * (1.0 + 0.25 * gap_rtol):
                    return Extremal(r_out, list(sign0), rigid.nuh, T_out, 1.0, 0.0)
    return None
