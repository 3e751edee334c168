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
   sample free and every limit loosened by :data:`.proof.LOOSEN` decide (there the
   proof is HiGHS's infeasibility verdict, not an independently checked
   certificate: deflection limits usually end here, their lifted bounds are
   weak).
4. At the final rate the extrapolated count ``K`` is not probed by itself when ``K - 1``'s window
   LP is above 1 and the coarser level's slope puts ``K`` below: the accepted smooth LP at ``K``
   decides (:func:`.accept.accept_predicted`).

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

from ..errors import SolverError, UnreachableError
from ..model.boundary import MoveProblem
from ..model.modal_model import check_positive
from ..results import ProofKind, SampledProfile
from ..sampled.check import verified_samples
from ..sampled.zoh import plan_time_optimal_zoh
from .accept import accept, accept_predicted
from .level import MAP_WIDTH, BeyondCap, Level, OutOfTime, extrapolate
from .limits import Limits, check_limits
from .lp import LimitLP
from .proof import prove_impossible

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
#: Times the search may re-anchor its windows on an exact optimum when they proved misleading.
MAX_ANCHORS = 2


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


def _not_found(limits: Limits, K_cap: int, rate: float, exc: BeyondCap) -> None:
    """Nothing found up to the hard cap and nothing proved impossible: say exactly that."""
    names = ", ".join(f"limits.{n}" for n in limits.active)
    raise SolverError(
        f"limited planner: no sequence found up to {K_cap} samples ({K_cap / rate:.4g} s, {MAX_FACTOR} x the "
        f"unlimited move) and the limits ({names}) are not proved impossible; nothing is returned"
    ) from exc


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
    except OutOfTime as exc:
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
    ref, seed, times, solves, skipped = None, None, [], 0, []
    profile = predicted = slope = None
    level = None
    for r in rates:
        final = r == rate
        width = 0 if ref is None else MAP_WIDTH * COARSE_FACTOR + 2
        level = Level(problem, r, limits, round(K_soft * r / rate) + 10, lp if final else None, ref, width)
        level.lp.coarse_rows = seed
        level.lp.coarse_profile = profile
        level.reachable = K0 if final else None
        level.deadline = level.lp.deadline = deadline
        lo = max(proved - 1, 0) if final else max(math.ceil(T_star * r * (1.0 - 1e-12)) - 1, 0)
        guess = math.ceil(extrapolate(times, 1.0 / r) * r - 1e-9) if times else lo + 1
        if final:
            coarse_time = time.perf_counter() - t0
        try:
            predicted = accept_predicted(level, guess, lo, slope) if final else None
            K = predicted[0] if predicted is not None else level.fewest(guess, lo)
        except BeyondCap as exc:
            if not final:
                ref = seed = None  # this coarse rate finds nothing below the soft cap: skip it (it only guides)
                skipped.append(r)
                solves += level.lp.solves
                continue
            # nothing up to the soft cap: impossible (proved) or keep searching up to the hard cap
            prove_impossible(problem, dt, limits, K_soft, exc)
            level.K_cap = K_cap
            try:
                K = level.fewest(max(level.t) + 1, lo)
            except BeyondCap as exc2:
                _not_found(limits, K_cap, rate, exc2)
        except UnreachableError:
            if final:
                raise
            # a coarse rate the user never asked for cannot steer a mode, or finds nothing below
            # the cap: skip it (it only guides the search)
            ref = seed = None
            skipped.append(r)
            solves += level.lp.solves
            continue
        x = level.crossing()
        times.append((1.0 / r, (x if x is not None and K - 1 <= x <= K else K) / r))
        if not final:
            # the final rate's windows come from this level's answer (the fewest feasible count), the
            # coarser levels' from K - 1 as before.  At K - 1 a level's first probe still has its wide
            # mapped windows (the bench's all-three move: 564 free samples at 250 Hz against 290, the
            # reference LP 0.75 s against 0.2 s), and at 1 kHz the K - 1 window solution did not lift to
            # a proof without the wider fallback LP (1,048 free samples, 1.7 s); taken at K for every
            # level, the seed-18 fuzz's case 186 ended 15 samples longer (unproved either way)
            handoff = r * COARSE_FACTOR == rate
            ref = level.reference(K if handoff or K - 1 not in level.sols else K - 1, reach_first=not handoff)
            seed = (level.lp.run_rows[ref[1]], ref[1]) if ref[1] in level.lp.run_rows else None
            profile = level.lp.profile
            solves += level.lp.solves
            # t's slope per sample at the next rate (a sample there is 1 / COARSE_FACTOR of one here)
            near = [level.t.get(k, math.inf) for k in (K - 1, K)]
            slope = (near[1] - near[0]) / COARSE_FACTOR if all(map(math.isfinite, near)) else None
    accepted = None
    reject = proved - 1  # counts up to here are out: proved infeasible, or no sequence passed the checks
    proof = ProofKind.UNLIMITED
    rounds = 2 * MAX_CUT_ROUNDS
    anchors = 0
    if predicted is not None:  # accepted at the predicted count, its K - 1 proved (or not) as below
        K, res, got = predicted
        accepted = (K, *got)
        if res:
            proved, proof = K, res
    for _ in range(0 if accepted is not None else rounds):
        # the proof for K - 1, moving down while K - 1 turns out feasible
        while K - 1 >= proved and K - 1 > reject:
            res = level.prove(K - 1)
            if res is False:
                K -= 1
                if anchors < MAX_ANCHORS and level.anchor(K):
                    # the windows misled the search (a coarse level's structure was wrong): search
                    # again around the exact optimum at K instead of stepping down one sample at a time
                    anchors += 1
                    try:
                        K = level.fewest(K, max(proved - 1, reject))
                    except BeyondCap as exc:  # cannot happen below a feasible K; kept honest anyway
                        _not_found(limits, K_cap, rate, exc)
                continue
            if res:
                proved, proof = K, res
            break
        res = accept(level, K)
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
        except BeyondCap as exc:
            _not_found(limits, K_cap, rate, exc)
    if accepted is None:
        raise SolverError(
            f"limited planner: no sequence passed the exact limit checks in {rounds} rounds "
            f"({len(lp.cuts)} deflection cuts added, counts up to {reject} rejected); the limits are not proved "
            "impossible; nothing is returned"
        )
    K, u, peaks, accepted_free = accepted
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
            # the final probe's windows (at K, or at K - 1 when K was predicted and not probed)
            "free_samples": next((int(level.sols[k].segments.n_free) for k in (K, K - 1) if k in level.sols), K),
            "accepted_free_samples": int(accepted_free),
        },
    )
