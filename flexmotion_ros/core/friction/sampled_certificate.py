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
independently of the planner's scaled LP, asks HiGHS for a dual (of the same
LP in scaled chain form, sparse: :func:`scaled_duals`; of the dense rows if
those multipliers fall short), and then *checks* it in numpy on the dense rows: any multipliers with the right signs give the rigorous
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
from .lp_work import lp_iteration_limit
from .sampled_lp import FrictionLP

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


def dense_duals(lp: FrictionLP, s: np.ndarray, A_ub, b_ub, A_eq, b_eq, nI: int):
    """``(status, (p, q))``: HiGHS's multipliers of the pattern's dense rows (:func:`pattern_rows`) in the sign
    convention of the check (``p`` on ``A_ub``, ``q`` on ``A_eq``); ``(status, None)`` without an optimum."""
    n = A_ub.shape[1]
    cost = np.zeros(n)
    cost[-1] = 1.0
    res = solve_lp(
        cost=cost,
        A_ub=A_ub,
        b_ub=b_ub,
        A_eq=A_eq,
        b_eq=b_eq,
        lower=np.full(n, -np.inf),
        upper=np.full(n, np.inf),
        method=LpMethod.DUAL_SIMPLEX,
        iteration_limit=lp_iteration_limit(n, A_ub.shape[0] + A_eq.shape[0]),  # work, not wall time
        presolve=False,
        primal_feasibility_tolerance=1e-10,
        dual_feasibility_tolerance=1e-10,
    )
    if res.status is not LpStatus.OPTIMAL or res.ub_marginals is None or res.eq_marginals is None:
        return res.status, None
    return res.status, (-np.asarray(res.ub_marginals, float), -np.asarray(res.eq_marginals, float))


def scaled_duals(lp: FrictionLP, s: np.ndarray, A_ub, b_ub, A_eq, b_eq, nI: int):
    """As :func:`dense_duals`, from the pattern's LP in scaled chain form (a fraction of the dense solve).

    The same LP divided by the peak: ``u = t z`` with ``|z_k| <= 1`` as bounds, ``mu = 1 / t`` maximised,
    the velocities ``y_j = mu v_j`` as variables defined by their recursion (``y_{j+1} = ev y_j + gv z_j +
    mu (a_{j+1} - ev a_j)``, ``a`` the velocity without command; no drive on a stuck sample), their signs
    as bounds, ``|z_k| <= F mu`` on stuck samples.  Its stationarity in ``z`` is that of the dense LP in
    ``u`` (the velocity rows' multipliers are the reduced costs of ``y``, the peak rows' those of ``z``), up
    to one factor fixed by the dense LP's stationarity in ``t``, ``sum p_peak = 1``.  Only a source of
    multipliers: the bound is the dense rows' check.
    """
    K = s.size
    stuck = s == 0.0
    a = lp.velocities(np.zeros(K), s)
    left, right = s, np.append(s[1:], 0.0 if stuck[-1] else s[-1])
    pos = (left[:K] > 0) & (right > 0)
    neg = (left[:K] < 0) & (right < 0)
    rows_ineq = np.flatnonzero(pos | neg)
    rows_eq = np.flatnonzero(~(pos | neg))
    ks = np.flatnonzero(stuck)
    n_s = ks.size
    if A_ub.shape[0] != 2 * K + rows_ineq.size + 2 * n_s or A_eq.shape[0] != nI + rows_eq.size:
        return LpStatus.OTHER, None  # not the rows this form mirrors (never seen): the dense solve then
    n = 2 * K + 1
    iy, imu = K, 2 * K  # columns: z_0..z_{K-1}, y_1..y_K, mu
    G = A_eq[:nI, :K].toarray()  # the arrival rows G^T u = w of the dense form
    w = b_eq[:nI]
    k = np.arange(K)
    e = a[1:] - lp.ev * a[:-1]
    e[0] = a[1]  # y_0 = mu a_0 is no variable: its term joins the constant
    # equality rows: arrival G^T z - mu w = 0, then chain y_{k+1} - ev y_k - gv z_k - mu e_k = 0
    rows = [np.repeat(np.arange(nI), K), nI + k, nI + k[1:], nI + k, np.arange(nI), nI + k]
    cols = [np.tile(k, nI), iy + k, iy + k[1:] - 1, k, np.full(nI, imu), np.full(K, imu)]
    vals = [G.ravel(), np.ones(K), np.full(K - 1, -lp.ev), np.where(stuck, 0.0, -lp.gv), -w, -e]
    eq = coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(nI + K, n))
    ub = None
    if n_s:  # held by friction: |z_k| <= F mu
        r2 = np.concatenate([np.arange(2 * n_s), np.arange(2 * n_s)])
        c2 = np.concatenate([ks, ks, np.full(2 * n_s, imu)])
        v2 = np.concatenate([np.ones(n_s), -np.ones(n_s), np.full(2 * n_s, -lp.F)])
        ub = coo_matrix((v2, (r2, c2)), shape=(2 * n_s, n)).tocsr()
    lo = np.full(n, -np.inf)
    hi = np.full(n, np.inf)
    lo[:K], hi[:K] = -1.0, 1.0
    lo[iy:imu] = np.where(neg, -np.inf, 0.0)
    hi[iy:imu] = np.where(pos, np.inf, 0.0)
    lo[imu] = 0.0
    cost = np.zeros(n)
    cost[imu] = -1.0
    eq = eq.tocsr()
    res = solve_lp(
        cost=cost,
        A_ub=ub,
        b_ub=None if ub is None else np.zeros(2 * n_s),
        A_eq=eq,
        b_eq=np.zeros(nI + K),
        lower=lo,
        upper=hi,
        method=LpMethod.DUAL_SIMPLEX,
        iteration_limit=lp_iteration_limit(n, nI + K + 2 * n_s),  # work, not wall time
        presolve=False,
        primal_feasibility_tolerance=1e-10,
        dual_feasibility_tolerance=1e-10,
    )
    if res.status is not LpStatus.OPTIMAL or res.eq_marginals is None or res.x[imu] <= 0.0:
        return res.status, None
    y_eq = np.asarray(res.eq_marginals, float)
    y_ub = np.zeros(0) if ub is None else np.asarray(res.ub_marginals, float)
    d = cost - eq.T @ y_eq - (ub.T @ y_ub if ub is not None else 0.0)  # reduced costs: the bounds' multipliers
    dz, dy = d[:K], d[iy:imu]
    peak = np.concatenate([np.maximum(-dz, 0.0), np.maximum(dz, 0.0)])  # z_k = 1, z_k = -1
    total = float(np.sum(peak))
    if not total > 0.0:
        return LpStatus.OTHER, None
    sig = np.where(pos[rows_ineq], 1.0, -1.0)
    p = np.concatenate([peak, sig * dy[rows_ineq], -y_ub]) / total
    q = np.concatenate([-y_eq[:nI], -dy[rows_eq]]) / total
    return res.status, (p, q)


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
    # 2. a dual (HiGHS's, not trusted), first from the pattern's LP in scaled chain form (the dense rows'
    #    solve took 20-30 ms at 190 samples, most of a median plan's certificate), then, if those multipliers
    #    do not prove the peak, from the dense rows themselves; either way the bound is step 3's check
    cost = np.zeros(K + 1)
    cost[K] = 1.0
    lb = 0.0
    lam = none
    status = LpStatus.OTHER
    for duals in (scaled_duals, dense_duals):
        status, got = duals(lp, s, A_ub, b_ub, A_eq, b_eq, nI)
        if got is None:
            continue
        # 3. the bound, checked: p >= 0 (clipped), r = c + A_ub^T p + A_eq^T q; for any feasible (u, t) with
        #    |u_k| <= t: t >= -(p b_ub + q b_eq) + r.z >= D - rho t, so t >= D / (1 + rho)
        p = np.maximum(got[0], 0.0)
        q = got[1]
        r = cost + A_ub.T @ p + A_eq.T @ q
        # r is itself rounded: add a bound on the rounding of each of its entries (K + 1 terms of each row sum)
        rounding = 1e-15 * (K + 1) * (1.0 + np.abs(A_ub.T) @ p + np.abs(A_eq.T) @ np.abs(q))
        rho = float(np.sum(np.abs(r) + rounding))
        dual = -float(p @ b_ub) - float(q @ b_eq)
        sums = float(np.abs(p) @ np.abs(b_ub) + np.abs(q) @ np.abs(b_eq))
        dual -= 1e-14 * K * sums  # rounding of the sums themselves
        bound = max(dual / (1.0 + rho), 0.0)
        if bound > lb:
            lb, lam = bound, q[:nI]
        if lb > 0.0 and peak <= lb * (1.0 + PEAK_RTOL):
            break
    res_status = status
    reasons = []
    if not row_violation <= ROW_RTOL:
        reasons.append(f"the move breaks its pattern's rows (relative violation {row_violation:.2e})")
    if not (lb > 0.0 and peak <= lb * (1.0 + PEAK_RTOL)):
        reasons.append(f"peak {peak:.9g} N not proved least (proved bound {lb:.9g} N; LP {res_status.value})")
    return PatternCertificate(
        passed=not reasons,
        peak=peak,
        peak_lower_bound=lb,
        row_violation=row_violation,
        stuck_samples=stuck,
        costate_final=lam,
        message="; ".join(reasons) or "ok",
    )
