"""The least-peak linear program of a zero-order-hold move at ``K`` samples, and its weak-duality bound.

``t*(K) = min t  s.t.  sum_m g_m u_m = w_K, |u_m| <= t`` (``g_m``: the state
change of a unit sample ``m`` samples before the end, :func:`grid_sample_vectors`),
solved with some samples fixed at ``signs * t`` and the rest free
(:func:`window_mask`: windows around the sign changes of the switching
function), and the bound ``nu^T w / sum_m |nu^T g_m|`` any ``nu`` proves
(:func:`dual_bound`).  The planners that search the sample count
(:mod:`.zoh`, :mod:`.robust`, :mod:`.fixed_time`) call these.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import sparse

from ..linear_program import LpMethod, LpStatus, solve_lp
from ..simulation.modal_response import ModalResponse
from ..simulation.sample_grid import expm_x_grid
from .lp_tools import sample_vectors


def grid_sample_vectors(system, K: int, dt: float) -> np.ndarray:
    """:func:`~.lp_tools.sample_vectors` by complex power products on the grid for a :class:`ModalResponse`.

    The same vectors to a few ulp of each column's size (tested against
    ``sample_vectors``), 2.5-3x faster at ``K = 5000``
    (:func:`~flexmotion_ros.core.simulation.sample_grid.expm_x_grid`); any
    other system (the robust augmented one) through its own ``expm_x_many``.
    """
    if not isinstance(system, ModalResponse):
        return sample_vectors(system, K, dt)
    gam = system.input_integral(np.array([dt]))[0]
    return expm_x_grid(system, dt, K, gam)


def window_mask(S: np.ndarray, width: int) -> np.ndarray:
    """Samples within ``width`` of a sign change of ``S`` (and the first/last ``width``)."""
    K = S.size
    free = np.zeros(K, dtype=bool)
    change = np.flatnonzero(np.sign(S[1:]) != np.sign(S[:-1]))
    for c in change:
        free[max(0, c - width + 1) : min(K, c + width + 1)] = True
    free[:width] = True  # the first samples before arrival absorb the end effects
    free[K - width :] = True
    return free


#: The unpresolved dual simplex of :func:`solve_peak_lp` stops after ``PEAK_LP_ITERATIONS + 2 columns``
#: iterations (then HiGHS's presolve decides).
PEAK_LP_ITERATIONS = 1000


def peak_lp_iterations(columns: int) -> int:
    """The iteration limit of :func:`solve_peak_lp`'s first (unpresolved) solve with ``columns`` free samples."""
    return PEAK_LP_ITERATIONS + 2 * int(columns)


def solve_peak_lp(G: np.ndarray, w: np.ndarray, signs: np.ndarray, free: np.ndarray):
    """``min t`` with samples outside ``free`` fixed at ``signs * t``.  Returns ``(u, t, nu)`` or None.

    Solved in the scaled form ``u = v / s``: ``max s  s.t.  G_F^T v_F - s w =
    -sum_fixed signs_m g_m,  |v_F| <= 1,  s >= 0``, so ``t* = 1 / s*``.  The
    peak bounds are plain variable bounds (no ``2 |F|`` inequality rows), which
    makes a full-horizon LP ~10x cheaper.  The equality multipliers ``y`` of this
    form are ``nu / t*`` (``nu``: those of the ``min t`` form, ``y^T w = s*``),
    so ``nu = t* y``.  ``s* = 0`` (no finite peak reaches ``w``) and an
    infeasible LP both return None, as the ``min t`` form's infeasibility would;
    ``w = 0`` (``t* = 0``, nothing to scale) uses the ``min t`` form itself.
    """
    if not np.any(w):  # t* = 0: the scaled form has no s to maximise
        return _solve_peak_lp_rows(G, w, signs, free)
    F = np.flatnonzero(free)
    nF = F.size
    c_fix = np.where(free, 0.0, signs) @ G  # one product, no K x n copy of the fixed rows
    A_eq = np.column_stack([G[F].T, -w])
    b_eq = -c_fix
    # equilibrate the rows (one per state): HiGHS's feasibility tolerance is
    # absolute, and a row of 1e-12 (u_max 1e12: every sample moves a state by
    # far more than the move) would be met by any point.  Row scaling leaves
    # the solution unchanged; the multipliers scale back below.
    rows = np.maximum(np.max(np.abs(A_eq), axis=1), np.abs(b_eq))
    rows = np.where(rows > 0.0, rows, 1.0)
    A_eq = A_eq / rows[:, None]  # dense: the backend builds its compressed columns without scipy.sparse
    b_eq = b_eq / rows
    cost = np.zeros(nF + 1)
    cost[-1] = -1.0
    lower = np.full(nF + 1, -1.0)
    upper = np.ones(nF + 1)
    lower[nF] = 0.0
    upper[nF] = np.inf
    # n dense rows and box bounds: HiGHS's presolve finds nothing to remove and
    # costs ~30 % of the solve; it runs only if the dual simplex alone reports
    # a numerical difficulty
    # ... and an iteration limit: on a long move's wide windows (columns of 1e-7 to 1 after the row scaling)
    # the unpresolved dual simplex crawled (6099 columns: 84,455 iterations, 8 s; presolved: 305, 0.2 s)
    lp = dict(cost=cost, A_eq=A_eq, b_eq=b_eq, lower=lower, upper=upper)
    res = solve_lp(**lp, method=LpMethod.DUAL_SIMPLEX, presolve=False, iteration_limit=peak_lp_iterations(nF))
    if res.status in (LpStatus.OTHER, LpStatus.TIME_LIMIT):
        res = solve_lp(**lp)
    if res.status is LpStatus.UNBOUNDED:  # unbounded s (t* = 0 numerically): the min-t form decides
        return _solve_peak_lp_rows(G, w, signs, free)
    if res.status is not LpStatus.OPTIMAL:
        return None
    s_star = float(res.x[-1])
    if not s_star > 0.0:
        return None
    t = 1.0 / s_star
    u = signs * t
    u[F] = res.x[:nF] * t
    return u, t, t * res.eq_marginals / rows


def _solve_peak_lp_rows(G: np.ndarray, w: np.ndarray, signs: np.ndarray, free: np.ndarray):
    """:func:`solve_peak_lp` in the direct ``min t`` form with ``2 |F|`` rows ``|u_f| <= t``.

    Only for ``w = 0`` (``t* = 0``), where the scaled form has nothing to maximise.
    """
    F = np.flatnonzero(free)
    fixed = ~free
    nF = F.size
    c_fix = (G[fixed] * signs[fixed, None]).sum(axis=0)
    A_eq = np.column_stack([G[F].T, c_fix])
    cost = np.zeros(nF + 1)
    cost[-1] = 1.0
    # -t <= u_f <= t, sparse: over a full horizon a dense matrix would be O(K^2)
    rows = np.concatenate([np.arange(2 * nF), np.arange(2 * nF)])
    cols = np.concatenate([np.arange(nF), np.arange(nF), np.full(2 * nF, nF)])
    vals = np.concatenate([np.ones(nF), -np.ones(nF), -np.ones(2 * nF)])
    A_ub = sparse.csr_matrix((vals, (rows, cols)), shape=(2 * nF, nF + 1))
    lower = np.full(nF + 1, -np.inf)
    lower[nF] = 0.0
    res = solve_lp(cost=cost, A_ub=A_ub, b_ub=np.zeros(2 * nF), A_eq=A_eq, b_eq=w, lower=lower, upper=np.inf)
    if res.status is not LpStatus.OPTIMAL:
        return None
    t = float(res.x[-1])
    u = signs * t
    u[F] = res.x[:nF]
    return u, t, res.eq_marginals


def dual_bound(G: np.ndarray, w: np.ndarray, nu: np.ndarray) -> float:
    """Weak-duality lower bound on the peak command needed (any ``nu``)."""
    denom = float(np.sum(np.abs(G @ nu)))
    return float(nu @ w) / denom if denom > 0.0 else -math.inf
