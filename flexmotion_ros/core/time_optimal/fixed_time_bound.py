"""Fixed arrival time, the bound search: the lowest bound ``u'`` whose time-optimal move takes ``T_req``.

``T*(u')`` decreases strictly with ``u'`` (reachable sets grow with the
bound): a safeguarded secant (regula falsi, Illinois) on ``log T*(u') = log
T_req`` in ``log u'``, each evaluation a certified time-optimal plan
warm-started from the nearest one solved.  The arrival time's check
(``arrival_time >= T*``) lives here too.  The planner is
:func:`~.fixed_time.plan_fixed_time`.
"""

from __future__ import annotations

import math
from dataclasses import replace

from ..errors import InputError
from ..model.boundary import MoveProblem
from ..results import BangBangProfile
from ..simulation.prepared import PreparedMove, prepare
from ..tolerances import SAME_TIME_RTOL
from .solver import plan_time_optimal
from .warm_start import WarmStart, remainder


def check_arrival_time(arrival_time, T_star: float) -> float:
    """``arrival_time`` as float if finite and ``>= T*``, else raise naming the parameter and the range."""
    try:
        T = float(arrival_time)
    except (TypeError, ValueError):
        raise InputError(
            "arrival_time", f"must be a time in [T*, inf) = [{T_star:.9g}, inf) s, got {arrival_time!r}"
        ) from None
    if not math.isfinite(T) or T < T_star * (1.0 - SAME_TIME_RTOL):
        raise InputError(
            "arrival_time",
            f"must be in [T*, inf) = [{T_star:.9g}, inf) s (T* is the time-optimal move time at u_max), got {T}",
        )
    return max(T, T_star)


#: Most bound evaluations (each a certified time-optimal plan, warm-started) of the root-find.
MAX_BOUND_EVALUATIONS = 60
#: ``|log T*(u') - log T_req|`` below which a profile's structure is tried at ``T_req`` (one Newton).
TRY_STRUCTURE_LOG = 0.05


def _warm_guess(prof: BangBangProfile, T_guess: float) -> WarmStart | None:
    """``prof``'s structure stretched to a duration guess, as the next bound's warm start."""
    warm = remainder(prof, 0.0)
    if warm is None or not prof.duration > 0.0:
        return None
    return replace(warm, roots=warm.roots * (T_guess / prof.duration), duration=T_guess)


def bound_search(move: PreparedMove, best: BangBangProfile, T_req: float, xtol: float):
    """Profiles ``(x, T*(e^x) profile)`` of a safeguarded secant search of ``log T*(e^x) = log T_req``.

    Regula falsi with the Illinois rule on a bracket (``T*`` falls strictly
    with the bound), every evaluation a certified time-optimal plan
    warm-started from the nearest profile already solved (stretched to the
    duration the secant predicts): when the switch structure is the same,
    Newton on the switches replaces the cold solve.  At most
    :data:`MAX_BOUND_EVALUATIONS` plans.  Yields each evaluated profile.
    """
    um = move.u_max
    target = math.log(T_req)
    known: list[tuple[float, float, BangBangProfile]] = [(math.log(um), math.log(best.duration) - target, best)]

    def evaluate(x: float) -> tuple[float, BangBangProfile]:
        near = sorted(known, key=lambda k: abs(k[0] - x))
        if len(near) >= 2 and near[0][0] != near[1][0]:
            slope = (near[0][1] - near[1][1]) / (near[0][0] - near[1][0])
        else:
            slope = -0.5  # the rigid body's T ~ u'^(-1/2)
        g_guess = near[0][1] + slope * (x - near[0][0])
        warm = _warm_guess(near[0][2], math.exp(target + g_guess))
        prof = plan_time_optimal(move.with_bound(math.exp(x)), warm_start=warm)
        g = math.log(prof.duration) - target
        known.append((x, g, prof))
        return g, prof

    x_hi, g_hi = known[0][0], known[0][1]
    # T* grows at least like u'^(-1/2) as u' falls (rigid body, from rest); bracket from a guess
    x_lo = x_hi + 2.0 * g_hi
    g_lo, prof = evaluate(x_lo)
    yield x_lo, prof
    n = 1
    while g_lo < 0.0 and n < MAX_BOUND_EVALUATIONS:
        x_hi, g_hi, x_lo = x_lo, g_lo, x_lo - math.log(4.0)
        g_lo, prof = evaluate(x_lo)
        n += 1
        yield x_lo, prof
    if g_lo < 0.0:
        return
    side = 0
    while n < MAX_BOUND_EVALUATIONS and abs(x_hi - x_lo) > xtol and g_lo != 0.0 and g_hi != 0.0:
        x = (x_lo * g_hi - x_hi * g_lo) / (g_hi - g_lo)
        if not min(x_lo, x_hi) < x < max(x_lo, x_hi):
            x = 0.5 * (x_lo + x_hi)
        g, prof = evaluate(x)
        n += 1
        yield x, prof
        if g > 0.0:
            x_lo, g_lo = x, g
            if side == 1:
                g_hi *= 0.5  # Illinois: the end kept twice in a row counts half
            side = 1
        elif g < 0.0:
            x_hi, g_hi = x, g
            if side == -1:
                g_lo *= 0.5
            side = -1
        else:
            return


def lowest_bound(
    problem: MoveProblem | PreparedMove, arrival_time: float, T_star: float | None = None, xtol: float = 1e-15
) -> tuple[float, BangBangProfile]:
    """The bound ``u' <= u_max`` whose time-optimal move takes ``arrival_time`` (root-find; see module notes).

    ``problem``: a :class:`PreparedMove` shares its responses with every
    bound tried, and its attached time-optimal profile (at ``u_max``) is used
    instead of solving again.  Returns ``(u', profile at u')``; the profile's
    duration equals ``arrival_time`` (s) to the root-finder's tolerance (the
    caller polishes).
    """
    move = prepare(problem)
    um = move.u_max
    best = move.continuous if move.continuous is not None else plan_time_optimal(move)
    T_star = best.duration if T_star is None else T_star
    T_req = check_arrival_time(arrival_time, T_star)
    if T_req <= T_star * (1.0 + SAME_TIME_RTOL):
        return um, best
    found = (math.inf, math.log(um), best)
    for x, prof in bound_search(move, best, T_req, xtol):
        err = abs(math.log(prof.duration / T_req))
        if err < found[0]:
            found = (err, x, prof)
    return math.exp(found[1]), found[2]
