"""A sampled bang-bang sequence from the switching function's signs: one free sample per switch, no LP.

At a vertex of the peak LP of :mod:`.zoh` (``n`` equality rows) at most
``n - 1`` samples lie strictly inside ``(-t, t)``; every other sample is at
``+-t`` with the sign of the switching function.  A sampled time-optimal
sequence therefore is, as a rule, ``+-t`` everywhere but one sample per
switch.  Given the signs ``S_m = nu^T g_m`` (``nu``: the continuous optimum's
dual direction), the sample of each sign change whose interval holds the
switch (the smaller ``|S_m|``; moved to the switch's other sample if its
value comes out past the peak, then walked one sample per round toward the
side it leans to, :func:`_walk`) is left free, and the final-state equations
are linear in the peak ``t`` and the free values ``v_j``::

    t sum_{m fixed} sign_m g_m + sum_j v_j g_{m_j} = w,

``n`` equations in ``c + 1`` unknowns (``c`` sign changes).  The least peak
on this pattern is a linear program in the ``d = c + 1 - n`` dimensions of
the solutions (``d <= 3``: a rotating, damped structure has a few switches
more than states): the best vertex of a polytope, among the intersections of
``d`` of its ``2 c + 1`` edges, then the samples at the peak pinned there and
the rest solved exactly -- ``O(switches)`` work with no LP solver, whatever
the number of samples ``K``.  The sequence is kept only if ``0 <= t <=
u_max``, ``|v_j| <= t`` and it lands exactly (to rounding); otherwise (the
sampled structure is not the continuous one: switches a few samples away
from the signs' changes, two switches within a sample, more free samples)
the caller solves the LP as before.  Nothing here proves anything: the
sample count's proof is the caller's (``K dt >= T*``, or the LP's dual bound
for the count below), and the sequence still passes the exact simulation of
:func:`.check.verified_samples`.
"""

from __future__ import annotations

import functools
import itertools
import math

import numpy as np

from .correction import lands_exactly

#: Free samples left past ``n - 1 + MAX_FREEDOM`` (more switches than states), or more than
#: ``MAX_VERTICES`` candidate vertices: the LP decides.
MAX_FREEDOM = 3
MAX_VERTICES = 1000
#: Attempts at most, each moving the free samples past the peak to their switch's other sample.
SWAP_ROUNDS = 3
#: A free sample within this (relative) of the peak at the minimum is pinned there.
PIN_RTOL = 1e-9


def switch_sample_sequence(G: np.ndarray, w: np.ndarray, S: np.ndarray, u_max: float) -> np.ndarray | None:
    """``u`` (rows of ``G``: ``m`` = samples to go) with ``G^T u = w``, ``|u| <= u_max``, or None.

    Parameters
    ----------
    G : ndarray, shape (K, n)
        Sample vectors ``g_m`` (scaled as the caller's LP).
    w : ndarray, shape (n,)
        The final-state target of the sum ``sum_m g_m u_m`` (same scaling).
    S : ndarray, shape (K,)
        Switching-function values ``nu^T g_m``: their signs are the commands'.
    u_max : float
        Bound on every command (N).
    """
    K, n = G.shape
    if K < n:
        return None
    signs = np.where(S >= 0.0, 1.0, -1.0)
    change = np.flatnonzero(signs[1:] != signs[:-1])
    # the sample of each switch whose interval holds it: first the smaller |S|; a free sample past the
    # peak moves to the switch's other sample (the sampled switch fell one sample over)
    first = np.abs(S[change]) <= np.abs(S[change + 1])
    # a long move: every sample's signed sum once, then O(switches) per pattern (was O(K n) per try, up to
    # 11 tries per count: 2 s of a 2.4e6-sample plan); short moves keep the direct sum (bit for bit as before)
    base = signs @ G if K > SUMMED_ROWS else None
    for _ in range(SWAP_ROUNDS):
        picks = np.where(first, change, change + 1)
        free = np.unique(picks)
        u, over, v = _sequence_on(G, w, signs, free, u_max, base)
        if u is not None:
            return u
        if over is None or not over.any():
            return None
        first ^= np.isin(picks, free[over])
    if change.size == 0 or v is None or free.size != change.size:
        return None
    return _walk(G, w, free, v, float(signs[0]), u_max, signs, base)


#: :func:`_walk`: rounds at most, each moving every free sample past the peak by one sample.
WALK_ROUNDS = 8
#: Past this many samples the fixed samples' sum ``signs @ G`` is formed once per count and updated
#: (the samples whose sign changed, the free ones), not summed again per pattern.
SUMMED_ROWS = 100_000


def _walk(G, w, free, v, sign0, u_max, signs_in=None, base=None) -> np.ndarray | None:
    """Walk the free samples toward the sampled switches, one sample per round (None if that finds nothing).

    The sampled optimum's switches lie a few samples from the continuous
    optimum's (its peak is below ``u_max``: ``K dt`` exceeds ``T*`` by a
    fraction of a sample, and the whole pattern stretches), further than the
    swaps above reach (one sample).  A free sample whose value ``v`` comes
    out past the peak in the sign of the arc before it means that arc is
    longer: its switch moves one sample later; in the sign of the arc after
    it, one sample earlier.  The arcs keep their signs (``sign0`` first,
    alternating); two switches in one sample end the walk (the LP decides).
    The 3-mode replans of ``bench/replan_latency.py``: 48 of 200 took the LP
    (~2 ms) for switches 1-3 samples away.
    """
    K = G.shape[0]
    free = free.copy()
    idx = np.arange(K)
    arc = sign0 * (1.0 - 2.0 * (np.arange(free.size) % 2))  # the sign of the arc before each free sample
    for _ in range(WALK_ROUNDS):
        over = np.abs(v) > 1.0 + PIN_RTOL
        if not over.any():
            return None
        free[over] += np.where(np.sign(v[over]) == arc[over], 1, -1)
        if free[0] < 0 or free[-1] >= K or np.any(np.diff(free) <= 0):
            return None
        count = np.searchsorted(free, idx, side="left")  # free samples before (or at) each sample
        signs = sign0 * (1.0 - 2.0 * (count % 2))
        if base is not None:  # the sum of the previous signs, updated where they changed
            moved = np.flatnonzero(signs != signs_in)
            base = base + (signs[moved] - signs_in[moved]) @ G[moved]
            signs_in = signs
        u, _, v = _sequence_on(G, w, signs, free, u_max, base)
        if u is not None:
            return u
        if v is None:
            return None
    return None


def _sequence_on(G, w, signs, free, u_max, base=None) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]:
    """The sequence with the samples ``free`` free, or ``(None, the free samples past the peak or None, v / t)``.

    ``v / t``: the free samples' values relative to the peak (past it: ``|v / t| > 1``), None if not solved.
    ``base``: ``signs @ G`` if known (the fixed samples' sum is then ``base`` less the free samples').
    """
    fixed = signs.copy()
    fixed[free] = 0.0
    col = fixed @ G if base is None else base - signs[free] @ G[free]
    M = np.column_stack([col, G[free].T])  # n x (free + 1): the peak t, then the free samples
    x, x0 = _min_peak(M, w)
    if x is None:
        if x0 is None:
            return None, None, None
        return None, np.abs(x0[1:]) > x0[0], (x0[1:] / x0[0] if x0[0] > 0.0 else None)
    # the vertex to rounding: the free samples at the peak pinned there, the others solved exactly
    t, v = x[0], x[1:]
    if np.any(np.abs(v) > t * (1.0 + PIN_RTOL)):  # a square system's solution past the peak: try the neighbours
        return None, np.abs(v) > t * (1.0 + PIN_RTOL), (v / t if t > 0.0 else None)
    pin = np.abs(v) >= t * (1.0 - PIN_RTOL)
    rest = free[~pin]
    if pin.any() or M.shape[1] != M.shape[0]:
        fixed[free[pin]] = np.sign(v[pin])
        col = (
            fixed @ G
            if base is None
            else base - signs[rest] @ G[rest] + (fixed[free[pin]] - signs[free[pin]]) @ G[free[pin]]
        )
        x = _solve(np.column_stack([col, G[rest].T]), w)
    # else: a square system with nothing pinned is solved already (the same matrix again)
    t, v = float(x[0]), x[1:]
    if not (0.0 <= t <= u_max) or np.any(np.abs(v) > t):
        return None, None, None
    u = fixed * t
    u[rest] = v
    return (u, None, None) if lands_exactly(G, w, u) else (None, None, None)


@functools.lru_cache(maxsize=64)
def _combinations(m: int, d: int) -> np.ndarray:
    """Every ``d`` of ``m`` row indices, shape ``(comb(m, d), d)`` (kept: the same few sizes recur)."""
    out = np.array(list(itertools.combinations(range(m), d)), dtype=np.intp).reshape(-1, d)
    out.flags.writeable = False
    return out


def _solve(M: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Least-norm ``M x = w`` with one refinement (the residual to rounding)."""
    x = np.linalg.lstsq(M, w, rcond=None)[0]
    return x + np.linalg.lstsq(M, w - M @ x, rcond=None)[0]


def _min_peak(M: np.ndarray, w: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None]:
    """``(x, x0)``: ``x = (t, v)`` minimising ``t`` over ``M x = w``, ``|v_j| <= t``, ``t >= 0`` (None if none
    is found: past ``MAX_FREEDOM``, rank-deficient, infeasible), and the least-norm solution ``x0``.

    The solutions are ``x0 + N z`` (``N``: the null space of ``M``, ``d``
    columns); with ``d <= MAX_FREEDOM`` the optimum is a vertex of the polytope
    ``A z <= b``, found among the intersections of every ``d`` of its rows.
    """
    n, p = M.shape
    d = p - n
    if d < 0:
        return None, None
    if d > MAX_FREEDOM or math.comb(2 * p - 1, d) > MAX_VERTICES:
        return None, _solve(M, w)
    U, sv, Vt = np.linalg.svd(M)
    if sv.size < n or sv[-1] <= np.finfo(float).eps * p * sv[0]:  # rank-deficient: the LP decides
        return None, None
    # the least-norm solution from this SVD (full rank), with one refinement: what _solve's two
    # least-squares solves give, without factorising M twice more
    R = Vt[:n].T
    x0 = R @ ((U.T @ w) / sv)
    x0 = x0 + R @ ((U.T @ (w - M @ x0)) / sv)
    if d == 0:
        return x0, x0
    N = Vt[n:].T  # p x d
    t0, tN, v0, vN = x0[0], N[0], x0[1:], N[1:]
    A = np.vstack([vN - tN, -vN - tN, -tN[None, :]])  # v - t <= 0, -v - t <= 0, -t <= 0
    b = np.concatenate([t0 - v0, t0 + v0, [t0]])
    rows = _combinations(A.shape[0], d)
    sub = A[rows]  # (pairs, d, d)
    det = np.linalg.det(sub) if d > 1 else sub[:, 0, 0]
    ok = np.abs(det) > 1e-12 * np.max(np.abs(A))
    if not ok.any():
        return None, x0
    z = np.linalg.solve(sub[ok], b[rows[ok]][..., None])[..., 0]  # (vertices, d)
    feasible = np.all(z @ A.T <= b + 1e-9 * max(1.0, float(np.max(np.abs(b)))), axis=1)
    if not feasible.any():
        return None, x0
    z = z[feasible]
    return x0 + N @ z[np.argmin(z @ tN)], x0
