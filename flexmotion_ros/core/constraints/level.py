"""One rate of the limited planner's search: probing ``t(K)`` with every sample free or in windows.

:class:`Level` solves the limit LP (:mod:`.lp`) at sample counts ``K`` of one
rate, either with every sample free or with windows around a reference
structure (:mod:`.structure`), and keeps what it learnt; the search over
rates and counts is :mod:`.planner`'s, the proofs that a count is impossible
are :mod:`.proof`'s.
"""

from __future__ import annotations

import math
import time

from ..errors import SolverError, UnreachableError
from ..model.boundary import MoveProblem
from ..results import ProofKind
from .certify import feasible as independent_feasible
from .dual import OWN_WEIGHT, RETRY_OWN_WEIGHT, dual_bound, lift, proves_infeasible
from .limits import Limits
from .lp import LimitLP, LPUndecided
from .proof import LIFT_MAX_UNKNOWNS, LOOSEN
from .segments import LPSolution, Segments
from .structure import map_runs, solution_runs

#: Window half-widths (samples): mapped from the coarser level (in its samples), or from the same rate.
MAP_WIDTH = 2
OWN_WIDTH = 4
#: Fallback windows are this many times wider (before every sample is freed).
WIDE = 4
#: No LP with every sample free (proof or re-anchoring) above this many samples: at 4,000 samples the
#: feasibility LP and its independent confirmation take 5-30 s on a loaded machine, at 13,000 one LP
#: takes 10 s and more; beyond it a count the dual bounds cannot settle is left unproved (and says so).
FULL_LP_MAX_SAMPLES = 3000
#: The reference structure handed to the next level is that of the smoothest sequence within this
#: (relative) of the probe's ``t``: a vertex chatters where a state rides its limit (each chattering
#: stretch would be free at the next level, 4 x longer: 936 free samples at 1 kHz for the bench's
#: deflection limit); much looser (1e-5) and the smooth sequence flattens ramps the optimum needs
#: (the windows then miss the optimum at ``K - 1`` and its lifted dual bound fails); much tighter
#: (1e-8) and it keeps the chatter.
REF_SLACK = 1e-6


class Level:
    """Probes ``t(K)`` at one rate: every sample free, or windows around a reference structure.

    ``t(K)`` from a window LP is an upper bound on ``t*(K)`` (a restriction);
    ``t(K) <= 1`` shows ``K`` feasible.  No bound here claims a count
    infeasible (that is :meth:`prove`'s job); only a rate at which the target
    cannot be reached at all raises :class:`UnreachableError`.
    """

    def __init__(
        self,
        problem: MoveProblem,
        rate: float,
        limits: Limits,
        K_cap: int,
        lp: LimitLP | None = None,
        ref: tuple | None = None,
        width: int = 0,
    ) -> None:
        self.rate = rate
        self.lp = lp if lp is not None else LimitLP(problem, 1.0 / rate, limits)
        self.ref = ref  # (runs, K_ref) or None: every sample free
        self.width = width
        self.K_cap = K_cap
        self.sols: dict[int, LPSolution] = {}
        self.t: dict[int, float] = {}
        self.own = False  # the reference is this level's own solution
        self.undecided: set[int] = set()  # counts where HiGHS gave no verdict with any method
        self.reachable: int | None = None  # from this count on the target is proved reachable (final rate)
        self.deadline = math.inf  # time.perf_counter() after which the search gives up (says so)
        # counts proved infeasible and how: a proof stays valid after cuts (it was for a relaxation)
        self.proofs: dict[int, ProofKind | str] = {}

    @property
    def full(self) -> bool:
        return self.ref is None

    def segments(self, K: int) -> Segments:
        if self.ref is None:
            return Segments.all_free(K)
        runs, K_ref = self.ref
        return map_runs(runs, K_ref, K, self.width)

    def probe(self, K: int) -> float:
        """``t(K)``: an upper bound on ``t*(K)`` (exact with every sample free); ``inf`` if HiGHS gave no verdict."""
        if K not in self.t:
            if time.perf_counter() > self.deadline:
                raise OutOfTime(K)
            if K > self.K_cap:
                raise BeyondCap(K)
            sol = None
            if self.ref is not None:
                for width in (None, WIDE * max(self.width, OWN_WIDTH)):  # the runs cannot reach: wider windows
                    seg = self.segments(K) if width is None else map_runs(self.ref[0], self.ref[1], K, width)
                    try:
                        sol = self.lp.solve(K, seg)
                    except LPUndecided:
                        sol = None
                    if sol is not None:
                        break
            if sol is None:  # no windows, or still none: every sample free (seconds at 1 kHz)
                try:
                    sol = self.lp.solve(K)
                    if sol is None and self.reachable is not None and K >= self.reachable:
                        # K samples reach the target (the unlimited optimum, held at rest, proves it):
                        # "infeasible" here is numerical, not a verdict
                        raise LPUndecided(f"limited planner: no LP verdict at {K} samples")
                except LPUndecided:
                    # no verdict: this K says nothing (never "infeasible"); the search steps past it
                    self.t[K] = math.inf
                    self.undecided.add(K)
                    return math.inf
            if sol is None:
                m = self.lp.model
                turns = ", ".join(f"{w / self.rate / math.pi:.6g}" for w in m.omega)
                raise UnreachableError(
                    f"limited planner: no {K}-sample sequence at {self.rate:g} Hz reaches the target: a mode "
                    f"whose omega / rate_hz is a multiple of pi cannot be steered at this rate (omega_i / (pi rate_hz): {turns})"
                )
            self.sols[K] = sol
            self.t[K] = sol.t
            if not self.own and self.ref is not None:  # narrower windows from this rate's own optimum
                self.ref = (solution_runs(sol, self.lp.um, self.lp.slew), K)
                self.width = OWN_WIDTH
                self.own = True
        return self.t[K]

    def anchor(self, K: int) -> bool:
        """Re-anchor the windows on the exact optimum at ``K`` (every sample free); forget window probes.

        False (nothing changed) if that LP gives no solution or no verdict, or is too large.
        """
        if K > FULL_LP_MAX_SAMPLES:
            return False
        try:
            sol = self.lp.solve(K)
        except LPUndecided:
            return False
        if sol is None:
            return False
        self.forget()
        self.sols[K], self.t[K] = sol, sol.t
        self.ref = (solution_runs(sol, self.lp.um, self.lp.slew), K)
        self.width, self.own = OWN_WIDTH, True
        return True

    def forget(self) -> None:
        """After new cuts: every probe may have changed."""
        self.sols.clear()
        self.t.clear()
        self.undecided.clear()

    def fewest(self, guess: int, lo: int) -> int:
        """Fewest ``K > lo`` with ``t(K) <= 1``: secant steps from ``guess``, bracketed, then bisection.

        Until a feasible count is found the steps grow geometrically (at most
        doubling the count, at least one more sample than the largest probe): a
        flat ``t`` (a secant crossing far away) cannot jump past the cap, and a
        cap reached this way is only reported (:class:`BeyondCap`), never read
        as "infeasible".  Every count claimed impossible is proved by :meth:`prove`.
        """
        K = max(guess, lo + 1)
        step = down = 1
        widths: list[int] = []
        for _ in range(200):
            self.probe(K)
            if len(self.undecided) >= 3 and not any(v <= 1.0 for v in self.t.values()):
                raise SolverError(
                    f"limited planner: HiGHS gave no verdict at {len(self.undecided)} sample counts "
                    f"({', '.join(str(k) for k in sorted(self.undecided)[:4])}); the limits are not proved "
                    "impossible; nothing is returned"
                )
            feas = [k for k, v in self.t.items() if v <= 1.0 and k > lo]
            hi = min(feas) if feas else None
            below = max([lo] + [k for k, v in self.t.items() if v > 1.0 and (hi is None or k < hi)])
            if hi is not None and hi <= below + 1:
                return hi
            cand = self._secant()
            if hi is None:
                top = max(self.t)
                cand = top + step if cand is None or cand <= top else min(cand, 2 * top + 1)
                cand = min(cand, max(self.K_cap, top + 1))  # the cap itself is probed before giving up
                step *= 2
            elif cand is None and below == lo:
                # one feasible count and nothing below it probed: the guess is usually within a sample or two
                # (extrapolated from the coarser levels), so step down from it, doubling, rather than bisect
                # towards ``lo`` (the unlimited optimum: hundreds of samples below at 1 kHz)
                cand = max(hi - down, lo + 1)
                down *= 2
            else:
                widths.append(hi - below)
                stalled = len(widths) >= 3 and widths[-1] > widths[-3] // 2
                if cand is None or stalled or not below < cand < hi or cand in self.t:
                    cand = (below + hi) // 2
                    widths.clear()
            K = cand
        raise SolverError("limited planner: the sample-count search did not converge")

    def _secant(self) -> int | None:
        x = self.crossing()
        if x is None:
            return None
        cand = math.ceil(x - 1e-9)
        if cand in self.t:
            cand = cand - 1 if self.t[cand] <= 1.0 else cand + 1
        return cand

    def crossing(self) -> float | None:
        """Real-valued ``K`` where the secant through the two probes nearest ``t = 1`` crosses 1."""
        pts = sorted(((k, v) for k, v in self.t.items() if math.isfinite(v)), key=lambda kv: abs(kv[1] - 1.0))[:2]
        if len(pts) < 2 or pts[0][1] == pts[1][1]:
            return None
        (k1, t1), (k2, t2) = pts
        s = (t2 - t1) / (k2 - k1)
        return k1 + (1.0 - t1) / s if s < 0.0 else None

    def reference(self, K: int, reach_first: bool = False) -> tuple:
        """Runs of the optimum at ``K`` for the next level: of the smoothest sequence in the same
        segments within :data:`REF_SLACK` of its ``t`` (a vertex chatters where a state rides its
        limit, with every sample free and in the free windows alike); the vertex's if that LP fails.

        ``reach_first``: with a deflection limit, first ask whether any sequence meets that LP's
        constraints (``mode="reach"``: the same rows, mid-interval ones included, no objective).  Its
        midpoint rows often make it infeasible at a coarse rate (the bench's all-three move at 15.6 and
        62.5 Hz), and the feasibility LP says so in about half the smooth LP's time (62.5 Hz: 0.05 against
        0.11 s CPU); where it is feasible the smooth LP follows (a few ms more at these sizes), so the
        planner asks it only of the levels before the one handing over to the final rate.
        """
        sol = self.sols[K]
        t_fix = sol.t * (1.0 + REF_SLACK)
        try:
            if reach_first and any(b.mode is not None for b in self.lp.blocks) and not self._reaches(K, t_fix):
                return solution_runs(sol, self.lp.um, self.lp.slew), K
            smooth = self.lp.solve(K, sol.segments, mode="smooth", t_fix=t_fix, start=sol)
        except SolverError:
            smooth = None
        if smooth is not None:
            sol = smooth
        return solution_runs(sol, self.lp.um, self.lp.slew), K

    def _reaches(self, K: int, t_fix: float) -> bool:
        """False only on HiGHS's verdict that no sequence in ``K``'s segments meets the smooth LP's rows
        (limits scaled by ``t_fix``, mid-interval rows included); no verdict counts as True."""
        try:
            sol = self.sols[K]
            return self.lp.solve(K, sol.segments, mode="reach", t_fix=t_fix, start=sol) is not None
        except LPUndecided:
            return True

    def prove(self, K: int) -> bool | ProofKind | str | None:
        """Is ``K`` proved infeasible?  The proof kind if so; False: ``K`` turned out feasible; None: not proved.

        The proof kind is a :class:`~flexmotion_ros.core.results.ProofKind`, or
        for a HiGHS verdict the text ``f"{ProofKind.HIGHS} ({method})"``.

        In order: the weak-duality bound of the probe's LP (lifted to every sample
        if it was a window LP; a second lift without the pull towards the window's
        multipliers if the first does not prove), the same from wider windows, and last the
        feasibility LP over every sample with the limits loosened by ``LOOSEN``
        (HiGHS's verdict).  The last step also runs when every sample was already
        free: its scaled LP said ``t > 1`` but a dual bound too weak to prove it.
        """
        if K in self.proofs:
            return self.proofs[K]
        res = self._prove(K)
        if res:
            self.proofs[K] = res
        return res

    def _prove(self, K: int) -> bool | ProofKind | str | None:
        lp = self.lp
        t = self.probe(K)
        if t <= 1.0:
            return False
        if K in self.undecided:
            return None
        sol = self.sols[K]
        if self.full or sol.segments.n_free == K:
            if proves_infeasible(dual_bound(lp, sol)[0]):
                return ProofKind.DUAL
        else:
            liftable = K * lp.sys.n <= LIFT_MAX_UNKNOWNS
            if liftable and any(
                proves_infeasible(dual_bound(lp, lift(lp, sol, own_weight=w))[0])
                for w in (OWN_WEIGHT, RETRY_OWN_WEIGHT)
            ):
                return ProofKind.DUAL  # the second lift (no pull towards the window's multipliers) only if needed
            # wider windows around this structure, lifted again; then every sample free
            try:
                wide = lp.solve(K, map_runs(self.ref[0], self.ref[1], K, WIDE * max(self.width, OWN_WIDTH)))
            except LPUndecided:
                wide = None
            if wide is not None:
                if wide.t <= 1.0:
                    self.sols[K], self.t[K] = wide, wide.t
                    return False
                if liftable and proves_infeasible(dual_bound(lp, lift(lp, wide))[0]):
                    return ProofKind.DUAL
        # every sample free: the feasibility LP with every limit loosened by LOOSEN (so that "infeasible"
        # is not a rounding artefact).  Its scaled twin (min t) is the same size but 100x slower in HiGHS's
        # interior-point method (1 kHz deflection limit: 160 s against 0.7 s).
        if K > FULL_LP_MAX_SAMPLES or time.perf_counter() > self.deadline:
            return None  # the full LP would take many seconds: K stays unproved (reported, not hidden)
        try:
            full = lp.solve(K, mode="feasible", t_fix=1.0 + LOOSEN)
        except LPUndecided:
            return None  # no verdict: K - 1 stays unproved (the count is reported not proved fewest)
        if full is None:
            # one method's verdict on one formulation: a proof only if the independent formulation agrees
            said, method = independent_feasible(
                lp.problem, K, lp.dt, lp.limits, scale=1.0 + LOOSEN, cuts=lp.cuts, deadline=self.deadline
            )
            if said is False:
                return (
                    f"{ProofKind.HIGHS} ({lp.infeasible_method}, confirmed by an independent state-space LP ({method}))"
                )
            return None
        self.sols[K], self.t[K] = full, 1.0
        return False


class OutOfTime(Exception):
    """The planning-time budget ran out (no claim about any count)."""


class BeyondCap(Exception):
    """The search reached ``K_cap`` samples without a feasible count (no claim about larger counts)."""


def extrapolate(times: list[tuple[float, float]], dt: float) -> float:
    """``T(dt)`` extrapolated linearly from the last two levels (the ZOH error is first order in ``dt``)."""
    if len(times) == 1:
        return times[0][1]
    (d1, t1), (d2, t2) = times[-2], times[-1]
    return t2 + (t2 - t1) / (d2 - d1) * (dt - d2)
