"""Weak duality for the limit LP: a lower bound on ``t*(K)`` from any multipliers, over ALL samples.

The scaled problem of :mod:`.limit_lp` (commands ``v = u / u_max``, every
limit row ``a_j^T v + d_j <= t``, arrival ``G^T v = w``, ``|v_m| <= t``)::

    t*(K) = min t   s.t.   G^T v = w,   a_j^T v + d_j <= t (all j),   |v_m| <= t (all m).

Derivation.  Take any ``nu`` (one per state) and any ``lambda_j >= 0`` and
put ``c = sum_j lambda_j a_j - G nu`` (one entry per sample).  For every
feasible ``(v, t)``:

* ``c^T v = sum_j lambda_j a_j^T v - nu^T w <= t sum_j lambda_j - lambda^T d - nu^T w``
  (the limit rows, ``lambda >= 0``; the arrival, exactly);
* ``c^T v >= -t ||c||_1`` (``|v_m| <= t``).

Hence ``t (||c||_1 + sum_j lambda_j) >= nu^T w + lambda^T d``, that is::

    t*(K) >= (nu^T w + lambda^T d) / (||c||_1 + sum_j lambda_j).

A ratio above 1 proves that no ``K``-sample sequence meets every limit (and,
since ``t*`` is non-increasing, no shorter one).  It holds for *any*
multipliers: those of a windowed LP (few free samples, runs sharing a level)
are evaluated here on every sample of the full problem, so the proof never
depends on the window being right, only its strength does.  ``c`` over all
samples costs ``O(n K log K)``: each multiplier of a state row acts on the
earlier commands through ``e^{A j dt} Gamma``, a correlation done by FFT.
Rounding in this evaluation is far below :data:`PROOF_RTOL`.

At an optimum ``v_m = -t sgn(c_m)`` wherever ``c_m != 0``; the per-sample
*loss* ``|c_m| + c_m v_m / t >= 0`` shows where a window solution's
multipliers disagree with the full problem (samples to free).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import fftconvolve

from ..sampled.sparse_rows import SparseRows
from ..tolerances import PROOF_RTOL
from .assembly import LimitRows
from .segments import CUT, SLEW, STATE, LPSolution


def dual_bound(lp: LimitRows, sol: LPSolution) -> tuple[float, np.ndarray]:
    """``(bound, loss)``: the weak-duality bound on ``t*(K)`` from ``sol``'s multipliers and the per-sample loss."""
    K = sol.K
    kd = lp.kdata(K)
    n = lp.sys.n
    um = lp.um
    gK = kd.g[K - 1 :: -1] * um / kd.sc  # arrival column of sample m: g_{K-1-m}
    num = float(sol.nu @ (kd.w / kd.sc))
    pi = np.zeros((K + 1, n))  # multipliers acting through the state at sample k
    direct = np.zeros(K + 1)  # multipliers acting on the command of sample k directly
    limit = {b.idx[0]: float(b.D[0]) for b in lp.blocks}
    rows = sol.rows
    lam = sol.lam
    on = lam > 0.0
    kind, k, idx, sgn = (rows[on, c] for c in range(4))
    k = k.astype(int)
    idx = idx.astype(int)
    ls = lam[on] * sgn
    st = kind == STATE
    if st.any():
        L = np.array([limit[i] for i in idx[st]])
        np.add.at(pi, (k[st], idx[st]), ls[st] / L)
        num += float(np.sum(ls[st] * kd.xf[k[st], idx[st]] / L))
    for j in np.flatnonzero(kind == CUT):
        mode = idx[j]
        Ps, Gs = lp.at(float(sol.s[on][j]), mode)
        ix = lp.sys.r + 2 * mode
        qm = float(lp.limits.deflection_max[mode])
        pi[k[j], ix : ix + 2] += ls[j] * Ps / qm
        direct[k[j]] += ls[j] * Gs * um / qm
        num += float(ls[j] * Ps @ kd.xf[k[j], ix : ix + 2] / qm)
    sw = kind == SLEW
    if sw.any():
        np.add.at(direct, k[sw], ls[sw] / lp.slew)  # + v_k
        np.add.at(direct, k[sw] - 1, -ls[sw] / lp.slew)  # - v_{k-1} (index -1 / K: the hold value 0)
    c = direct[:K] - gK @ sol.nu
    g = kd.g[:K]
    for e in range(n):
        a = pi[1 : K + 1, e]
        if np.any(a):  # sum_{k > m} pi_k . g_{k-1-m}: a correlation
            c += um * fftconvolve(a, g[::-1, e])[K - 1 : 2 * K - 1]
    den = float(np.sum(np.abs(c)) + np.sum(lam))
    bound = num / den if den > 0.0 else -np.inf
    v = sol.u / um
    loss = np.abs(c) + c * v / max(sol.t, 1e-300)
    return bound, loss


def proves_infeasible(bound: float) -> bool:
    """The bound proves ``t*(K) > 1`` (no ``K``-sample sequence meets the limits)."""
    return bound > 1.0 + PROOF_RTOL


# ------------------------------------------------------------------- lifting
#: A row (or command) within this (relative to ``t``) of its limit counts as active in :func:`lift`.
ACTIVE_RTOL = 1e-7
#: Weight of the pull towards the window LP's multipliers (only felt where the system leaves freedom).
REGULARISATION = 1e-6
LIFT_ROUNDS = 4
#: Pull (relative to the other rows) of the rows the window LP has towards its own multipliers.
OWN_WEIGHT = 1e8
#: ... in a second lift, when the first did not prove: none.  A window LP's runs share one level, so its
#: multipliers on a riding arc (rows inside a run) are those of a restriction; held near them, the lift
#: may stay away from the full problem's (the bench's 1 kHz deflection limit: bound 0.847 with the pull,
#: 0.992 without, neither proves).  On the seed-18 fuzz at 100 Hz (velocity limit) the second lift proves
#: 33 of the 36 counts the full feasibility LP and its confirmation proved, and 3 counts left unproved;
#: without the pull alone (no first lift) the bench's slew and all-three limits at 1 kHz lost their proofs.
RETRY_OWN_WEIGHT = 1.0


def lift(lp: LimitRows, sol: LPSolution, own_weight: float = OWN_WEIGHT) -> LPSolution:
    """Multipliers for the FULL problem from a window solution's primal (the full KKT system).

    A window LP shares one level over a run; its own multipliers only make
    the run's *sum* of ``c_m`` vanish, not each ``c_m``.  If the window
    solution is optimal for the full problem, full multipliers exist with
    ``c_m = 0`` on every interior sample and ``lambda_j = 0`` on every
    inactive row.  They solve a sparse linear system: the adjoint recursion
    ``psi_{m-1} = Phi^T psi_m + pi_m(lambda)``, ``psi_{K-1} = -nu``,
    ``c_m = u_max Gamma^T psi_m + direct_m(lambda)``, with one component of
    ``psi_{K-1}`` fixed from the window's ``nu`` (the scale): a sparse LU of
    the (regularised) least-squares system, ``O(n K)``, repeated up to
    :data:`LIFT_ROUNDS` times with negative multipliers pinned to zero.
    :func:`dual_bound` then decides what the result proves.  ``own_weight``: the pull of the rows the
    window LP has towards its multipliers (:data:`OWN_WEIGHT`, :data:`RETRY_OWN_WEIGHT`).
    """
    K, um, t = sol.K, lp.um, sol.t
    kd = lp.kdata(K)
    n = lp.sys.n
    v = sol.u / um
    Phi = np.column_stack([lp.sys.expm_x(lp.dt, e) for e in np.eye(n)])
    Gam = kd.g[0] * um
    thr = t * (1.0 - ACTIVE_RTOL)
    # active rows: (kind, k, index, sign), cut offsets, coefficient vector on psi-sources, direct terms
    rows, svals = [], []
    # rows of the window LP with a zero multiplier stay zero (a degenerate vertex has active rows it does not need)
    lp_rows: dict = {}
    for (kind, k, idx, _), lam_ in zip(sol.rows, sol.lam):
        key = (int(kind), int(k), int(idx))
        lp_rows[key] = max(lp_rows.get(key, 0.0), lam_)
    dead = {key for key, val in lp_rows.items() if val == 0.0}
    for b, x in zip(lp.blocks, lp.block_states(K, sol.u)):
        ks = np.flatnonzero(np.abs(x[1:K]) >= thr) + 1
        ks = np.array([k for k in ks if (STATE, k, b.idx[0]) not in dead], int)
        rows += [(STATE, k, b.idx[0], np.sign(x[k])) for k in ks]
        svals += [0.0] * ks.size
    if lp.slew is not None:
        step = np.diff(np.concatenate([[0.0], v, [0.0]])) / lp.slew
        ks = np.flatnonzero(np.abs(step) >= thr)
        rows += [(SLEW, k, 0, np.sign(step[k])) for k in ks]
        svals += [0.0] * ks.size
    if lp.cuts:
        states = _response_states(lp, K, sol.u)
        for c in lp.cuts:
            if c.k >= K:
                continue
            Ps, Gs = lp.at(c.s, c.mode)
            ix = lp.sys.r + 2 * c.mode
            qm = float(lp.limits.deflection_max[c.mode])
            q = (Ps @ states[c.k, ix : ix + 2] + Gs * sol.u[c.k]) / qm
            if abs(q) >= thr:
                rows.append((CUT, c.k, c.mode, np.sign(q)))
                svals.append(c.s)
    J = len(rows)
    interior = np.flatnonzero(np.abs(v) < thr)
    # unknowns: psi (K x n, psi_{K-1} = -nu / sc) | lambda (J); each with a time stamp for a banded order
    ol = n * K
    eq = SparseRows()
    # psi_{m-1} - Phi^T psi_m - pi_m(lambda) = 0, vectorised over m
    m = np.arange(1, K)
    for e in range(n):
        cols = [(m - 1) * n + e] + [m * n + f for f in range(n) if Phi[f, e] != 0.0]
        vals = [np.ones(m.size)] + [np.full(m.size, -Phi[f, e]) for f in range(n) if Phi[f, e] != 0.0]
        eq.add_many(np.column_stack(cols), np.column_stack(vals), s=m - 0.5)
    rec0 = 0  # row of (m, e) is e * (K - 1) + (m - 1)
    direct: dict[int, list] = {}
    limit = {b.idx[0]: float(b.D[0]) for b in lp.blocks}
    lam_stamp = np.zeros(J)
    for j, ((kind, k, idx, sgn), s_) in enumerate(zip(rows, svals)):
        col = ol + j
        lam_stamp[j] = k - 0.5
        if kind == STATE and 1 <= k <= K - 1:
            eq.entry(rec0 + idx * (K - 1) + (k - 1), col, -sgn / limit[idx])
        elif kind == CUT:
            Ps, Gs = lp.at(s_, idx)
            ix = lp.sys.r + 2 * idx
            qm = float(lp.limits.deflection_max[idx])
            if k >= 1:  # (sample 0's state is the initial one)
                for c in range(2):
                    eq.entry(rec0 + (ix + c) * (K - 1) + (k - 1), col, -sgn * Ps[c] / qm)
            direct.setdefault(k, []).append((col, sgn * Gs * um / qm))
        elif kind == SLEW:
            if k < K:
                direct.setdefault(k, []).append((col, sgn / lp.slew))
            if k >= 1:
                direct.setdefault(k - 1, []).append((col, -sgn / lp.slew))
    # c_m = u_max Gamma^T psi_m + direct_m = 0 at every interior sample, scaled to a unit row; the
    # samples without direct terms (most of them) in one block (the rows are ordered by stamp below,
    # so the matrix is the same as row by row)
    has_direct = np.isin(interior, np.fromiter(direct, int, len(direct)))
    plain = interior[~has_direct]
    if plain.size:
        nrm = float(np.linalg.norm(Gam)) or 1.0
        eq.add_many(
            plain[:, None] * n + np.arange(n), np.broadcast_to(Gam / nrm, (plain.size, n)), s=plain.astype(float)
        )
    for mm in interior[has_direct]:
        cols = [mm * n + f for f in range(n)]
        vals = [Gam[f] for f in range(n)]
        for col, val in direct[int(mm)]:
            cols.append(col)
            vals.append(val)
        nrm = float(np.linalg.norm(vals)) or 1.0
        eq.add(cols, np.array(vals) / nrm, s=float(mm))
    # the scale: one component of psi_{K-1} = -nu / sc from the window solution's nu
    e_fix = int(np.argmax(np.abs(sol.nu)))
    if sol.nu[e_fix] == 0.0:
        return sol
    fix = (K - 1) * n + e_fix
    stamps = np.concatenate([np.repeat(np.arange(K, dtype=float), n), lam_stamp])
    # where the system leaves freedom (a degenerate vertex), stay near the window LP's multipliers
    y0 = np.zeros(ol + J)
    y0[(K - 1) * n : K * n] = -sol.nu / kd.sc
    own = {(int(a), int(b), int(c), int(d)): lam_ for (a, b, c, d), lam_ in zip(sol.rows, sol.lam)}
    reg = np.zeros(ol + J)
    for j, (kind, k, idx, sgn) in enumerate(rows):
        key = (int(kind), int(k), int(idx), int(sgn))
        y0[ol + j] = own.get(key, 0.0)
        reg[ol + j] = own_weight if key in own else 1.0
    reg[(K - 1) * n : K * n] = 1.0
    A = eq.matrix(ol + J)
    meta = np.array([[k_, kk, i_, s_] for k_, kk, i_, s_ in rows], float).reshape(-1, 4)
    best, best_bound = sol, -np.inf
    for _ in range(LIFT_ROUNDS):
        y = _least_squares(A, eq.rhs(), eq.s_array(), stamps, fix, -sol.nu[e_fix] / kd.sc[e_fix], reg, y0)
        if y is None:
            break
        lam = y[ol:]
        cand = LPSolution(
            K,
            sol.u,
            t,
            -y[(K - 1) * n : K * n] * kd.sc,
            meta,
            np.array(svals, float),
            np.maximum(lam, 0.0),
            sol.segments,
            sol.levels,
        )
        bound, _ = dual_bound(lp, cand)
        if bound > best_bound:
            best, best_bound = cand, bound
        if proves_infeasible(bound):
            break  # what the caller asks: another round could only raise a bound that already proves
        neg = lam < -1e-12 * max(float(np.max(np.abs(lam), initial=0.0)), 1e-300)
        if not neg.any():
            break
        # a multiplier must not be negative: pin those at zero and solve again (as in NNLS)
        reg[ol:][neg] = 1.0 / REGULARISATION**2
        y0[ol:][neg] = 0.0
    return best


def _response_states(lp: LimitRows, K: int, u: np.ndarray) -> np.ndarray:
    """States (response coordinates) at samples 0..K by the closed forms (FFT convolution)."""
    kd = lp.kdata(K)
    out = kd.xf.copy()
    for e in range(lp.sys.n):
        out[1:, e] += fftconvolve(u, kd.g[:K, e])[:K]
    return out


def _least_squares(A, b, row_stamp, col_stamp, fix: int, value: float, reg: np.ndarray, y0: np.ndarray):
    """``min |Ax - b|^2 + d^2 |x|^2`` with ``x[fix] = value``: one sparse LU of the augmented system.

    Rows and unknowns are interleaved in time order, so the augmented matrix
    is banded and its LU costs ``O(K)``.
    """
    from scipy import sparse
    from scipy.sparse.linalg import splu

    A = sparse.csc_matrix(A)
    keep = np.ones(A.shape[1], bool)
    keep[fix] = False
    b = b - A[:, fix].toarray().ravel() * value
    A = A[:, keep]
    m, k = A.shape
    D = REGULARISATION**2 * reg[keep]
    M = sparse.bmat([[sparse.identity(m), A], [A.T, -sparse.diags(D)]], format="csc")
    order = np.argsort(np.concatenate([row_stamp, col_stamp[keep]]), kind="stable")
    M = M[order][:, order]
    rhs = np.concatenate([b, -D * y0[keep]])[order]
    try:
        z = splu(M, permc_spec="NATURAL", diag_pivot_thresh=0.1).solve(rhs)
    except RuntimeError:
        return None
    out = np.empty(m + k)
    out[order] = z
    x = np.empty(keep.size)
    x[keep] = out[m:]
    x[fix] = value
    return x if np.all(np.isfinite(x)) else None
