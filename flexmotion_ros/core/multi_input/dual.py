"""The convex reachable-set dual with ``m`` inputs, and its independent weak-duality bound.

In time-to-go ``tau = T - t`` a co-state direction ``nu`` (``-lambda(T)`` up to
a positive factor) gives every input its Pontryagin level
``u_i(tau) = rho u_max_i sgn(S_i(tau))``, ``S_i = nu^T e^{A tau} B_i``, and::

    h_T(nu) = rho sum_i u_max_i int_0^T |S_i(tau)| dtau

is the support function of the set reachable in time ``T`` with peaks
``rho u_max_i``: the sum over the inputs of their support functions (the
reachable set is the Minkowski sum of the inputs' sets).  ``x0`` reaches rest
in time ``T`` iff ``m(T) = min {h_T(nu) : nu^T w = 1} >= 1`` with
``w = -e^{A T} x0``.  Hence:

* minimum time (``rho = 1``): the root of ``m(T) = 1``;
* lowest peak at a fixed ``T`` (``sync=time``): ``rho* = 1 / m(T)`` at ``rho = 1``.

Weak duality bounds both from below, for ANY ``nu``: ``nu^T w(T) > h_T(nu)``
proves that no admissible input reaches rest in ``T`` (and, feasibility being
monotone, in any shorter time); ``rho >= nu^T w / h_T(nu)|_{rho=1}`` for any
input arriving at ``T``.  :func:`duality_bound` evaluates it independently of
the planner: zeros of ``S_i`` isolated with proof, ``int |S_i|`` from the
augmented matrix exponential of the full ``(A, B)`` (:mod:`.exact`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from ..time_optimal.reachable_set import bracketed_step, null_basis
from ..time_optimal.switching import isolate_roots, sample_grid
from .exact import input_integral
from .response import MultiResponse

#: Smoothing levels (relative to the bound-weighted mean ``|S|``) of the warm start.
SMOOTHING = (0.005,)
#: Finer levels tried, in turn, when the switch-time Newton fails from the first warm start.
FINER = ((2e-4,), (2e-5,), (2e-6,))


def multi_state_scale(resp: MultiResponse, x0: np.ndarray, u_max: np.ndarray, T: float) -> np.ndarray:
    """How large each (reduced) state can get in a move of length ``T`` (state units).

    ``|x0|`` (a mode's position and velocity sharing one amplitude, a position
    carried by its initial speed) plus ``sum_i u_max_i max_tau |Gamma_i(tau)|``:
    independent of the profile, the scale final-state errors are judged against.
    """
    grid = np.concatenate([np.linspace(0.0, T, 65), np.geomspace(T * 1e-6, T, 61)]) if T > 0 else np.zeros(1)
    G = resp.input_integral(grid)  # (L, n, m)
    s = np.abs(x0).copy()
    hp = resp.has_pos
    s[resp.p_idx[hp]] += np.abs(x0[resp.v_idx[hp]]) * T
    if resp.w.size:
        q, qd = x0[resp.q_idx], x0[resp.qd_idx]
        amp = np.hypot(q, (qd + resp.sig * q) / resp.wd)
        s[resp.q_idx] = np.maximum(s[resp.q_idx], amp)
        s[resp.qd_idx] = np.maximum(s[resp.qd_idx], amp * resp.w)
    s = s + np.max(np.abs(G), axis=0) @ np.asarray(u_max, float)
    return np.where(s > 0.0, s, 1.0)


@dataclass
class Stage:
    """The discretised dual at one ``T``: stacked rows ``e^{A tau} B_i / s`` and weights."""

    T: float
    grid: np.ndarray
    G: np.ndarray  # (m * L, n), input-major
    W: np.ndarray  # (m * L,) u_max_i * quadrature weight
    w: np.ndarray  # -e^{A T} x0 / s
    eAx: np.ndarray


def stage(resp: MultiResponse, x0: np.ndarray, u_max: np.ndarray, s: np.ndarray, T: float) -> Stage:
    """The discretised dual problem at ``T`` (grid fine enough for the fastest mode)."""
    grid = sample_grid(resp, T)
    wq = np.full(grid.size, grid[1] - grid[0])
    wq[[0, -1]] *= 0.5
    E = resp.expm_B(grid) / s[None, :, None]  # (L, n, m)
    G = np.ascontiguousarray(np.transpose(E, (2, 0, 1)).reshape(resp.m * grid.size, resp.n))
    W = (np.asarray(u_max, float)[:, None] * wq[None, :]).ravel()
    eAx = resp.expm_x(T, x0)
    return Stage(T, grid, G, W, -eAx / s, eAx)


def inner_smooth(resp, x0, u_max, s, T, nuh, eps_rel: float, max_iter: int = 60, active=None, V=None, w_vec=None):
    """Smoothed, discretised ``min h_T(nu)`` on ``nu^T w = 1`` by Newton's method.

    ``|S|`` is replaced by ``sqrt(S^2 + eps^2) - eps``: smooth and strictly
    convex, so Newton with a line search converges from any start whatever the
    switch structure.  Returns ``(nuh, m, dm/dT, stage)`` (``nuh`` scaled by ``s``).

    ``active`` (bool per input): only those inputs' support functions count;
    ``V`` (orthonormal columns): ``nu`` restricted to that subspace; ``w_vec``:
    the (scaled) state to reach instead of ``-e^{A T} x0`` (a part of the
    move left to some inputs).
    """
    st = stage(resp, x0, u_max, s, T)
    L = st.grid.size
    G, W = st.G, st.W.copy()
    w = st.w if w_vec is None else np.asarray(w_vec, float)
    if active is not None:
        W = W * np.repeat(np.asarray(active, float), L)
    if V is not None:
        G, w = G @ V, V.T @ w
        nuh = None if nuh is None else V.T @ nuh
    if nuh is None or float(nuh @ w) <= 0.0:
        nuh = w / float(w @ w)
    else:
        nuh = nuh / float(nuh @ w)
    Z = null_basis(w)
    S = G @ nuh
    # one smoothing width per input, relative to that input's own mean |S_i|: an input whose
    # switching function is far smaller than the others' (nearly singular) keeps its structure
    U = np.asarray(u_max, float)
    mean_i = (np.abs(S) * W).reshape(resp.m, L).sum(axis=1) / (T * U)
    mean_i = np.maximum(mean_i, 1e-9 * float(np.max(mean_i)) + 1e-300)
    eps = np.repeat(eps_rel * mean_i, L)

    def value(S):
        return float(W @ (np.sqrt(S * S + eps * eps) - eps))

    f = value(S)
    GZ = G @ Z
    for _ in range(max_iter):
        sq = np.sqrt(S * S + eps * eps)
        g = GZ.T @ (W * S / sq)
        H = (GZ.T * (W * eps * eps / sq**3)) @ GZ
        try:
            dy = -np.linalg.solve(H, g)
        except np.linalg.LinAlgError:
            dy = -g
        dec = -float(g @ dy)
        if dec <= 1e-14 * f:
            break
        dS = GZ @ dy
        t = 1.0
        for _ in range(40):
            fc = value(S + t * dS)
            if fc <= f - 0.25 * t * dec:
                break
            t *= 0.5
        else:
            break
        nuh = nuh + t * (Z @ dy)
        S = S + t * dS
        f = fc
    if V is not None:
        nuh = V @ nuh
    nu = nuh / s
    sq = np.sqrt(S * S + eps * eps)
    mu = float(W @ (S * S / sq))
    last = np.arange(resp.m) * L + (L - 1)
    act = np.ones(resp.m) if active is None else np.asarray(active, float)
    dm = float((U * act) @ (sq[last] - eps[last])) + mu * float(nu @ resp.A_x(st.eAx))
    return nuh, f, dm, st


def smoothed_time(resp, x0, u_max, s, T_low: float, T_init: float, levels=SMOOTHING, nuh=None):
    """Co-state direction (scaled) and time near the optimum from smoothed duals (bracketed Newton on ``T``)."""
    T = max(T_init, T_low, 1e-300)
    for eps in levels:
        lo, hi = T_low, math.inf
        # the smoothing itself moves the root by about eps: solving m(T) = 1 much closer is wasted work
        tol = min(1e-2, max(1e-4, eps))
        for _ in range(14):
            nuh, mval, dm, _ = inner_smooth(resp, x0, u_max, s, T, nuh, eps)
            if mval > 0.0 and abs(math.log(mval)) < tol:
                break
            T, lo, hi = bracketed_step(T, mval, dm, lo, hi)
    return nuh, T


# ----------------------------------------------------------- independent bound
@dataclass(frozen=True, kw_only=True)
class DualityBound:
    """``nu^T w(T) - h_T(nu)`` evaluated independently.

    Attributes
    ----------
    value : float
        ``nu^T w(T)`` with ``w = -e^{A T} x0`` (scipy ``expm``).
    support : float
        ``h_T(nu) = sum_i u_max_i int_0^T |nu^T e^{A tau} B_i|`` from augmented
        exponentials between the proved zeros of each ``S_i``.
    unproved : int
        Root-isolation cells not proved (0: the integral is exact to rounding).
    """

    value: float
    support: float
    unproved: int

    @property
    def margin(self) -> float:
        """``(value - support) / (|value| + support)``: > 0 proves infeasibility at ``T``."""
        return (self.value - self.support) / max(abs(self.value) + self.support, 1e-300)

    @property
    def ratio(self) -> float:
        """``value / support``: a lower bound on the peak fraction of any input arriving at ``T``."""
        return self.value / self.support if self.support > 0.0 else math.inf


def duality_bound(
    resp: MultiResponse,
    A: np.ndarray,
    B: np.ndarray,
    x0: np.ndarray,
    u_max: np.ndarray,
    nu: np.ndarray,
    T: float,
    proved_roots: list | None = None,
    inputs=None,
    w: np.ndarray | None = None,
) -> DualityBound:
    """Weak-duality figures of ``nu`` at ``T`` (see :class:`DualityBound`); ``A, B`` the full reduced system.

    ``proved_roots``: per input, every sign change of ``S_i`` on ``[0, T']``,
    ``T' >= T``, isolated with proof (e.g. by the certificate); otherwise
    they are isolated here.  ``inputs``: only these inputs' support functions
    (default all); ``w``: the state to reach (unscaled) instead of ``-e^{A T} x0``.
    """
    cuts = [0.0, float(T)]
    per_input = []
    unproved = 0
    for i in range(resp.m):
        if inputs is not None and i not in inputs:
            per_input.append(None)
            continue
        if proved_roots is not None:
            roots = np.asarray(proved_roots[i], float)
        else:
            iso = isolate_roots(resp.for_input(i), nu, T)
            unproved += iso.unproved
            roots = iso.roots
        r = roots[(roots > 0.0) & (roots < T)]
        per_input.append(r)
        cuts.extend(r.tolist())
    cuts_arr = np.unique(np.asarray(cuts))
    gam = {float(t): input_integral(A, B, t) for t in cuts_arr}
    support = 0.0
    for i, r in enumerate(per_input):
        if r is None:
            continue
        pts = np.concatenate([[0.0], r, [T]])
        acc = 0.0
        for a, b in zip(pts[:-1], pts[1:]):
            acc += abs(float(nu @ (gam[float(b)][:, i] - gam[float(a)][:, i])))
        support += float(u_max[i]) * acc
    value = float(nu @ (-(expm(A * T) @ x0) if w is None else np.asarray(w, float)))
    return DualityBound(value=value, support=support, unproved=unproved)
