"""Certificate of a sampled friction move with stick arcs: the discrete-time Pontryagin conditions, by LP duality.

A sampled move (zero-order hold, period ``dt``, ``K`` samples) under rigid-body
Coulomb friction is linear once its velocity-sign pattern is fixed
(:mod:`.sampled_lp`): on a sliding sample the friction is the known force
``-F s_k``, on a stuck sample (a stick arc, ``s_k = 0``) the body is held
(``v = 0`` at both ends, ``|u_k| <= F``) and only the modes feel ``u_k``.
For that pattern the least-peak problem is the linear program

    min t   s.t.   |u_k| <= t,   G^T u = w (rest at the target),
                   s v_j >= 0 at every instant (v_j = 0 where the pattern changes or sticks),
                   |u_k| <= F on stuck samples,

with ``v_j = a_j + D_j u`` (the exact velocity recursion).  Its dual is the
discrete-time maximum principle: ``lambda`` (the arrival rows' multipliers) is
the costate ``lambda(T)``, ``G lambda`` the switching function of every
sample, the multipliers of the velocity rows are the costate jumps where the
body rests or reverses (the stick arc as a boundary arc of ``s v >= 0``) and
those of the stick rows price the friction band.

:func:`certify_sampled` builds this LP from the returned commands' pattern
independently of the planner's scaled LP, asks HiGHS for a dual, and then
*checks* it in numpy: any multipliers with the right signs give the rigorous
lower bound ``D / (1 + rho)`` on the least peak (``D`` the dual objective,
``rho`` the l1 norm of the stationarity residual, since ``|u_k| <= t``), so
HiGHS is not trusted.  The move passes if it satisfies every row of the LP
and its peak is within :data:`PEAK_RTOL` of that bound.

What is proved (:data:`SAMPLED_PATTERN_CLAIM`): no ``K``-sample sequence at
this period with the same velocity-sign/stick pattern has a peak smaller by
more than :data:`PEAK_RTOL` (relative).
Not proved: that the pattern or the count ``K`` is the best (both are
searched), nor anything about the continuous-time optimum.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix, csr_matrix, vstack

from ..linear_program import LpMethod, LpStatus, solve_lp
from .sampled_lp import FrictionLP, lp_iteration_limit

#: The move's peak may exceed the proved lower bound on the least peak by this (relative): the returned
#: commands are the LP's, corrected (least norm) to land exactly, which moves the peak by up to ~2e-5 of
#: itself (seed-18 fuzz cases 45, 51, 92, 149: 2e-6 - 1.8e-5); the claim says "to within" this.
PEAK_RTOL = 1e-4
#: A row of the pattern's LP holds if violated by at most this (relative to the row's scale).
ROW_RTOL = 1e-7
#: Sampled moves with more samples are not certified (the LP's dense velocity rows grow as ``K^2``).
MAX_SAMPLES = 1500
#: What a passed sampled certificate claims.
SAMPLED_PATTERN_CLAIM = (
    "discrete-time Pontryagin conditions of the sampled friction move for its velocity-sign/stick pattern "
    "(LP duality, the dual checked in numpy): no sequence of the same number of samples at this period with "
    "this pattern (sliding signs, stick arcs held with |u| <= F) has a peak smaller by more than 1e-4 of it; the "
    "pattern and the "
    "count are searched, not proved; no continuous-time optimality is claimed; lower_bound_s is a proved bound"
)


@dataclass(frozen=True, kw_only=True)
class PatternCertificate:
    """Outcome of :func:`certify_sampled`.

    Attributes
    ----------
    passed : bool
        The move satisfies its pattern's LP and its peak is the least (within :data:`PEAK_RTOL`).
    peak : float
        ``max |u_k|`` of the move (N).
    peak_lower_bound : float
        Proved lower bound on the least peak of the pattern at ``K`` samples (N); 0 if none.
    row_violation : float
        Largest relative violation of the pattern's rows by the move.
    stuck_samples : int
        Samples of the pattern where the body is held (stick arcs).
    costate_final : ndarray
        The arrival rows' multipliers (the discrete costate ``lambda(T)`` on the constrained states).
    message : str
        ``"ok"`` or why it failed.
    """

    passed: bool
    peak: float
    peak_lower_bound: float
    row_violation: float
    stuck_samples: int
    costate_final: np.ndarray
    message: str


def pattern_rows(lp: FrictionLP, pattern: np.ndarray):
    """The pattern's LP in the variables ``z = (u_0..u_{K-1}, t)``.

    Returns ``(A_ub, b_ub, A_eq, b_eq, n_arrival)``: ``A_ub z <= b_ub`` (peak rows, sign rows, stick
    rows), ``A_eq z = b_eq`` (arrival first, then the velocities held at zero).
    """
    s = np.asarray(pattern, float)
    K = s.size
    G, Hf, free, pw = lp.kdata(K)
    stuck = s == 0.0
    G = lp.stuck_rows(G, stuck)
    w = -free + lp.F * (s @ Hf)
    nI = G.shape[1]
    # v_j = a_j + D_j u (j = 1..K): a from the start and the pattern's friction, D the drive (none when stuck)
    a = lp.velocities(np.zeros(K), s)
    j = np.arange(1, K + 1)
    lag = j[:, None] - 1 - np.arange(K)[None, :]
    D = np.where(lag >= 0, lp.gv * pw[np.maximum(lag, 0)], 0.0)
    D[:, stuck] = 0.0
    left, right = s, np.append(s[1:], 0.0 if stuck[-1] else s[-1])
    # instant j (1..K) lies between interval j-1 (left) and j (right); the end keeps the last sign unless stuck
    pos = (left[:K] > 0) & (right > 0)
    neg = (left[:K] < 0) & (right < 0)
    zero = ~(pos | neg)
    ones = np.ones(K)
    eye = csr_matrix((ones, (np.arange(K), np.arange(K))), shape=(K, K + 1))
    tcol = csr_matrix((np.ones(K), (np.arange(K), np.full(K, K))), shape=(K, K + 1))
    ub_blocks = [eye - tcol, -eye - tcol]  # u_k - t <= 0, -u_k - t <= 0
    ub_rhs = [np.zeros(K), np.zeros(K)]
    rows_ineq = np.flatnonzero(pos | neg)
    if rows_ineq.size:
        sig = np.where(pos[rows_ineq], 1.0, -1.0)  # -sig v_j <= 0
        Dj = -sig[:, None] * D[rows_ineq]
        ub_blocks.append(csr_matrix(np.column_stack([Dj, np.zeros(rows_ineq.size)])))
        ub_rhs.append(sig * a[1:][rows_ineq])
    ks = np.flatnonzero(stuck)
    if ks.size:  # |u_k| <= F on stuck samples
        n_s = ks.size
        S = coo_matrix((np.ones(n_s), (np.arange(n_s), ks)), shape=(n_s, K + 1)).tocsr()
        ub_blocks += [S, -S]
        ub_rhs += [np.full(n_s, lp.F), np.full(n_s, lp.F)]
    rows_eq = np.flatnonzero(zero)
    eq_blocks = [csr_matrix(np.column_stack([G.T, np.zeros(nI)]))]
    eq_rhs = [w]
    if rows_eq.size:
        eq_blocks.append(csr_matrix(np.column_stack([D[rows_eq], np.zeros(rows_eq.size)])))
        eq_rhs.append(-a[1:][rows_eq])
    return vstack(ub_blocks).tocsr(), np.concatenate(ub_rhs), vstack(eq_blocks).tocsr(), np.concatenate(eq_rhs), nI


def certify_sampled(lp: FrictionLP, pattern: np.ndarray, u: np.ndarray) -> PatternCertificate:
    """Check that ``u`` (``K`` samples at ``lp.dt``) is the least-peak sequence of its pattern (module notes).

    Parameters
    ----------
    lp : FrictionLP
        Problem, friction force (N) and sample period (s).
    pattern : ndarray
        Velocity sign on every sample (+1, -1; 0 where the body is held).
    u : ndarray
        The commands (N).
    """
    s = np.asarray(pattern, float)
    u = np.asarray(u, float)
    K = u.size
    stuck = int(np.count_nonzero(s == 0.0))
    none = np.zeros(0)
    peak = float(np.max(np.abs(u))) if K else 0.0
    if K == 0 or s.size != K:
        return PatternCertificate(
            passed=False, peak=peak, peak_lower_bound=0.0, row_violation=np.inf, stuck_samples=stuck,
            costate_final=none, message="no samples, or a pattern of another length",
        )  # fmt: skip
    if K > MAX_SAMPLES:
        return PatternCertificate(
            passed=False, peak=peak, peak_lower_bound=0.0, row_violation=np.inf, stuck_samples=stuck,
            costate_final=none, message=f"not attempted: {K} samples (more than {MAX_SAMPLES})",
        )  # fmt: skip
    A_ub, b_ub, A_eq, b_eq, nI = pattern_rows(lp, s)
    z = np.append(u, peak)
    # 1. the move satisfies its pattern's rows (each relative to its own scale)
    viol_ub = A_ub @ z - b_ub
    viol_eq = np.abs(A_eq @ z - b_eq)
    sc_ub = np.abs(A_ub) @ np.abs(z) + np.abs(b_ub) + 1e-300
    sc_eq = np.abs(A_eq) @ np.abs(z) + np.abs(b_eq) + 1e-300
    row_violation = float(max(np.max(viol_ub / sc_ub, initial=0.0), np.max(viol_eq / sc_eq, initial=0.0)))
    # 2. a dual (HiGHS's, not trusted): rows only, so every multiplier is a row dual
    cost = np.zeros(K + 1)
    cost[K] = 1.0
    res = solve_lp(
        cost=cost,
        A_ub=A_ub,
        b_ub=b_ub,
        A_eq=A_eq,
        b_eq=b_eq,
        lower=np.full(K + 1, -np.inf),
        upper=np.full(K + 1, np.inf),
        method=LpMethod.DUAL_SIMPLEX,
        iteration_limit=lp_iteration_limit(K + 1, A_ub.shape[0] + A_eq.shape[0]),  # work, not wall time
        presolve=False,
        primal_feasibility_tolerance=1e-10,
        dual_feasibility_tolerance=1e-10,
    )
    lb = 0.0
    lam = none
    if res.status is LpStatus.OPTIMAL and res.ub_marginals is not None and res.eq_marginals is not None:
        # 3. the bound, checked: p >= 0 (clipped), r = c + A_ub^T p + A_eq^T q; for any feasible (u, t) with
        #    |u_k| <= t: t >= -(p b_ub + q b_eq) + r.z >= D - rho t, so t >= D / (1 + rho)
        p = np.maximum(-np.asarray(res.ub_marginals, float), 0.0)
        q = -np.asarray(res.eq_marginals, float)
        r = cost + A_ub.T @ p + A_eq.T @ q
        # r is itself rounded: add a bound on the rounding of each of its entries (K + 1 terms of each row sum)
        rounding = 1e-15 * (K + 1) * (1.0 + np.abs(A_ub.T) @ p + np.abs(A_eq.T) @ np.abs(q))
        rho = float(np.sum(np.abs(r) + rounding))
        dual = -float(p @ b_ub) - float(q @ b_eq)
        sums = float(np.abs(p) @ np.abs(b_ub) + np.abs(q) @ np.abs(b_eq))
        dual -= 1e-14 * K * sums  # rounding of the sums themselves
        lb = max(dual / (1.0 + rho), 0.0)
        lam = q[:nI]
    reasons = []
    if not row_violation <= ROW_RTOL:
        reasons.append(f"the move breaks its pattern's rows (relative violation {row_violation:.2e})")
    if not (lb > 0.0 and peak <= lb * (1.0 + PEAK_RTOL)):
        reasons.append(f"peak {peak:.9g} N not proved least (proved bound {lb:.9g} N; LP {res.status.value})")
    return PatternCertificate(
        passed=not reasons,
        peak=peak,
        peak_lower_bound=lb,
        row_violation=row_violation,
        stuck_samples=stuck,
        costate_final=lam,
        message="; ".join(reasons) or "ok",
    )
