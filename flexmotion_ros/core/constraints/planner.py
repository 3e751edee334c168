"""Fewest samples under velocity, deflection and slew-rate limits: the search over sample counts.

Real machines add limits the bang-bang theory ignores
(:class:`~flexmotion_ros.core.limit_checks.Limits`).  For ``K`` samples the
limits and the exact arrival are linear constraints; ``t*(K)``, the smallest
common scale of every limit (command bound included) that ``K`` samples
need, is non-increasing in ``K`` (a move can hold zero one sample longer: the
target is an equilibrium, every limit holds at rest and the slew limit
already admits the step to 0), and ``K`` samples work iff ``t*(K) <= 1``
(:mod:`.limit_lp`).  The fewest samples are the first ``K`` with ``t* <= 1``,
found by a secant on ``t*`` from a good guess, bracketed and bisected.

Speed (as :mod:`.zoh`)
----------------------
An LP with all ``K`` commands costs seconds at 1 kHz.  So:

1. *Levels*: the count is first found at rates 4, 16, ... times lower, the
   coarsest with at most :data:`FULL_SAMPLES` samples and every sample free.
2. Each finer level takes the *structure* of the coarser optimum
   (:mod:`.limit_structure`: runs at full force, riding a limit at a constant
   level, or on a slew ramp) and solves LPs with only windows around the
   changes free; runs share one level variable each.  The real-valued
   crossing ``t* = 1`` of the coarser levels, extrapolated linearly in
   ``dt``, is the first guess.  After the first probe at a level its own
   solution gives the runs and the windows narrow.
3. A window solution with ``t <= 1`` is feasible, full stop (its commands
   are checked exactly below).  ``K - 1`` samples are proved impossible
   by the weak-duality bound over ALL samples (:mod:`.limit_dual`), with
   multipliers lifted from the window solution's primal; if that bound does
   not exceed 1, wider windows, and then the feasibility LP with every
   sample free and every limit loosened by :data:`LOOSEN` decide (there the
   proof is HiGHS's infeasibility verdict, not an independently checked
   certificate: deflection limits usually end here, their lifted bounds are
   weak).

Exactness: the accepted sequence is the smoothest one (total variation;
under a slew limit alone any vertex) in the final structure with every state and slew limit tightened by ``1e-7``;
its arrival is corrected to rounding and every limit is checked at and
between the samples on the exact matrix-exponential simulation.  A
deflection peak between samples above its limit becomes a cut (a
necessary condition) and the search resumes; proofs made before a cut stay
valid (they were for a relaxation).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

from ..errors import GoalError, SolverError, UnreachableError
from ..model.boundary import MoveProblem
from ..model.modal_model import check_positive
from ..results import ProofKind, SampledProfile
from ..sampled.check import verified_samples
from ..sampled.zoh import plan_time_optimal_zoh
from .certify import feasible as independent_feasible
from .certify import prefix_feasible
from .dual import dual_bound, lift, proves_infeasible
from .limits import Limits, check_limits
from .lp import LimitLP, LPSolution, LPUndecided, Segments
from .structure import map_runs, solution_runs

#: Give up (raise) beyond this many times the unlimited sample count.
MAX_FACTOR = 64
#: Planning-time budget (s): past it the planner stops and says so (SolverError), it claims nothing.
TIME_BUDGET_S = 120.0
#: ... or this many samples more, whichever is larger (short moves).
CAP_EXTRA = 1000
#: Beyond this many times the unlimited count, the search first tries to prove the limits impossible.
SOFT_FACTOR = 8
MAX_CUT_ROUNDS = 12
#: Levels: rates a factor COARSE_FACTOR apart; the coarsest has at most FULL_SAMPLES samples, all free.
COARSE_FACTOR = 4
FULL_SAMPLES = 160
#: Window half-widths (samples): mapped from the coarser level (in its samples), or from the same rate.
MAP_WIDTH = 2
OWN_WIDTH = 4
#: Fallback windows are this many times wider (before every sample is freed).
WIDE = 4
#: The last-resort infeasibility proof loosens every limit by this (relative; above HiGHS's 1e-10 feasibility tolerance).
LOOSEN = 1e-9


@dataclass
class LimitedProfile:
    """The fewest-sample move under limits.

    Attributes
    ----------
    sampled : SampledProfile
        The commands (``method = "limited"``), checked exactly.
    limits : Limits
    unlimited_samples : int
        The ZOH optimum without limits (proved fewest by :func:`plan_time_optimal_zoh`).
    lower_bound_samples : int
        No sequence with fewer samples satisfies every limit: proved by the
        unlimited ZOH optimum, a weak-duality bound above 1 or HiGHS's
        infeasibility verdict (``extra["lower_bound_proof"]`` says which).
    minimal : bool
        ``sampled.samples == lower_bound_samples``.
    added_time_s : float
        Extra move time over the unlimited ZOH optimum (s).
    peaks : dict
        Exact maxima over the whole move, between samples included.
    lp_solves, cuts : int
    """

    sampled: SampledProfile
    limits: Limits
    unlimited_samples: int
    lower_bound_samples: int
    minimal: bool
    added_time_s: float
    peaks: dict
    lp_solves: int
    cuts: int
    solve_time_s: float = 0.0
    extra: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {
            "limits": self.limits.to_dict(),
            "unlimited_samples": self.unlimited_samples,
            "limited_samples": self.sampled.samples,
            "limited_lower_bound_samples": self.lower_bound_samples,
            "limited_minimal": self.minimal,
            "added_time_s": self.added_time_s,
            "peaks": self.peaks,
            "lp_solves": self.lp_solves,
            "cuts": self.cuts,
            "lower_bound_proof": str(self.extra.get("lower_bound_proof", "")),
        }


class _Level:
    """Probes ``t(K)`` at one rate: every sample free, or windows around a reference structure.

    ``t(K)`` from a window LP is an upper bound on ``t*(K)`` (a restriction);
    ``t(K) <= 1`` shows ``K`` feasible.  No bound here claims a count
    infeasible (that is :func:`_prove`'s job); only a rate at which the target
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
                raise _OutOfTime(K)
            if K > self.K_cap:
                raise _BeyondCap(K)
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
        cap reached this way is only reported (:class:`_BeyondCap`), never read
        as "infeasible".  Every count claimed impossible is proved by :func:`_prove`.
        """
        K = max(guess, lo + 1)
        step = 1
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

    def reference(self, K: int) -> tuple:
        """Runs of the optimum at ``K`` for the next level; with every sample free, of the smoothest
        sequence at the same ``t`` (a vertex chatters where a state rides its limit)."""
        sol = self.sols[K]
        if self.full:
            try:
                smooth = self.lp.solve(K, Segments.all_free(K), mode="smooth", t_fix=sol.t * (1.0 + 1e-5))
            except SolverError:
                smooth = None
            if smooth is not None:
                sol = smooth
        return solution_runs(sol, self.lp.um, self.lp.slew), K


class _OutOfTime(Exception):
    """The planning-time budget ran out (no claim about any count)."""


class _BeyondCap(Exception):
    """The search reached ``K_cap`` samples without a feasible count (no claim about larger counts)."""


def _extrapolate(times: list[tuple[float, float]], dt: float) -> float:
    """``T(dt)`` extrapolated linearly from the last two levels (the ZOH error is first order in ``dt``)."""
    if len(times) == 1:
        return times[0][1]
    (d1, t1), (d2, t2) = times[-2], times[-1]
    return t2 + (t2 - t1) / (d2 - d1) * (dt - d2)


#: How a lower bound on the sample count was proved (``LimitedProfile.extra["lower_bound_proof"]``):
#: aliases of the :class:`~flexmotion_ros.core.results.ProofKind` members (``str`` values).
PROOF_UNLIMITED = ProofKind.UNLIMITED
PROOF_DUAL = ProofKind.DUAL
PROOF_HIGHS = ProofKind.HIGHS


def _prove(level: _Level, K: int) -> bool | ProofKind | str | None:
    """Is ``K`` proved infeasible?  The proof kind if so; False: ``K`` turned out feasible; None: not proved.

    The proof kind is a :class:`~flexmotion_ros.core.results.ProofKind`, or
    for a HiGHS verdict the text ``f"{ProofKind.HIGHS} ({method})"``.

    In order: the weak-duality bound of the probe's LP (lifted to every sample
    if it was a window LP), the same from wider windows, and last the
    feasibility LP over every sample with the limits loosened by ``LOOSEN``
    (HiGHS's verdict).  The last step also runs when every sample was already
    free: its scaled LP said ``t > 1`` but a dual bound too weak to prove it.
    """
    lp = level.lp
    t = level.probe(K)
    if t <= 1.0:
        return False
    if K in level.undecided:
        return None
    sol = level.sols[K]
    if level.full or sol.segments.n_free == K:
        if proves_infeasible(dual_bound(lp, sol)[0]):
            return ProofKind.DUAL
    else:
        liftable = K * lp.sys.n <= LIFT_MAX_UNKNOWNS
        if liftable and proves_infeasible(dual_bound(lp, lift(lp, sol))[0]):
            return ProofKind.DUAL
        # wider windows around this structure, lifted again; then every sample free
        try:
            wide = lp.solve(K, map_runs(level.ref[0], level.ref[1], K, WIDE * max(level.width, OWN_WIDTH)))
        except LPUndecided:
            wide = None
        if wide is not None:
            if wide.t <= 1.0:
                level.sols[K], level.t[K] = wide, wide.t
                return False
            if liftable and proves_infeasible(dual_bound(lp, lift(lp, wide))[0]):
                return ProofKind.DUAL
    # every sample free: the feasibility LP with every limit loosened by LOOSEN (so that "infeasible"
    # is not a rounding artefact).  Its scaled twin (min t) is the same size but 100x slower in HiGHS's
    # interior-point method (1 kHz deflection limit: 160 s against 0.7 s).
    if K > FULL_LP_MAX_SAMPLES or time.perf_counter() > level.deadline:
        return None  # the full LP would take many seconds: K stays unproved (reported, not hidden)
    try:
        full = lp.solve(K, mode="feasible", t_fix=1.0 + LOOSEN)
    except LPUndecided:
        return None  # no verdict: K - 1 stays unproved (the count is reported not proved fewest)
    if full is None:
        # one method's verdict on one formulation: a proof only if the independent formulation agrees
        said, method = independent_feasible(
            lp.problem, K, lp.dt, lp.limits, scale=1.0 + LOOSEN, cuts=lp.cuts, deadline=level.deadline
        )
        if said is False:
            return f"{ProofKind.HIGHS} ({lp.infeasible_method}, confirmed by an independent state-space LP ({method}))"
        return None
    level.sols[K], level.t[K] = full, 1.0
    return False


#: No LP with every sample free (proof or re-anchoring) above this many samples: at 4,000 samples the
#: feasibility LP and its independent confirmation take 5-30 s on a loaded machine, at 13,000 one LP
#: takes 10 s and more; beyond it a count the dual bounds cannot settle is left unproved (and says so).
FULL_LP_MAX_SAMPLES = 3000
#: Lifting window multipliers to every sample is one sparse LU of about ``K n`` unknowns: at 42,000
#: (4,200 samples, 10 states) it takes 10 s; above this the lifted bound is not tried.
LIFT_MAX_UNKNOWNS = 30000
#: Times the search may re-anchor its windows on an exact optimum when they proved misleading.
MAX_ANCHORS = 2
#: The prefix of the impossibility proof covers at most this many samples.
PREFIX_SAMPLES = 4000


def _prove_impossible(problem: MoveProblem, dt: float, limits: Limits, K: int, exc: _BeyondCap) -> None:
    """Raise :class:`GoalError` if no move of any length meets the limits (proved), else return.

    The proof: the limits cannot be held even over the first ``M`` samples
    with no arrival asked, and both HiGHS methods agree on the independent
    state-space formulation (:func:`.certify.prefix_feasible`).  A ``K``-sample
    move held at rest after its arrival would hold them, so none exists.
    """
    M = min(K, PREFIX_SAMPLES)
    said, method = prefix_feasible(problem, M, dt, limits, scale=1.0 + LOOSEN)
    if said is False:
        names = ", ".join(f"limits.{n}" for n in limits.active)
        raise GoalError(
            names,
            f"no move satisfies the limits: from this initial state they are broken within {M} samples "
            f"({M * dt:.4g} s) whatever the command (proved: {method} on the state-space LP); relax them",
        ) from exc


def _not_found(limits: Limits, K_cap: int, rate: float, exc: _BeyondCap) -> None:
    """Nothing found up to the hard cap and nothing proved impossible: say exactly that."""
    names = ", ".join(f"limits.{n}" for n in limits.active)
    raise SolverError(
        f"limited planner: no sequence found up to {K_cap} samples ({K_cap / rate:.4g} s, {MAX_FACTOR} x the "
        f"unlimited move) and the limits ({names}) are not proved impossible; nothing is returned"
    ) from exc


def _accept(level: _Level, K: int):
    """The smoothest sequence at ``K`` in ``K``'s structure, exact arrival, exact checks; cuts added on the way.

    Returns ``(u, peaks)``, or None (no sequence here: try more samples), or ``"cuts"`` (new cuts: search again).
    """
    lp = level.lp
    seg = level.sols[K].segments
    for _attempt in ("this structure", "every sample free"):
        try:
            sol = lp.solve(K, seg, mode="smooth")
            if sol is None and seg.n_free < K:
                sol = lp.solve(K, mode="smooth")
        except LPUndecided:
            sol = None
        if sol is None:
            return None
        u = lp.exact_commands(sol.u)
        peaks, cuts, ok = check_limits(lp.model, lp.problem.x0, u, lp.dt, lp.limits)
        if cuts:
            lp.cuts.extend(cuts)
            return "cuts"
        if ok:
            return u, peaks
        seg = Segments.all_free(K)  # a sample limit missed after the correction: the full LP
    return None


def plan_limited_zoh(
    problem: MoveProblem,
    rate_hz: float,
    limits: Limits,
    unlimited: SampledProfile | None = None,
) -> LimitedProfile:
    """Fewest zero-order-hold samples at ``rate_hz`` reaching rest exactly under ``limits``.

    Raises
    ------
    FlexmotionError
        A limit out of range, or an initial state already outside a limit.
    GoalError
        The limits are proved impossible (broken within the first samples whatever the command).
    SolverError
        No sequence passed the exact checks, none was found up to ``MAX_FACTOR`` times the unlimited
        count, or the ``TIME_BUDGET_S`` planning budget ran out; none of these claims the limits impossible.
    """
    try:
        return _plan_limited(problem, rate_hz, limits, unlimited)
    except _OutOfTime as exc:
        raise SolverError(
            f"limited planner: no plan within the {TIME_BUDGET_S:g} s planning budget (the search reached "
            f"{exc.args[0]} samples); the limits are not proved impossible; nothing is returned"
        ) from exc


def _plan_limited(problem: MoveProblem, rate_hz: float, limits: Limits, unlimited: SampledProfile | None):
    t0 = time.perf_counter()
    rate = check_positive("rate_hz", rate_hz, "Hz")
    dt = 1.0 / rate
    limits = limits.validated(problem.model)
    lp = LimitLP(problem, dt, limits)  # validates the initial state against the limits
    if unlimited is None:
        unlimited = plan_time_optimal_zoh(problem, rate)
    K0 = unlimited.samples
    if not limits.active or K0 == 0:
        prof = verified_samples(
            problem, unlimited.commands, dt, "limited", unlimited.minimal, unlimited.lower_bound_samples, None, {}, t0
        )
        peaks, _, _ = check_limits(problem.model, problem.x0, unlimited.commands, dt, limits)
        return LimitedProfile(
            prof,
            limits,
            K0,
            unlimited.lower_bound_samples,
            unlimited.minimal,
            0.0,
            peaks,
            0,
            0,
            time.perf_counter() - t0,
        )
    proved = K0 if unlimited.minimal else unlimited.lower_bound_samples  # every K < proved is infeasible
    deadline = t0 + TIME_BUDGET_S
    K_cap = max(K0 * MAX_FACTOR, K0 + CAP_EXTRA)
    K_soft = max(K0 * SOFT_FACTOR, K0 + CAP_EXTRA // 10)  # beyond this, first try to prove the limits impossible
    T_star = unlimited.continuous.duration if unlimited.continuous is not None else (proved - 1) * dt
    # levels, coarsest first
    rates = [rate]
    while K0 * rates[0] / rate > FULL_SAMPLES:
        rates.insert(0, rates[0] / COARSE_FACTOR)
    ref, times, solves, skipped = None, [], 0, []
    level = None
    for r in rates:
        final = r == rate
        width = 0 if ref is None else MAP_WIDTH * COARSE_FACTOR + 2
        level = _Level(problem, r, limits, round(K_soft * r / rate) + 10, lp if final else None, ref, width)
        level.reachable = K0 if final else None
        level.deadline = level.lp.deadline = deadline
        lo = max(proved - 1, 0) if final else max(math.ceil(T_star * r * (1.0 - 1e-12)) - 1, 0)
        guess = math.ceil(_extrapolate(times, 1.0 / r) * r - 1e-9) if times else lo + 1
        try:
            K = level.fewest(guess, lo)
        except _BeyondCap as exc:
            if not final:
                ref = None  # this coarse rate finds nothing below the soft cap: skip it (it only guides)
                skipped.append(r)
                solves += level.lp.solves
                continue
            # nothing up to the soft cap: impossible (proved) or keep searching up to the hard cap
            _prove_impossible(problem, dt, limits, K_soft, exc)
            level.K_cap = K_cap
            try:
                K = level.fewest(max(level.t) + 1, lo)
            except _BeyondCap as exc2:
                _not_found(limits, K_cap, rate, exc2)
        except UnreachableError:
            if final:
                raise
            # a coarse rate the user never asked for cannot steer a mode, or finds nothing below
            # the cap: skip it (it only guides the search)
            ref = None
            skipped.append(r)
            solves += level.lp.solves
            continue
        x = level.crossing()
        times.append((1.0 / r, (x if x is not None and K - 1 <= x <= K else K) / r))
        if not final:
            ref = level.reference(K if K - 1 not in level.sols else K - 1)
            solves += level.lp.solves
    coarse_time = time.perf_counter() - t0
    accepted = None
    reject = proved - 1  # counts up to here are out: proved infeasible, or no sequence passed the checks
    proof = ProofKind.UNLIMITED
    rounds = 2 * MAX_CUT_ROUNDS
    anchors = 0
    for _ in range(rounds):
        # the proof for K - 1, moving down while K - 1 turns out feasible
        while K - 1 >= proved and K - 1 > reject:
            res = _prove(level, K - 1)
            if res is False:
                K -= 1
                if anchors < MAX_ANCHORS and level.anchor(K):
                    # the windows misled the search (a coarse level's structure was wrong): search
                    # again around the exact optimum at K instead of stepping down one sample at a time
                    anchors += 1
                    try:
                        K = level.fewest(K, max(proved - 1, reject))
                    except _BeyondCap as exc:  # cannot happen below a feasible K; kept honest anyway
                        _not_found(limits, K_cap, rate, exc)
                continue
            if res:
                proved, proof = K, res
            break
        res = _accept(level, K)
        if isinstance(res, tuple):
            accepted = (K, *res)
            break
        try:
            if res == "cuts":  # the relaxation changed: search again from K
                level.forget()
                K = level.fewest(K, max(proved - 1, reject))
            else:  # feasible only within the margin: one more sample
                reject = K
                K = level.fewest(K + 1, K)
        except _BeyondCap as exc:
            _not_found(limits, K_cap, rate, exc)
    if accepted is None:
        raise SolverError(
            f"limited planner: no sequence passed the exact limit checks in {rounds} rounds "
            f"({len(lp.cuts)} deflection cuts added, counts up to {reject} rejected); the limits are not proved "
            "impossible; nothing is returned"
        )
    K, u, peaks = accepted
    minimal = K == proved
    prof = verified_samples(problem, u, dt, "limited", minimal, proved, None, {}, t0)
    return LimitedProfile(
        sampled=prof,
        limits=limits,
        unlimited_samples=K0,
        lower_bound_samples=proved,
        minimal=bool(minimal),
        added_time_s=(prof.samples - K0) * dt,
        peaks=peaks,
        lp_solves=lp.solves + solves,
        cuts=len(lp.cuts),
        solve_time_s=time.perf_counter() - t0,
        extra={
            "levels_hz": [r for r in rates if r not in skipped],
            "skipped_levels_hz": skipped,
            "coarse_time_s": coarse_time,
            "lower_bound_proof": proof,
            "free_samples": int(level.sols[K].segments.n_free) if K in level.sols else K,
        },
    )
