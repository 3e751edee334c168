"""The solver's fallbacks when its co-state iterations end on a structure that misses the target.

The optimum then usually differs from that structure by a narrow pair of
switches (a notch) that the switching function cannot show: its sign there
is below rounding.  The final state, however, is a smooth, well-scaled
function of the switch times.

Both solve the final-state conditions alone for a structure with a notch
(:func:`~.switch_newton.primal_newton`), then hand each candidate to the one
check every profile passes (the solver's ``assemble``, passed in: exact
simulation and certificate; a miss raises :class:`SolverError`):

* :func:`cluster_fallback`: a switch split into a triple, when the duration
  is already within ``GAP_RTOL`` of the proved lower bound (a notch below
  rounding: certified by the gap, or fully if the co-state can be had);
* :func:`structure_fallback`: a bounded structure search
  (:func:`notch_candidates`): a fixed, small set of structures, each a known
  one (the solver's, the rigid body's) with one notch added at one of
  :data:`LOCATIONS` places or one switch split into ``2 m + 1``; the work is
  at most ``len(bases) x (LOCATIONS + switches) x len(WIDTHS)`` Newton runs of
  :data:`NEWTON_STEPS` steps, whatever the model.  The first certified
  candidate is returned (a certified extremal is the optimum), else the
  shortest exact one with the proved bound it has.

When nothing reaches the target, :func:`refusal_reason` words what the
refusal can still say (the proved bound, what plans such a move).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import SolverError
from ..results import BangBangProfile, CertificateStatus, SolverPath
from ..tolerances import GAP_RTOL, SWITCH_TIME_RTOL
from .costate_lp import widest_costate
from .dual_bound import REPORT_GAPS, proved_lower_bound
from .reachable_set import Shooting
from .rigid_body import rigid_profile
from .switch_newton import primal_newton, refine_switches, split_candidates

#: Places (fractions of ``T``) tried for an added notch.
LOCATIONS = 24
#: Notch half-widths tried (relative to ``T``).
WIDTHS = (1e-3, 1e-2)
#: Newton steps per structure.
NEWTON_STEPS = 15
#: Two candidates with durations this close (relative) and the same number of
#: switches, every switch as close, are one.
SAME_RTOL = 1e-9
#: Rounds of cutting planes (samples where the last co-state's ``S`` changed sign off the
#: switches) when the widest co-state of a structure has extra sign changes.
CUT_ROUNDS = 3
#: A proved zero of ``S`` farther than this (relative to ``T``) from every switch is an extra one.
CUT_RTOL = 1e-9


def notch_candidates(sh: Shooting, bases: list[tuple[np.ndarray, float]], T: float):
    """Structures reaching the target, from ``bases`` plus one notch: yields ``(T, roots, sign0)`` as found.

    Parameters
    ----------
    sh : Shooting
        The problem (state scale for durations near ``T``).
    bases : list of (ndarray, float)
        Known structures: switch times-to-go (s, increasing) and the sign of
        ``S`` before the first.
    T : float
        Duration (s) the bases belong to.

    Yields
    ------
    tuple of (float, ndarray, float)
        Duration (s), switch times-to-go (s) and first sign of each distinct
        structure whose final state the Newton run brought below
        ``POLISH_TOL``.  A generator: the caller stops at the first one it
        certifies (a certified extremal is the optimum, whatever the order).
    """
    found: list[tuple[float, np.ndarray, float]] = []
    for roots, sign0 in bases:
        for cand in _with_a_notch(roots, T, sh.s.size):
            if not (cand[0] > 0.0 and cand[-1] < T and np.all(np.diff(cand) > 0.0)):
                continue
            ok, tau, T_c, _ = primal_newton(sh, cand, sign0, T, max_iter=NEWTON_STEPS)
            if ok and not any(_same(T_c, tau, sign0, f) for f in found):
                found.append((T_c, tau, sign0))
                yield T_c, tau, sign0


def _with_a_notch(roots: np.ndarray, T: float, n: int):
    """``roots`` with notches added: enough switches for ``n`` final-state conditions (``L + 1 >= n``).

    One pair short: a narrow pair at one of :data:`LOCATIONS` places, or one
    switch split into three.  More pairs short (several modes tuned near
    whole periods at once): one switch split into ``2 m + 1`` equally spaced.
    """
    m = max(1, -(-(n - 1 - roots.size) // 2))  # pairs needed, at least one
    places = (np.arange(LOCATIONS) + 0.5) / LOCATIONS * T
    for w in WIDTHS:
        d = w * T
        if m == 1:
            for c in places:
                yield np.sort(np.concatenate([roots, [c - d, c + d]]))
        offsets = d * np.arange(-m, m + 1)
        for j in range(roots.size):
            yield np.sort(np.concatenate([np.delete(roots, j), roots[j] + offsets]))


def _same(T_c: float, tau: np.ndarray, sign0: float, other: tuple[float, np.ndarray, float]) -> bool:
    T_o, tau_o, sign_o = other
    return (
        sign0 == sign_o
        and tau.size == tau_o.size
        and abs(T_c - T_o) <= SAME_RTOL * T_c
        and bool(np.all(np.abs(tau - tau_o) <= SAME_RTOL * T_c))
    )


def cluster_fallback(problem, system, sh, nuh, T, roots, signs, t0, T_low, assemble) -> BangBangProfile | None:
    """A switch split into a notch below rounding, solved on the final state alone, certified by the gap.

    When the co-state iterations end on a structure that misses the target
    (the final-state error is real, measured by the exact simulation) while
    ``T`` is already within :data:`GAP_RTOL` of the proved lower bound, the
    optimum has a cluster of switches whose switching-function sign is below
    rounding (e.g. a two-mass machine tuned near ``omega T = 4 pi``: a notch
    of a few microseconds at the rigid switch).  Its switch times are found
    from the final-state conditions alone (:func:`primal_newton`); the
    profile is returned only if it passes the exact final-state check and is
    within ``GAP_RTOL`` of the lower bound (the certificate then says so:
    ``within_gap``).
    """
    if not T - T_low <= GAP_RTOL * T or roots.size == 0:
        return None
    for cand, sign0 in split_candidates(roots, float(signs[0]), T):
        ok, tau, T_c, _ = primal_newton(sh, cand, sign0, T)
        if not ok or not T_c - T_low <= GAP_RTOL * T_c:
            continue
        signs_c = sign0 * (1.0 - 2.0 * (np.arange(tau.size + 1) % 2))
        # a full Pontryagin certificate where the co-state can still be had
        # (a notch wide enough for S to resolve): switch-time Newton from here
        ok2, tau2, nuh2, T2, _ = refine_switches(sh, tau, sign0, nuh, T_c)
        if ok2 and T2 - T_low <= GAP_RTOL * T2:
            try:
                profile = assemble(problem, system, nuh2 / sh.s, T2, tau2, signs_c, t0, sh.evaluations, T_low)
                if profile.certificate.status is CertificateStatus.OPTIMAL:
                    profile.extra["solver_path"] = SolverPath.CLUSTER
                    return profile
            except SolverError:
                pass
        try:
            profile = assemble(problem, system, nuh / sh.s, T_c, tau, signs_c, t0, sh.evaluations, T_low)
        except SolverError:
            continue
        if profile.certificate.passed:
            profile.extra["solver_path"] = SolverPath.CLUSTER
            return profile
    return None


def structure_fallback(problem, system, sh, nuh, T, roots, signs, t0, T_low, assemble) -> BangBangProfile | None:
    """The bounded structure search (:func:`notch_candidates`) when the co-state iterations missed the target.

    Candidates reaching the target are tried shortest first: the switch-time
    Newton with the co-state from there, then the exact simulation and the
    certificate.  The first certified one is returned.  If none certifies
    (a notch whose switching-function sign is below rounding, and too far
    from the rigid body's bound for the gap to prove it), the shortest one
    that passes the exact final-state check is returned, not certified, its
    certificate message stating the proved bound it has: ``T`` is within
    ``(T - T_low) / T`` of the rigid body's minimum time.
    """
    rigid = rigid_profile(problem.model, problem.u_max, sh.x0, problem.include_position)
    bases = [(roots, float(signs[0]))]
    if rigid.switch_times.size or rigid.duration > 0.0:
        bases.append((np.sort(rigid.duration - rigid.switch_times), float(np.sign(rigid.levels[-1]))))
    best = None  # the shortest candidate that reaches the target, if none certifies
    for T_c, tau, sign0 in notch_candidates(sh, bases, T):
        signs_c = sign0 * (1.0 - 2.0 * (np.arange(tau.size + 1) % 2))
        ok, tau2, nuh2, T2, _ = refine_switches(sh, tau, sign0, nuh, T_c)
        kept = without_rounding_pairs(tau2, T2) if ok else tau2
        signs2 = signs_c
        if kept.size < tau2.size:
            # converged with a pair of switches merged by rounding (a zero-width blip the certificate
            # rejects): the extremal without it, Newton again (issue 15: a replan 1e-6 off the plan, whose
            # notch candidates converged to the optimum's 7 switches plus such a pair, none certified)
            ok, tau2, nuh2, T2, _ = refine_switches(sh, kept, sign0, nuh2, T2)
            signs2 = sign0 * (1.0 - 2.0 * (np.arange(tau2.size + 1) % 2))
        if ok:
            try:
                profile = assemble(problem, system, nuh2 / sh.s, T2, tau2, signs2, t0, sh.evaluations, T_low)
            except SolverError:
                profile = None
            if profile is not None and profile.certificate.passed:
                profile.extra["solver_path"] = SolverPath.SEARCH
                return profile
        if best is None or T_c < best.duration:
            try:
                best = assemble(problem, system, nuh / sh.s, T_c, tau, signs_c, t0, sh.evaluations, T_low)
            except SolverError:
                pass
    if best is None:
        return None
    gap = (best.duration - T_low) / best.duration
    cert = replace(
        best.certificate,
        message=f"not proved optimal: within {gap:.1e} (relative) of the proved lower bound {T_low!r} s "
        f"(the rigid body's minimum time); sign test: {best.certificate.message}",
    )
    profile = replace(best, certificate=cert)
    profile.extra["solver_path"] = SolverPath.SEARCH
    return profile


def without_rounding_pairs(tau: np.ndarray, T: float) -> np.ndarray:
    """``tau`` (switch times-to-go, s, ascending) without interior pairs closer than ``SWITCH_TIME_RTOL T``.

    Such a pair is two roots of ``S`` merged by rounding, not a structure an
    extremal has (the certificate rejects it); removing both keeps the levels
    around it.  Neighbours are paired from the smallest ``tau``; a switch at
    an end of ``(0, T)`` is left (removing it would change a boundary level).
    """
    tol = SWITCH_TIME_RTOL * T
    keep = np.ones(tau.size, dtype=bool)
    k = 0
    while k < tau.size - 1:
        if tau[k + 1] - tau[k] <= tol and tau[k] > tol and T - tau[k + 1] > tol:
            keep[k : k + 2] = False
            k += 2
        else:
            k += 1
    return tau[keep]


def end_blip_fallback(problem, system, sh, profile, t0, T_low, assemble) -> BangBangProfile | None:
    """The structure without an unresolved blip of switches, when the certificate could not prove it.

    A co-state iteration can end on the optimum's switches plus a blip a few
    microseconds before ``T`` where the switching function is far below what
    the final-state error can resolve (the certificate's ``end_gap``): a
    longer move than the optimum, not proved.  The certificate reports the
    proved sign changes without that cluster (``details["zeros_tau"]``,
    ``"sign0"``; also without intervals narrower than the switch times
    resolve); the final-state Newton (:func:`primal_newton`) solves that
    structure, and the result is returned only if it is certified
    ``OPTIMAL`` with the co-state of widest margin (:func:`~.costate_lp.widest_costate`) and not longer.
    """
    cert = profile.certificate
    roots, sign0 = cert.details.get("zeros_tau"), float(cert.details.get("sign0", 0.0))
    T = profile.duration
    if roots is None or not sign0 or roots.size >= profile.switch_times.size:
        return None  # nothing dropped: not a blip
    roots = np.asarray(roots, float)
    # The proved zeros, then without the one or two nearest the end: an iteration that ended on a blip can
    # leave a spurious sign change just beyond the unresolved window as well (each dropped zero flips the
    # last arc's sign); every candidate must be certified OPTIMAL and not longer, so none is trusted blindly.
    for drop in range(min(3, roots.size + 1)):
        better = _without_blip(problem, system, sh, roots[drop:], sign0 * (-1.0) ** drop, T, t0, T_low, assemble)
        if better is not None:
            return better
    return None


def _without_blip(problem, system, sh, roots, sign0, T, t0, T_low, assemble) -> BangBangProfile | None:
    """The certified extremal with switches at ``roots`` (time to go, s) and last-arc sign ``sign0``, or None."""
    ok, tau, T_c, _ = primal_newton(sh, roots, sign0, T)
    if not ok or not T_c <= T * (1.0 + GAP_RTOL):  # a certified extremal is the optimum; rounding aside
        return None
    signs = sign0 * (1.0 - 2.0 * (np.arange(tau.size + 1) % 2))
    switch_times, levels = np.sort(T_c - tau), problem.u_max * signs[::-1]
    cuts = np.empty(0)
    for _ in range(CUT_ROUNDS + 1):
        nu = widest_costate(system, T_c, switch_times, levels, extra_tau=cuts)
        if nu is None:
            return None
        try:
            better = assemble(problem, system, nu, T_c, tau, signs, t0, sh.evaluations, T_low)
        except SolverError:
            return None
        if better.certificate.status is CertificateStatus.OPTIMAL:
            better.extra["solver_path"] = SolverPath.SEARCH
            return better
        # S of this co-state dips through zero between the LP's samples (a near-tangency of the
        # optimum's S: the structure of a state on a plan, n - 2 switches): sample the dips, again
        zeros = np.asarray(better.certificate.details.get("zeros_tau", np.empty(0)), float)
        new = zeros[np.min(np.abs(zeros[:, None] - tau[None, :]), axis=1, initial=np.inf) > CUT_RTOL * T_c]
        if new.size == 0:
            return None
        cuts = np.concatenate([cuts, new, 0.5 * (new[1:] + new[:-1])])
    return None


def duality_fallback(problem, system, profile, t0, T_low, assemble) -> BangBangProfile | None:
    """The same profile certified by the gap to a lower bound proved by weak duality, or None.

    For a profile that reaches the target but whose Pontryagin sign test
    cannot decide (a notch of switches a microsecond wide, whose ``S`` is at
    rounding, 8e-8 above the rigid body's bound: :func:`structure_fallback`),
    the co-state of its switches proves by weak duality
    (:func:`~.dual_bound.proved_lower_bound`) that no move arrives before
    ``T (1 - GAP_RTOL / 2)``; the certificate is then ``within_gap`` with that
    bound, as for the rigid body's.  The profile is simulated and certified
    again (``assemble``); the path it came from is kept.  If the bound it
    proves is farther from ``T`` but above ``T_low`` (s, the rigid body's),
    the profile is returned uncertified with that bound in its certificate.
    """
    T = profile.duration
    proof = proved_lower_bound(
        system, problem.shifted_initial(), problem.u_max, T, profile.switch_times, profile.levels, REPORT_GAPS
    )
    if proof is None or not proof[0] > T_low:
        return None
    T_dual, nu = proof  # the certificate's sign test then reports on the co-state that proves the bound
    if T - T_dual > GAP_RTOL * T:  # not proved optimal: a better bound than the rigid body's, said so
        cert = replace(
            profile.certificate,
            lower_bound=T_dual,
            message=f"not proved optimal: within {(T - T_dual) / T:.1e} (relative) of the proved lower bound "
            f"{T_dual!r} s (weak duality with the switches' co-state; the rigid body's is {T_low!r} s)",
        )
        better = replace(profile, certificate=cert)
        better.extra.update(profile.extra)
        better.extra["duality_bound"] = T_dual
        better.extra["duality_costate"] = nu  # nu of the proof (the shifted system's time-to-go convention)
        return better
    signs = np.sign(profile.levels[::-1])
    try:
        proved = assemble(problem, system, nu, T, np.sort(T - profile.switch_times), signs, t0, 0, T_dual)
    except SolverError:
        return None
    cert = proved.certificate
    if not cert.passed:
        return None
    cert = replace(cert, message=f"{cert.message} (lower bound by weak duality with the switches' co-state)")
    proved = replace(proved, certificate=cert, iterations=profile.iterations)
    proved.extra.update(profile.extra)
    proved.extra["duality_bound"] = T_dual
    proved.extra["duality_costate"] = nu
    return proved


def refusal_reason(T_low: float, fastest_period: float = 0.0) -> str:
    """What a refusal of the full solver can still say: why such a move is hard, the proved bound, what plans it.

    ``T_low``: the rigid body's minimum time (s), a proved lower bound on the optimum.  (No estimate
    of the optimum: the smoothed problems' duration can be a factor 2-20 below it on exactly these moves.)
    ``fastest_period``: the period (s) of the model's fastest mode (0: none).  A move whose rigid time is
    shorter than that is short against every mode: the bang-bang input rings them all like an impulse,
    and its optimum is set by bringing them to rest, not by the travel (6 of the 7 refusals of the
    10,000 fuzz cases of seed 15: rigid times of 0.11-0.39 s, optima found near 1 s of 15 or more switches).
    """
    short = (
        f"the move is short against every mode (its rigid-body time is below the {fastest_period:.3g} s period of "
        "the fastest): its optimum is set by bringing all of them to rest, not by the travel; "
        if 0.0 < T_low < fastest_period
        else ""
    )
    bound = f"the minimum time is at least {T_low:.6g} s (the rigid body's)"
    if T_low == 0.0 and fastest_period > 0.0:
        # a vibration alone to damp (local hypothesis seed 3: 4 modes, 1e-4 of a static deflection): every
        # switch rings the rigid body and the quiet modes too, so many are needed in a short time, a
        # structure of near-equal pulses whose switching function is flat to many orders
        short = (
            "the rigid body is already at rest where the move ends: the move only damps the vibration, and the "
            "bang-bang input that does it must leave the rigid body and every other mode at rest as well; "
        )
        bound = "no lower bound on the minimum time is proved (the rigid body's is 0 s)"
    return (
        f"{short}{bound}; nothing is returned: plan the move "
        "at a sample rate with method fixed_time (an arrival time of your choosing, by linear programs, without the "
        "continuous optimum; one too early is refused with the peak command it needs), or model fewer modes"
    )
