"""The linear program of the limited planner: ``K`` samples, every limit, the exact arrival; solved here.

Three modules: :mod:`.segments` (what the LP is over: :class:`Segments`, and
what a solve returns: :class:`LPSolution`), :mod:`.assembly` (its sparse rows,
:class:`~.assembly.LimitRows`) and this one (:class:`LimitLP`: HiGHS with its
fallbacks, limit rows generated inside runs, the exact arrival).

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

import numpy as np
from scipy.ndimage import maximum_filter1d

from ..errors import SolverError
from ..linear_program import LpMethod, LpStatus, solve_lp
from ..sampled.lp_tools import correct_arrival
from ..tolerances import HIGHS_OPTIONS, ROW_RTOL
from .assembly import LimitRows
from .segments import Lazy, LPSolution, Segments
from .warm import WarmStart, point_from_commands, resampled, same_columns, start_point

MAX_ROW_ROUNDS = 10
#: Scaled LPs include a state row at a knot, or a command row ``+-v <= t``, only where the last
#: solution at this rate (or the coarser level's) came within this fraction of ``t`` on that side,
#: within :data:`LAZY_SPREAD` of its samples; the rest are checked after the solve and added when
#: violated (the bench's 1 kHz probes: 5,124 inequality rows of which about 2,000 matter, half the
#: interior-point time).
LAZY_KEEP = 0.5
LAZY_SPREAD = 2
#: ... and only from a solution whose move time is within this (relative) of the LP's: the seed-18 fuzz's
#: case 100 (one level, counts 177 -> 355 -> 266 -> 221 -> 209) took 4-5 rounds per count from the
#: neighbouring counts' solutions, twice the CPU; the coarser level's answer and the neighbouring
#: samples of a bisection are within 1 %.
LAZY_NEAR = 0.02
#: Rounds with rows left out before every row is included.
LAZY_ROUNDS = 2
#: A left-out row this close to its limit (relative to ``t``) is added: :data:`.dual.ACTIVE_RTOL`.
LAZY_ACTIVE_RTOL = 1e-7
#: Rows seeded from a coarser level: the samples within this many of each mapped row (a coarse sample
#: stands for ``COARSE_FACTOR`` fine ones).
SEED_SPREAD = 2
#: Above this many free samples (with state chains) the interior-point method beats the simplex.
IPM_SAMPLES = 300
#: The verdicts that decide a sample count; ``linprog``'s names of the methods, for messages.
DECIDED = (LpStatus.OPTIMAL, LpStatus.INFEASIBLE)
METHOD_NAMES = {LpMethod.CHOOSE: "highs", LpMethod.DUAL_SIMPLEX: "highs-ds", LpMethod.IPM: "highs-ipm"}


class LPUndecided(SolverError):
    """HiGHS decided neither "optimal" nor "infeasible" with any method: the LP says nothing about ``K``."""


class LimitLP(LimitRows):
    """The limit LPs of one problem, rate and set of limits, for any ``K`` and :class:`Segments`: solved, rows
    generated inside runs until every limit holds at every sample, and the accepted arrival made exact."""

    # ------------------------------------------------------------------ solve
    def solve(
        self,
        K: int,
        seg: Segments | None = None,
        mode: str = "scaled",
        t_fix: float | None = None,
        start: LPSolution | None = None,
    ) -> LPSolution | None:
        """Solve at ``K`` samples (``seg`` None: every sample free); ``mode`` ``"scaled"``, ``"smooth"``,
        ``"feasible"`` or ``"reach"``.

        ``"feasible"``: any sequence meeting the limits scaled by ``t_fix`` (no
        objective, no mid-interval rows); None proves there is none.
        ``"reach"``: the same with the smooth LP's mid-interval rows (the smooth LP's
        constraints without its objective): None when the smooth LP has no solution.

        ``t_fix`` (smooth): the scale of every limit, commands included (default:
        ``1 - MARGIN`` on the state and slew limits, ``|u| <= u_max``): the
        smoothest of the sequences that meet the limits scaled by ``t_fix``.

        ``start`` (smooth, reach): a scaled solution at the same ``K`` in the same segments; its point
        (the same columns, the total-variation ones set to the steps) starts HiGHS's dual simplex, as a
        warm start: the same LP and verdict, fewer iterations (the bench's 250 Hz reference: 3,021 -> 1,224).
        Ignored when it does not fit.

        Returns None when the LP has no solution (``smooth``: the limits
        cannot be met with this parametrisation; ``scaled``: the runs and
        free samples cannot reach the target).  Raises :class:`LPUndecided`
        when HiGHS gives neither verdict with any method, or when the rows
        inside runs, added until the solution meets every limit at every
        sample, did not settle within ``MAX_ROW_ROUNDS`` (never read as "infeasible").
        """
        seg = seg if seg is not None else Segments.all_free(K)
        if K not in self.run_rows:
            self.run_rows[K] = self._seed_rows(K)
        rows = self.run_rows[K]
        sol = None
        warm = None
        # window LPs only: an LP with every sample free (the coarsest level, a re-anchoring, a proof) is
        # often far from the window solution that would predict its rows (the seed-18 fuzz's case 20:
        # five rounds of 0.12 s at 956 free samples where the LP with every row took 0.17 s)
        lazy = self._lazy(K) if mode == "scaled" and seg.n_free < K else None
        point = start if mode != "scaled" else None
        for i in range(MAX_ROW_ROUNDS):
            if i == LAZY_ROUNDS:
                lazy = None  # the prediction keeps missing: every row from here (rows added: still warm)
            try:
                sol, warm = self._solve_once(K, seg, mode, rows, t_fix, warm, lazy, point if i == 0 else None)
            except LPUndecided:
                if lazy is None:
                    raise
                # no verdict on the LP with rows left out: the LP with every row decides, as before
                lazy = warm = None
                sol, warm = self._solve_once(K, seg, mode, rows, t_fix, warm, lazy)
            if sol is None:
                return sol
            # the left-out rows first: a solution that breaks them says nothing about the rows inside runs
            # (rows added from it stay in the LP; at zero multipliers the lift of :mod:`.dual` reads them
            # as unneeded: the fuzz's case 93 lost its weak-duality proof that way)
            if lazy is not None and self._add_dropped_rows(sol, lazy):
                continue
            if not self._add_violated_rows(sol, rows):
                if mode == "scaled":
                    self._remember(sol)
                return sol
            # the next round is the same LP with rows added: the dual simplex from this optimum's basis
            # (the new rows' slacks basic) only repairs them (the bench's 1 kHz all-three move: 0.25-0.34 s
            # per cold round at 600 free samples)
        # rows inside runs still violated: not a restriction of the full problem (its t is no upper
        # bound), and no verdict either: the callers fall back to every sample free, or step past K
        raise LPUndecided(f"limited planner: limit rows at {K} samples did not settle in {MAX_ROW_ROUNDS} rounds")

    def _seed_rows(self, K: int) -> list[set]:
        """Rows inside runs for a count not solved yet: those of the nearest count solved at this rate, or
        of the coarser level (:attr:`coarse_rows`), placed by normalised time.

        A limit row at a sample is a constraint of the full problem wherever it lands (a row that is not
        needed only costs its size), so seeding changes no claim; it saves the LP round that would find
        the same violated samples again (each round is a new LP: at 1 kHz 0.1-0.3 s).
        """
        if self.run_rows:
            K_ref = min(self.run_rows, key=lambda k: abs(k - K))
            src, spread = self.run_rows[K_ref], 0
        elif self.coarse_rows is not None:
            src, K_ref = self.coarse_rows
            spread = SEED_SPREAD
        else:
            return [set() for _ in self.blocks]
        f = K / K_ref
        out = []
        for s in src:
            base = np.rint(np.fromiter(s, float, len(s)) * f).astype(int)
            ks = (base[:, None] + np.arange(-spread, spread + 1)).ravel()
            out.append(set(ks[(ks >= 1) & (ks < K)].tolist()))
        return out

    def _lazy(self, K: int) -> Lazy | None:
        """Which rows a scaled LP at ``K`` includes, from the last scaled solution at this rate or the
        coarser level's (placed by normalised time); None (every row) without one."""
        ref = self.profile if self.profile is not None else self.coarse_profile
        if ref is None:
            return None
        K_ref, T_ref, v_ref, x_ref = ref
        if abs(K * self.dt / T_ref - 1.0) > LAZY_NEAR:
            return None  # a move this much longer or shorter has other arcs near its limits (every row)
        width = 2 * LAZY_SPREAD + 1

        def keep(a: np.ndarray, n: int) -> np.ndarray:
            # (n, 2): the + and - side of sample k, from the reference's samples around k K_ref / K
            j = np.minimum(np.rint(np.arange(n) * (K_ref / K)).astype(int), a.size - 1)
            near = np.column_stack([maximum_filter1d(a, width), maximum_filter1d(-a, width)])
            return near[j] >= LAZY_KEEP

        return Lazy(state=[keep(x, K + 1) for x in x_ref], command=keep(v_ref, K))

    def _remember(self, sol: LPSolution) -> None:
        """Keep a scaled solution's commands and limited states (over ``t``) for :meth:`_lazy`."""
        t = max(sol.t, 1e-300)
        states = [x / t for x in self.block_states(sol.K, sol.u)]
        self.profile = (sol.K, sol.K * self.dt, sol.u / (self.um * t), states)

    def _add_dropped_rows(self, sol: LPSolution, lazy: Lazy) -> bool:
        """Include every left-out knot or command row the solution violates; True if any."""
        K, seg = sol.K, sol.segments
        run = seg.run_of()
        free = run < 0
        knot = free.copy()
        knot[0] = True
        F = np.flatnonzero(free)
        knot[F[F + 1 < K] + 1] = True
        knot[seg.start] = True
        knot[seg.end[seg.end < K]] = True
        at = np.append(knot, False)  # the knots with a state row (samples 1..K-1)
        at[0] = False
        # the rows at their limit too, not only the violated ones: the LP then holds every active row, as
        # with every row included (the lift of :mod:`.dual` reads a row left at zero by the LP as unneeded)
        lim = sol.t * (1.0 - LAZY_ACTIVE_RTOL)
        added = False
        for mask, x in zip(lazy.state, self.block_states(K, sol.u)):
            for side, sgn in ((0, 1.0), (1, -1.0)):
                bad = np.zeros(K + 1, bool)
                bad[1:K] = sgn * x[1:K] > lim
                bad = maximum_filter1d(bad, 2 * LAZY_SPREAD + 1) & at & ~mask[:, side]  # and the neighbours
                if bad.any():
                    mask[bad, side] = True
                    added = True
        v = sol.u / self.um
        for side, sgn in ((0, 1.0), (1, -1.0)):
            bad = maximum_filter1d(sgn * v > lim, 2 * LAZY_SPREAD + 1) & free & ~lazy.command[:, side]
            if bad.any():
                lazy.command[bad, side] = True
                added = True
        return added

    def _solve_once(
        self,
        K,
        seg,
        mode,
        extra,
        t_fix=None,
        warm: WarmStart | None = None,
        lazy: Lazy | None = None,
        point: LPSolution | None = None,
    ) -> tuple[LPSolution | None, WarmStart | None]:
        """One LP; with ``warm`` (the previous round of the same LP, fewer rows) the dual simplex starts
        from its optimal basis, with ``point`` (a solution over the same first columns) from a basis
        around its point; either falls back to a cold solve if that gives no verdict."""
        self.solves += 1
        a = self.assemble(K, seg, mode, extra, t_fix, lazy)
        F, uvar, lvar, nR, sl = a.free, a.uvar, a.lvar, seg.start.size, self.slew
        method = LpMethod.IPM if F.size > IPM_SAMPLES and self.blocks else LpMethod.CHOOSE
        limit = max(0.5, self.deadline - time.perf_counter()) if math.isfinite(self.deadline) else None
        # the planner's budget bounds every single LP too
        lp = dict(
            cost=a.cost,
            A_ub=a.A_ub,
            b_ub=a.b_ub,
            A_eq=a.A_eq,
            b_eq=a.b_eq,
            lower=a.lower,
            upper=a.upper,
            time_limit_s=limit,
            **HIGHS_OPTIONS,
        )
        start = warm.carried(a) if warm is not None else None
        x0 = None
        if start is None and point is not None:
            if same_columns(point, K, seg):
                x0 = start_point(a, point.x)
            else:
                x0 = point_from_commands(a, seg, resampled(point.u / self.um, K), self.slew)
        res = None
        if start is not None or x0 is not None:
            res = solve_lp(**lp, method=LpMethod.DUAL_SIMPLEX, start_basis=start, start_point=x0, return_basis=True)
            if res.status in DECIDED:
                method = LpMethod.DUAL_SIMPLEX
            else:
                res = None  # no verdict from the warm start: the cold solve decides, as before
        if res is None:
            res = solve_lp(**lp, method=method, return_basis=True)
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
            return None, None
        if res.status is not LpStatus.OPTIMAL:
            raise LPUndecided(f"limited planner: linear program at {K} samples undecided ({'; '.join(tried)})")
        x = res.x
        t = float(x[0])
        v = np.empty(K)
        v[F] = x[uvar[F]]
        levels = x[lvar] if nR else np.zeros(0)
        for r in range(nR):
            p, q = seg.start[r], seg.end[r]
            v[p:q] = levels[r] + (t * sl * seg.slope[r] * np.arange(q - p) if sl is not None else 0.0)
        keep_rows = a.meta[:, 0] >= 0
        lam = -np.asarray(res.ub_marginals, float)[keep_rows] if a.meta.shape[0] else np.zeros(0)
        nu = np.asarray(res.eq_marginals, float)[: a.n_arrival] * a.row_scale
        sol = LPSolution(K, self.um * v, t, nu, a.meta[keep_rows], a.s[keep_rows], np.maximum(lam, 0.0), seg, levels, x)
        return sol, (WarmStart(rows=a, solution=res) if res.basis_reader is not None else None)

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
