"""The linear program of the limited planner: ``K`` samples, every limit, the exact arrival.

At a fixed rate the states at the samples are linear in the commands, so for
``K`` samples "every limit holds and the target is reached exactly" is a set
of linear constraints (scipy HiGHS).  The limits are
:class:`~flexmotion_ros.core.limit_checks.Limits`; the search over ``K`` is
:mod:`.limits`, the proof that fewer samples cannot work :mod:`.limit_dual`.

Normalised form
---------------
Commands ``v_m = u_m / u_max``; every limit row is written ``a^T v + d <= t``
(a state or a step divided by its limit, each side separately).  Three uses:

* ``scaled``: ``min t`` with ``|v_m| <= t`` as well.  ``t*(K) <= 1`` iff ``K``
  samples meet every limit; ``t*`` is non-increasing in ``K`` (hold zero one
  sample longer).  With every sample free the LP is feasible whenever the
  sampled system can reach the target in ``K`` samples; a window LP (runs
  sharing a level) may not be, and then says so (None).  Its dual gives the
  weak-duality bound of :mod:`.limit_dual`.
* ``feasible``: the limits scaled by a fixed ``t``, no objective: the
  last-resort infeasibility proof of :mod:`.planner` (HiGHS's verdict, used
  as a proof only when the independent formulation of :mod:`.certify` agrees).
* ``smooth`` (the accepted solve): ``t`` fixed at ``1 - MARGIN``,
  ``|v_m| <= 1``, minimum total variation ``sum |u_k - u_{k-1}|`` (where a
  deflection limit is set or no slew limit: under a slew limit alone any
  vertex is smooth enough), and each
  limited deflection also kept within its limit at the middle of every free
  sample interval: a bare feasible vertex chatters at the sample rate where a
  state rides its limit, and a chattering deflection overshoots between
  samples.

Few variables (as in :mod:`.zoh`)
---------------------------------
In the optimum most samples sit at a bound, ride a state limit at a constant
level, or follow a slew ramp.  :class:`Segments` says which samples are free
variables and which share one *level* variable (a run; on a slew ramp the
level plus ``t`` slew steps per sample).  Limited states are sparse chain
variables only at *knots* (run ends and free samples): a run is crossed in
one step with closed-form powers and step responses
(:mod:`.limit_responses`), never a dense ``K x K`` matrix.  Limit rows inside runs are generated: after each solve
the states at every sample are evaluated and violated rows are added.
:meth:`Segments.all_free` gives the full problem.

Exactness: the accepted solution's arrival is corrected to rounding
(least-norm change on unsaturated samples; ``MARGIN`` absorbs it) and every
limit is checked on the exact matrix-exponential simulation; a deflection
found above its limit between samples becomes a :class:`Cut` (a necessary
condition, so the problem with cuts stays a relaxation of the continuous
one).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..errors import GoalError, SolverError
from ..linear_program import LpMethod, LpStatus, solve_lp
from ..model.boundary import MoveProblem
from ..sampled.lp_tools import correct_arrival
from ..sampled.sparse_rows import SparseRows
from ..simulation.modal_response import ModalResponse
from ..tolerances import HIGHS_OPTIONS, ROW_RTOL
from .limits import Cut, Limits
from .responses import Block, KData, block_states, deflection_row, limit_blocks

#: Relative margin by which the accepted LP tightens every state and slew limit (absorbs the arrival correction).
MARGIN = 1e-7
MAX_ROW_ROUNDS = 10
#: Above this many free samples (with state chains) the interior-point method beats the simplex.
IPM_SAMPLES = 300
#: The verdicts that decide a sample count; ``linprog``'s names of the methods, for messages.
DECIDED = (LpStatus.OPTIMAL, LpStatus.INFEASIBLE)
METHOD_NAMES = {LpMethod.CHOOSE: "highs", LpMethod.DUAL_SIMPLEX: "highs-ds", LpMethod.IPM: "highs-ipm"}
#: Row kinds in :class:`LPSolution`.
STATE, CUT, SLEW = 0, 1, 2


class LPUndecided(SolverError):
    """HiGHS decided neither "optimal" nor "infeasible" with any method: the LP says nothing about ``K``."""


@dataclass
class Segments:
    """Parametrisation of ``K`` commands: runs ``[start, end)`` sharing a level; the rest free.

    ``slope`` per run: 0 (constant level) or ``+-1`` (slew ramp: ``+-t`` slew
    steps per sample on top of the level).  Runs never touch the first or
    last sample.
    """

    K: int
    start: np.ndarray
    end: np.ndarray
    slope: np.ndarray

    @classmethod
    def all_free(cls, K: int) -> Segments:
        e = np.zeros(0, dtype=int)
        return cls(K, e, e.copy(), np.zeros(0))

    @classmethod
    def from_runs(cls, K: int, runs: list[tuple[int, int, float]]) -> Segments:
        runs = sorted((int(a), int(b), float(s)) for a, b, s in runs if 1 <= a < b <= K - 1)
        return cls(
            K, np.array([r[0] for r in runs], int), np.array([r[1] for r in runs], int), np.array([r[2] for r in runs])
        )

    def run_of(self) -> np.ndarray:
        """Run index of every sample, -1 for free samples."""
        out = np.full(self.K, -1)
        for r, (a, b) in enumerate(zip(self.start, self.end)):
            out[a:b] = r
        return out

    @property
    def n_free(self) -> int:
        return int(self.K - np.sum(self.end - self.start))


@dataclass
class LPSolution:
    """One solve: commands, scale and the dual values the weak-duality bound needs."""

    K: int
    u: np.ndarray  # commands (N), forward order
    t: float
    nu: np.ndarray  # multipliers of the (scaled) arrival rows
    rows: np.ndarray  # included limit rows: (kind, k, index, sign), shape (R, 4)
    s: np.ndarray  # offset within the interval of cut rows (s)
    lam: np.ndarray  # their multipliers (>= 0)
    segments: Segments
    levels: np.ndarray


class LimitLP:
    """The limit LPs of one problem, rate and set of limits, for any ``K`` and :class:`Segments`."""

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
        self._rows: dict[int, list[set]] = {}  # generated rows inside runs, per K and block
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

    # ------------------------------------------------------------------ solve
    def solve(
        self, K: int, seg: Segments | None = None, mode: str = "scaled", t_fix: float | None = None
    ) -> LPSolution | None:
        """Solve at ``K`` samples (``seg`` None: every sample free); ``mode`` ``"scaled"``, ``"smooth"`` or ``"feasible"``.

        ``"feasible"``: any sequence meeting the limits scaled by ``t_fix`` (no
        objective, no mid-interval rows); None proves there is none.

        ``t_fix`` (smooth): the scale of every limit, commands included (default:
        ``1 - MARGIN`` on the state and slew limits, ``|u| <= u_max``): the
        smoothest of the sequences that meet the limits scaled by ``t_fix``.

        Returns None when the LP has no solution (``smooth``: the limits
        cannot be met with this parametrisation; ``scaled``: the runs and
        free samples cannot reach the target).  Raises :class:`LPUndecided`
        when HiGHS gives neither verdict with any method, or when the rows
        inside runs, added until the solution meets every limit at every
        sample, did not settle within ``MAX_ROW_ROUNDS`` (never read as "infeasible").
        """
        seg = seg if seg is not None else Segments.all_free(K)
        rows = self._rows.setdefault(K, [set() for _ in self.blocks])
        sol = None
        for _ in range(MAX_ROW_ROUNDS):
            sol = self._solve_once(K, seg, mode, rows, t_fix)
            if sol is None or not self._add_violated_rows(sol, rows):
                return sol
        # rows inside runs still violated: not a restriction of the full problem (its t is no upper
        # bound), and no verdict either: the callers fall back to every sample free, or step past K
        raise LPUndecided(f"limited planner: limit rows at {K} samples did not settle in {MAX_ROW_ROUNDS} rounds")

    def _solve_once(self, K, seg, mode, extra, t_fix=None) -> LPSolution | None:
        self.solves += 1
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
            for r in range(nR):  # s_q = P^L s_p + psi_L level + slope R_L t
                p, q = seg.start[r], seg.end[r]
                L = q - p
                for c in range(d):
                    cols = [var(q, c), lvar[r]] + [var(p, cc) for cc in range(d)]
                    vals = [1.0, -psi[L, c]] + [-P[L, c, cc] for cc in range(d)]
                    if sl is not None and seg.slope[r]:
                        cols.append(T[p])
                        vals.append(-sl * seg.slope[r] * R[L, c])
                    E.add(np.array(cols), np.array(vals), 0.0)
            # limit rows at the knots (sample 0 is the initial state, sample K the target)
            kk = kn[kn >= 1]
            for sgn in (1.0, -1.0):
                U.add_many(
                    np.column_stack([var(kk, 0), T[kk]]),
                    np.column_stack([np.full(kk.size, sgn), np.full(kk.size, -1.0)]),
                    np.zeros(kk.size),
                    meta=(STATE, kk, b.idx[0], sgn),
                )
            # generated rows inside runs
            for k in sorted(extra[bi]):
                if k >= K or knot[k] or run[k] < 0:
                    continue
                cols, vals = self._run_state(k, 0, bi, seg, run, kd, var, lvar, T)
                for sgn in (1.0, -1.0):
                    U.add(
                        cols,
                        np.concatenate([sgn * vals[:-1], [sgn * vals[-1] - 1.0]]),
                        0.0,
                        meta=(STATE, k, b.idx[0], sgn),
                    )
        # command bounds |v| <= t (scaled) or <= 1
        ub_t, ub_rhs = (-1.0, 0.0) if scaled else (0.0, ubound)
        if scaled:
            for sgn in (1.0, -1.0):
                U.add_many(
                    np.column_stack([uvar[F], T[F]]),
                    np.column_stack([np.full(F.size, sgn), np.full(F.size, -1.0)]),
                    np.zeros(F.size),
                )
        for r in range(nR):
            ends = [seg.start[r]] if not (sl is not None and seg.slope[r]) else [seg.start[r], seg.end[r] - 1]
            for m in ends:
                off = sl * seg.slope[r] * (m - seg.start[r]) if sl is not None else 0.0
                for sgn in (1.0, -1.0):
                    if off or scaled:
                        U.add(np.array([lvar[r], T[m]]), np.array([sgn, sgn * off + ub_t]), ub_rhs)
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
        if mode == "smooth":
            for b in self.blocks:
                if b.mode is not None:
                    cuts += [(int(k), b.mode, 0.5 * self.dt) for k in F]
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
        method = LpMethod.IPM if F.size > IPM_SAMPLES and self.blocks else LpMethod.CHOOSE
        limit = max(0.5, self.deadline - time.perf_counter()) if math.isfinite(self.deadline) else None
        # the planner's budget bounds every single LP too
        lp = dict(
            cost=cost,
            A_ub=A_ub,
            b_ub=b_ub,
            A_eq=A_eq,
            b_eq=b_eq,
            lower=lo,
            upper=hi,
            time_limit_s=limit,
            **HIGHS_OPTIONS,
        )
        res = solve_lp(**lp, method=method)
        tried = [f"{METHOD_NAMES[method]}: {res.message}"]
        if res.status not in DECIDED:
            # neither optimal nor infeasible (e.g. "HiGHS Status 0: Not Set", an iteration or time limit):
            # ask the other methods, then the dual simplex without presolve (it sees the rows unscaled)
            ds, ipm = LpMethod.DUAL_SIMPLEX, LpMethod.IPM
            for alt, presolve in (
                (ds if method is not ds else ipm, True),
                (ipm if method is LpMethod.CHOOSE else ds, True),
                (ds, False),
            ):
                res = solve_lp(**lp, method=alt, presolve=presolve)
                tried.append(f"{METHOD_NAMES[alt]}{'' if presolve else ' (no presolve)'}: {res.message}")
                if res.status in DECIDED:
                    method = alt
                    break
        verdict = "interior point" if method is LpMethod.IPM else "dual simplex"
        if res.status is LpStatus.INFEASIBLE:
            # "infeasible" is a verdict of one method on this formulation; where it decides a proof,
            # the planner has it confirmed by an independent formulation (:mod:`.certify`)
            self.infeasible_verdicts += 1
            self.infeasible_method = verdict
            return None
        if res.status is not LpStatus.OPTIMAL:
            raise LPUndecided(f"limited planner: linear program at {K} samples undecided ({'; '.join(tried)})")
        x = res.x
        t = float(x[0])
        v = np.empty(K)
        v[F] = x[uvar[F]]
        levels = x[lvar] if nR else np.zeros(0)
        for r in range(nR):
            a, b_ = seg.start[r], seg.end[r]
            v[a:b_] = levels[r] + (t * sl * seg.slope[r] * np.arange(b_ - a) if sl is not None else 0.0)
        meta = U.meta_array()
        keep_rows = meta[:, 0] >= 0
        lam = -np.asarray(res.ub_marginals, float)[keep_rows] if U.n else np.zeros(0)
        nu = np.asarray(res.eq_marginals, float)[:n_arrival] * row_scale
        return LPSolution(
            K, self.um * v, t, nu, meta[keep_rows], U.s_array()[keep_rows], np.maximum(lam, 0.0), seg, levels
        )

    def _run_state(self, k, c, bi, seg, run, kd, var, lvar, T):
        """Columns/values of component ``c`` of block ``bi``'s state at sample ``k`` inside a run; t last."""
        r = run[k]
        p = seg.start[r]
        j = k - p
        P, _gh, psi, R = kd.blk[bi]
        d = len(self.blocks[bi].idx)
        cols = [var(p, cc) for cc in range(d)] + [lvar[r], T[k]]
        tco = self.slew * seg.slope[r] * R[j, c] if self.slew is not None else 0.0
        vals = [P[j, c, cc] for cc in range(d)] + [psi[j, c], tco]
        return np.array(cols), np.array(vals, float)

    def block_states(self, K: int, u: np.ndarray) -> list[np.ndarray]:
        """Limited component (scaled by its limit) of every block at samples ``0..K`` (closed forms, FFT)."""
        return block_states(self.kdata(K), self.blocks, u, self.um)

    def _add_violated_rows(self, sol: LPSolution, rows: list[set]) -> bool:
        """Add rows at every sample inside a run where a limited state exceeds ``t``; True if any.

        Every violating sample, not only the local peaks: a peak's row moves the peak to its
        neighbour, and each round is a new LP (the bench's 2 m move took 6-10 rounds at 1 kHz with
        peaks only, 2-3 with every violating sample).
        """
        K = sol.K
        seg = sol.segments
        inner = seg.run_of() >= 0
        inner[seg.start] = False  # run starts are knots: always rows
        added = False
        for bi, x in enumerate(self.block_states(K, sol.u)):
            a = np.abs(x[1:K])
            bad = (a > sol.t * (1.0 + ROW_RTOL) + 1e-12) & inner[1:K]
            if not bad.any():
                continue
            new = set((np.flatnonzero(bad) + 1).tolist()) - rows[bi]
            if new:
                rows[bi] |= new
                added = True
        return added

    # ------------------------------------------------------------ exactness
    def exact_commands(self, u: np.ndarray) -> np.ndarray:
        """Correct the arrival to rounding on unsaturated samples (the LP meets it to its tolerance)."""
        K = u.size
        kd = self.kdata(K)
        G = kd.g[K - 1 :: -1]
        movable = np.abs(u) < self.um * (1.0 - 1e-9)
        if self.slew is not None:
            movable[[0, -1]] = False  # keep the end steps inside the slew limit
        G, w = G / kd.sc, kd.w / kd.sc
        # each arrival equation in its own units: lstsq's rounding is relative to the largest column, and
        # a long move of a damped rigid body left one column 1e12 times the others (fuzz case 151: a
        # 1.3e-9 final-state error, refused); the least-norm change is the same
        big = np.max(np.abs(G[movable]), axis=0, initial=0.0)  # not the 2-norm: it can overflow
        d = 1.0 / np.where(big > 0.0, big, 1.0)
        out = correct_arrival(G * d, w * d, u, movable)
        return np.clip(out, -self.um, self.um)
