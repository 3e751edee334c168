"""The rows of the limited planner's linear program: ``K`` samples, every limit, the exact arrival.

:class:`LimitRows` holds what one problem, rate and set of limits share (the
limited blocks, their closed forms per ``K``, the cuts) and assembles the
sparse LP of :mod:`.lp` for any ``K`` and :class:`~.segments.Segments`
(:meth:`LimitRows.assemble`): arrival rows, the chains of the limited states at
the knots, limit rows at the knots and (generated) inside runs, command bounds,
slew and total-variation rows, and the deflection between samples (cuts, and
in the smooth LP the middle of every free interval).  The normalised form and
the three uses of the LP are described in :mod:`.lp`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import GoalError
from ..model.boundary import MoveProblem
from ..sampled.sparse_rows import SparseRows
from ..simulation.modal_response import ModalResponse
from .limits import Cut, Limits
from .responses import Block, KData, block_states, deflection_row, limit_blocks
from .segments import COMMAND, CUT, SLEW, STATE, Lazy, Segments

#: Relative margin by which the accepted LP tightens every state and slew limit (absorbs the arrival correction).
MARGIN = 1e-7


@dataclass(frozen=True, kw_only=True)
class Assembled:
    """One assembled limit LP (HiGHS's input) and where its answer sits.

    Attributes
    ----------
    cost, A_ub, b_ub, A_eq, b_eq, lower, upper
        The LP ``min cost x`` s.t. ``A_ub x <= b_ub``, ``A_eq x = b_eq``, ``lower <= x <= upper``.
    free : numpy.ndarray
        Indices of the free samples.
    uvar : numpy.ndarray
        Column of each sample's command (``-1`` inside runs).
    lvar : numpy.ndarray
        Column of each run's level.
    n_arrival : int
        The arrival rows (the first equalities).
    row_scale : numpy.ndarray
        Scale of each arrival row (its multipliers are scaled back by it).
    meta, s : numpy.ndarray
        Kind, sample, index and sign of every inequality row (``-1`` kind: not a limit row), and the
        offset of cut rows within their interval (s).
    """

    cost: np.ndarray
    A_ub: object
    b_ub: np.ndarray
    A_eq: object
    b_eq: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    free: np.ndarray
    uvar: np.ndarray
    lvar: np.ndarray
    n_arrival: int
    row_scale: np.ndarray
    meta: np.ndarray
    s: np.ndarray
    #: The ``t`` columns (one per knot, first) and the total-variation columns (last).
    n_t: int = 0
    n_tv: int = 0


class LimitRows:
    """The rows of the limit LPs of one problem, rate and set of limits, for any ``K`` and :class:`Segments`."""

    def __init__(self, problem: MoveProblem, dt: float, limits: Limits) -> None:
        self.problem = problem
        self.dt = dt
        self.limits = limits
        self.um = problem.u_max
        self.model = problem.model
        self.sys = ModalResponse(problem.model, problem.include_position)
        self.x0 = problem.shifted_initial()
        self.blocks: list[Block] = limit_blocks(self.sys, limits, self.model.omega)
        self.slew = limits.slew_rate * dt / self.um if limits.slew_rate is not None else None
        self.cuts: list[Cut] = []
        self.solves = 0
        self.infeasible_verdicts = 0  # LPs HiGHS found infeasible
        self.infeasible_method = ""  # the HiGHS method that gave the last such verdict
        self.deadline = math.inf  # time.perf_counter() past which an LP stops (HiGHS time limit)
        self._kd: dict[int, KData] = {}
        self.run_rows: dict[int, list[set]] = {}  # samples inside runs with limit rows, per K and block (generated)
        self.coarse_rows: tuple[list[set], int] | None = None  # a coarser level's rows and count (seeds)
        # the last scaled solution at this rate and the coarser level's: (K, K dt, v / t, limited states / t)
        self.profile: tuple | None = None
        self.coarse_profile: tuple | None = None
        self._at_cache: dict = {}
        self._check_initial()

    def _check_initial(self) -> None:
        x = self.problem.x0
        if self.limits.velocity_max is not None and abs(x[1]) > self.limits.velocity_max:
            raise GoalError("initial_velocity", f"|{x[1]}| exceeds limits.velocity_max = {self.limits.velocity_max}")
        for b in self.blocks:
            if b.mode is not None and abs(x[2 + 2 * b.mode]) > b.D[0]:
                raise GoalError(
                    "initial_state",
                    f"mode {b.mode} deflection {x[2 + 2 * b.mode]} exceeds limits.deflection_max[{b.mode}] = {b.D[0]}",
                )

    def kdata(self, K: int) -> KData:
        """Closed forms at ``K`` samples (:class:`~flexmotion_ros.core.limit_responses.KData`; the last few cached)."""
        if K not in self._kd:
            if len(self._kd) >= 6:
                self._kd.pop(next(iter(self._kd)))
            self._kd[K] = KData(self.sys, self.dt, self.x0, self.um, self.blocks, K)
        return self._kd[K]

    def at(self, s: float, mode: int) -> tuple[np.ndarray, float]:
        """Row of mode ``mode``'s ``q`` in ``e^{A s}`` (its 2x2 block) and in ``Gamma(s)``."""
        key = (s, mode)
        if key not in self._at_cache:
            self._at_cache[key] = deflection_row(self.sys, s, mode)
        return self._at_cache[key]

    def block_states(self, K: int, u: np.ndarray) -> list[np.ndarray]:
        """Limited component (scaled by its limit) of every block at samples ``0..K`` (closed forms, FFT)."""
        return block_states(self.kdata(K), self.blocks, u, self.um)

    def assemble(
        self, K: int, seg: Segments, mode: str, extra: list[set], t_fix: float | None = None, lazy: Lazy | None = None
    ) -> Assembled:
        """The LP at ``K`` samples in ``seg`` (``mode`` and ``t_fix`` as :meth:`.lp.LimitLP.solve`).

        ``extra``: per block, the samples inside runs that get limit rows (generated by the solver).
        ``lazy`` (scaled LPs): which state rows at the knots and which command rows ``+-v <= t`` to
        include (the rest are checked after the solve and added when violated, :mod:`.lp`); None: all.
        """
        kd = self.kdata(K)
        scaled = mode == "scaled"
        keep = 1.0 - MARGIN if t_fix is None else t_fix
        ubound = 1.0 if t_fix is None else t_fix
        n = self.sys.n
        run = seg.run_of()
        free = run < 0
        F = np.flatnonzero(free)
        nR = seg.start.size
        knot = free.copy()
        knot[0] = True
        knot[F[F + 1 < K] + 1] = True
        knot[seg.start] = True
        knot[seg.end[seg.end < K]] = True
        kn = np.flatnonzero(knot)
        kpos = np.full(K, -1)
        kpos[kn] = np.arange(kn.size)
        # variables: t (one copy per knot, chained: a single t column would be dense) | free commands |
        # run levels | chain states per block | total variation
        T = kpos[np.maximum.accumulate(np.where(knot, np.arange(K), 0))]
        T = np.concatenate([T, T[-1:]])  # the copy of t at sample k (k = K: the last)
        nv = kn.size
        uvar = np.full(K, -1)
        uvar[F] = nv + np.arange(F.size)
        nv += F.size
        lvar = nv + np.arange(nR)
        nv += nR
        cbase = []
        for b in self.blocks:
            cbase.append(nv)
            nv += len(b.idx) * kn.size
        E = SparseRows()  # equalities
        U = SparseRows()  # inequalities
        sl = self.slew

        def u_terms(ms: np.ndarray, coef: np.ndarray):
            """Columns and values of commands ``v_m`` (free variable or run level) and their t coefficient."""
            r_ = run[ms]
            cols = np.where(r_ < 0, uvar[ms], lvar[np.maximum(r_, 0)] if nR else 0)
            tco = np.zeros(ms.size)
            on = r_ >= 0
            if on.any() and sl is not None:
                tco[on] = coef[on] * sl * seg.slope[r_[on]] * (ms[on] - seg.start[r_[on]])
            return cols, coef, tco

        # arrival: sum_m g_{K-1-m} u_m = w (every state, scaled by its size)
        gK = kd.g[K - 1 :: -1] * self.um / kd.sc  # row m: g_{K-1-m}, normalised command
        row_scale = np.ones(n)
        for i in range(n):
            cols = [uvar[F]]
            vals = [gK[F, i]]
            tv = 0.0
            for r in range(nR):
                a, b_ = seg.start[r], seg.end[r]
                cols.append(np.array([lvar[r]]))
                vals.append(np.array([gK[a:b_, i].sum()]))
                if sl is not None and seg.slope[r]:
                    tv += sl * seg.slope[r] * float(gK[a:b_, i] @ np.arange(b_ - a))
            if tv:
                cols.append(np.array([0]))
                vals.append(np.array([tv]))
            vals = np.concatenate(vals)
            # each arrival row in its own units (HiGHS's tolerances are absolute: a damped rigid body's long
            # move left one row 1e12 times the others); nu is returned in kd.sc units (scaled back below)
            big = float(np.max(np.abs(vals))) if vals.size else 0.0
            row_scale[i] = 1.0 / big if big > 0.0 else 1.0
            E.add(np.concatenate(cols), vals * row_scale[i], kd.w[i] / kd.sc[i] * row_scale[i])
        n_arrival = n
        i = np.arange(kn.size - 1)
        E.add_many(np.column_stack([i, i + 1]), np.tile([1.0, -1.0], (i.size, 1)), np.zeros(i.size))
        # chains of the limited blocks at the knots
        for bi, b in enumerate(self.blocks):
            d = len(b.idx)
            P, gh, psi, R = kd.blk[bi]
            var = lambda k, c, bi=bi, d=d: cbase[bi] + d * kpos[k] + c
            Ph = P[1]
            a = F[F + 1 < K]  # free transitions a -> a + 1
            for c in range(d):
                cols = [var(a + 1, c), uvar[a]] + [var(a, cc) for cc in range(d)]
                vals = [np.ones(a.size), np.full(a.size, -gh[0, c])] + [np.full(a.size, -Ph[c, cc]) for cc in range(d)]
                E.add_many(np.column_stack(cols), np.column_stack(vals), np.zeros(a.size))
            if nR:  # s_q = P^L s_p + psi_L level + slope R_L t: one row per run and component, in that order
                p, q = seg.start, seg.end
                L = q - p
                rr = np.repeat(np.arange(nR), d)  # row (r, c): run r, component c
                cc_ = np.tile(np.arange(d), nR)
                pr, qr, Lr = p[rr], q[rr], L[rr]
                cols = [var(qr, cc_), lvar[rr]] + [var(pr, cc) for cc in range(d)] + [T[pr]]
                # a ramp's t term; 0 on a constant run (an explicit zero: HiGHS's input drops it)
                ramp = -sl * seg.slope[rr] * R[Lr, cc_] if sl is not None else np.zeros(rr.size)
                vals = [np.ones(rr.size), -psi[Lr, cc_]] + [-P[Lr, cc_, cc] for cc in range(d)] + [ramp]
                E.add_many(np.column_stack(cols), np.column_stack(vals), np.zeros(rr.size))
            # limit rows at the knots (sample 0 is the initial state, sample K the target)
            at = kn[kn >= 1]
            for side, sgn in enumerate((1.0, -1.0)):
                kk = at if lazy is None else at[lazy.state[bi][at, side]]
                U.add_many(
                    np.column_stack([var(kk, 0), T[kk]]),
                    np.column_stack([np.full(kk.size, sgn), np.full(kk.size, -1.0)]),
                    np.zeros(kk.size),
                    meta=(STATE, kk, b.idx[0], sgn),
                )
            # generated rows inside runs (each sample: the + row, then the - row)
            ks = np.array(sorted(extra[bi]), dtype=int)
            ks = ks[ks < K]
            ks = ks[~knot[ks] & (run[ks] >= 0)]
            if ks.size:
                cols, vals = self._run_states(ks, 0, bi, seg, run, kd, var, lvar, T)
                sg = np.tile([1.0, -1.0], ks.size)
                vals = np.repeat(vals, 2, axis=0) * sg[:, None]
                vals[:, -1] -= 1.0
                U.add_many(
                    np.repeat(cols, 2, axis=0), vals, np.zeros(sg.size), meta=(STATE, np.repeat(ks, 2), b.idx[0], sg)
                )
        # command bounds |v| <= t (scaled) or <= 1
        ub_t, ub_rhs = (-1.0, 0.0) if scaled else (0.0, ubound)
        if scaled:
            for side, sgn in enumerate((1.0, -1.0)):
                Fs = F if lazy is None else F[lazy.command[F, side]]
                U.add_many(
                    np.column_stack([uvar[Fs], T[Fs]]),
                    np.column_stack([np.full(Fs.size, sgn), np.full(Fs.size, -1.0)]),
                    np.zeros(Fs.size),
                    meta=(COMMAND, Fs, 0, sgn),
                )
        if nR:  # per run, its start (and a ramp's last sample), the + and the - row
            ramp = seg.slope != 0 if sl is not None else np.zeros(nR, bool)
            rr = np.repeat(np.arange(nR), np.where(ramp, 2, 1))
            mm = seg.start[rr].copy()
            mm[1:][rr[1:] == rr[:-1]] = seg.end[rr[1:][rr[1:] == rr[:-1]]] - 1
            off = sl * seg.slope[rr] * (mm - seg.start[rr]) if sl is not None else np.zeros(rr.size)
            on = (off != 0.0) | scaled
            rr, mm, off = rr[on], mm[on], off[on]
            sg = np.tile([1.0, -1.0], rr.size)
            cols = np.column_stack([np.repeat(lvar[rr], 2), np.repeat(T[mm], 2)])
            U.add_many(cols, np.column_stack([sg, sg * np.repeat(off, 2) + ub_t]), np.full(sg.size, ub_rhs))
        # slew rows and total variation on every step that is not inside a run
        edges = np.arange(K + 1)
        inside = np.zeros(K + 1, bool)
        inside[1:K] = (run[1:] >= 0) & (run[1:] == run[:-1])
        edges = edges[~inside]
        tv = mode == "smooth" and (sl is None or any(b.mode is not None for b in self.blocks))
        tvar = None
        if tv:
            tvar = nv + np.arange(edges.size)
            nv += edges.size
        if sl is not None or tv:
            right = edges < K
            left = edges >= 1
            for sgn in (1.0, -1.0):
                for kind in (["slew"] if sl is not None else []) + (["tv"] if tv else []):
                    rc, rv, rt = [], [], np.zeros(edges.size)
                    mr = np.where(right, edges, 0)
                    c1, v1, t1 = u_terms(mr, np.where(right, sgn, 0.0))
                    ml = np.where(left, edges - 1, 0)
                    c2, v2, t2 = u_terms(ml, np.where(left, -sgn, 0.0))
                    rc, rv = [c1, c2], [v1, v2]
                    rt = t1 + t2
                    if kind == "slew":  # +-step / slew - t <= 0
                        rc.append(T[edges])
                        rv = [v1 / sl, v2 / sl, rt / sl - 1.0]
                        U.add_many(
                            np.column_stack(rc), np.column_stack(rv), np.zeros(edges.size), meta=(SLEW, edges, 0, sgn)
                        )
                    else:  # +-step - tau <= 0
                        rc += [T[edges], tvar]
                        rv += [rt, np.full(edges.size, -1.0)]
                        U.add_many(np.column_stack(rc), np.column_stack(rv), np.zeros(edges.size))
        # deflection between samples: cuts, and (smooth) the middle of every free interval
        cuts = [(c.k, c.mode, c.s) for c in self.cuts if c.k < K]
        bmode = {b.mode: bi for bi, b in enumerate(self.blocks) if b.mode is not None}
        for k, i, s in cuts:
            if i not in bmode:
                continue
            bi = bmode[i]
            b = self.blocks[bi]
            Ps, Gs = self.at(s, i)
            var = lambda k_, c, bi=bi: cbase[bi] + 2 * kpos[k_] + c
            if knot[k]:
                cols = np.array([var(k, 0), var(k, 1)])
                vals = Ps * b.D / b.D[0]
            else:
                cs, vs = [], []
                for c in range(2):
                    cc, vv = self._run_state(k, c, bi, seg, run, kd, var, lvar, T)
                    cs.append(cc)
                    vs.append(vv * Ps[c] * b.D[c] / b.D[0])
                cols, vals = np.concatenate(cs), np.concatenate(vs)
            uc, uv, ut = u_terms(np.array([k]), np.array([Gs * self.um / b.D[0]]))
            cols = np.concatenate([cols, uc, [T[k]]])
            vals = np.concatenate([vals, uv, ut])
            for sgn in (1.0, -1.0):
                v_ = sgn * vals
                v_[-1] -= 1.0
                U.add(cols, v_, 0.0, meta=(CUT, k, i, sgn), s=s)
        if mode in ("smooth", "reach"):  # the middle of every free interval (free samples are knots: no run terms)
            s = 0.5 * self.dt
            for bi, b in enumerate(self.blocks):
                if b.mode is None or not F.size:
                    continue
                Ps, Gs = self.at(s, b.mode)
                c0 = cbase[bi] + 2 * kpos[F]
                cols = np.column_stack([c0, c0 + 1, uvar[F], T[F]])
                row = np.concatenate([Ps * b.D / b.D[0], [Gs * self.um / b.D[0], 0.0]])
                sg = np.tile([1.0, -1.0], F.size)
                vals = row[None, :] * sg[:, None]
                vals[:, -1] -= 1.0
                U.add_many(
                    np.repeat(cols, 2, axis=0), vals, np.zeros(sg.size), meta=(CUT, np.repeat(F, 2), b.mode, sg), s=s
                )
        # bounds, cost
        lo = np.full(nv, -np.inf)
        hi = np.full(nv, np.inf)
        if scaled:
            lo[: kn.size] = 0.0
        else:
            lo[: kn.size] = hi[: kn.size] = keep
            lo[uvar[F]], hi[uvar[F]] = -ubound, ubound
            lo[lvar], hi[lvar] = -ubound, ubound
        for bi, b in enumerate(self.blocks):
            d = len(b.idx)
            x0b = self.x0[b.idx] / b.D
            lo[cbase[bi] : cbase[bi] + d] = hi[cbase[bi] : cbase[bi] + d] = x0b  # knot 0
        if tvar is not None:
            lo[tvar] = 0.0
        cost = np.zeros(nv)
        if scaled:
            cost[0] = 1.0
        elif tvar is not None:
            cost[tvar] = 1.0
        A_eq, b_eq = E.system(nv)
        A_ub, b_ub = U.system(nv)
        return Assembled(
            cost=cost,
            A_ub=A_ub,
            b_ub=b_ub,
            A_eq=A_eq,
            b_eq=b_eq,
            lower=lo,
            upper=hi,
            free=F,
            uvar=uvar,
            lvar=lvar,
            n_arrival=n_arrival,
            row_scale=row_scale,
            meta=U.meta_array(),
            s=U.s_array(),
            n_t=int(kn.size),
            n_tv=0 if tvar is None else int(tvar.size),
        )

    def _run_states(self, ks, c, bi, seg, run, kd, var, lvar, T):
        """:meth:`_run_state` at the samples ``ks`` (all inside runs): columns and values, one row per sample."""
        r = run[ks]
        p = seg.start[r]
        j = ks - p
        P, _gh, psi, R = kd.blk[bi]
        d = len(self.blocks[bi].idx)
        cols = np.column_stack([var(p, cc) for cc in range(d)] + [lvar[r], T[ks]])
        tco = self.slew * seg.slope[r] * R[j, c] if self.slew is not None else np.zeros(ks.size)
        vals = np.column_stack([P[j, c, cc] for cc in range(d)] + [psi[j, c], tco])
        return cols, vals

    def _run_state(self, k, c, bi, seg, run, kd, var, lvar, T):
        """Columns/values of component ``c`` of block ``bi``'s state at sample ``k`` inside a run; t last."""
        cols, vals = self._run_states(np.array([k]), c, bi, seg, run, kd, var, lvar, T)
        return cols[0], vals[0]
