"""The velocity-sign pattern and the fewest samples of a sampled friction move (searched, not proved).

:class:`~.sampled_lp.FrictionLP` solves one pattern at one sample count.
:func:`consistent_pattern` finds a pattern by a fixed point: solve with the
friction of pattern ``s`` as a known disturbance and no sign rows, take the
signs of the resulting velocity as the next pattern, until they agree (then the
signed LP is solved once more, so the result is exactly consistent); with
``stick=True`` the body is held by friction where it would go back.
:func:`fastest_samples` searches the fewest samples at one rate.
"""

from __future__ import annotations

import math

import numpy as np

from .sampled_lp import FrictionLP, FrictionSolution

#: Fixed-point iterations of the velocity-sign pattern.
PATTERN_ROUNDS = 3
#: Relative margin above ``peak_max`` before a relaxation's least peak rules a signed LP out (both are HiGHS
#: optima to its 1e-10 feasibility tolerance).
RELAXED_MARGIN = 1e-8


def consistent_pattern(
    lp: FrictionLP, K: int, s0: np.ndarray, stick: bool = False, peak_max: float = math.inf
) -> FrictionSolution | None:
    """A pattern consistent with its own least-peak move (fixed point from ``s0``), solved with sign rows.

    The fixed point moves reversals to where the move made with the previous
    pattern's friction reverses; without convergence in
    :data:`PATTERN_ROUNDS` the last pattern is used (the sign rows still make
    the result consistent).  Both the fixed point and ``s0`` itself are solved
    with sign rows; the smaller peak wins.

    ``stick=True``: where the move would go backwards the body is held
    instead (pattern 0: stuck, ``|u| <= F``), and every pattern of the
    iteration is solved with sign rows (the smallest peak wins): for moves
    that must rest on the way while the modes are steered.

    ``peak_max``: a candidate whose LP without sign rows (a relaxation: the same LP with fewer conditions, so
    its least peak is a lower bound) already needs more than this is not solved with sign rows (the caller
    has no use for a solution above it); None is returned if no candidate is left.
    """
    if stick:
        return stick_pattern(lp, K, s0)
    s = np.asarray(s0, float).copy()
    seen = []
    relaxed: dict[bytes, float] = {}  # least peak without sign rows, by pattern
    for _ in range(PATTERN_ROUNDS):
        sol = lp.solve(K, s, signs=False)
        if sol is None:
            relaxed[s.tobytes()] = math.inf  # no solution without sign rows: none with them
            break
        relaxed[s.tobytes()] = sol.t
        nxt = lp.pattern_of(sol.u, s)
        if np.array_equal(nxt, s) or any(np.array_equal(nxt, p) for p in seen):
            break
        seen.append(s)
        s = nxt
    best = None
    for cand in (s, np.asarray(s0, float)):
        if best is not None and np.array_equal(cand, best.pattern):
            continue
        if relaxed.get(cand.tobytes(), -math.inf) > peak_max * (1.0 + RELAXED_MARGIN):
            continue  # its signed LP's peak is at least the relaxation's (seed-18 fuzz: one LP of ~10 a search)
        sol = lp.solve(K, cand, signs=True)
        if sol is not None and (best is None or sol.t < best.t):
            best = sol
    return best


#: Rounds of the stick-instead-of-reverse iteration.
STICK_ROUNDS = 5
#: Periods of the slowest mode the body is held at the end of the first stuck candidate.
STICK_TAIL_PERIODS = 4.0


def stick_pattern(lp: FrictionLP, K: int, s0: np.ndarray) -> FrictionSolution | None:
    direction = -1.0 if lp.x0[0] > 0.0 else 1.0  # lp.x0 is the start relative to the target
    s = np.where(np.asarray(s0, float) == direction, direction, 0.0)
    best, seen = None, []
    omega = lp.problem.model.omega
    if omega and K > 1:
        # first candidate: slide forward, then hold the body for the last few periods of the slowest mode
        # (the modes brought to rest by |u| <= F alone: a long damped move whose end game needs the body
        # to wait; the iteration below rarely finds so long a rest)
        n = min(K // 2, math.ceil(STICK_TAIL_PERIODS * 2.0 * math.pi / min(omega) / lp.dt))
        tail = np.full(K, direction)
        tail[K - n :] = 0.0
        best = lp.solve(K, tail, signs=True)
    for _ in range(STICK_ROUNDS):
        signed = lp.solve(K, s, signs=True)
        if signed is not None and (best is None or signed.t < best.t):
            best = signed
        sol = lp.solve(K, s, signs=False)
        if sol is None:
            break
        v = lp.velocities(sol.u, s)
        nxt = np.where(direction * (v[:-1] + v[1:]) > 0.0, direction, 0.0)
        if any(np.array_equal(nxt, p) for p in seen + [s]):
            break
        seen.append(s)
        s = nxt
    return best


def pattern_template(pattern: np.ndarray):
    """The velocity-sign template (sign at normalised time ``tau`` in [0, 1]) of a solved pattern: the
    warm start of a search at another count or sample period."""
    pat = np.asarray(pattern, float).copy()
    return lambda tau: pat[np.minimum((np.asarray(tau) * pat.size).astype(int), pat.size - 1)]


def template_pattern(template, K: int) -> np.ndarray:
    """``template(tau)`` (velocity sign at normalised time ``tau`` in [0, 1]) on ``K`` intervals."""
    return np.asarray(template((np.arange(K) + 0.5) / K), float)


def count_for_peak(K: int, sol: FrictionSolution | None, F: float, u_max: float) -> int | None:
    """The sample count at which the least peak ``sol.t`` found at ``K`` samples would be ``u_max``, if the
    part above the friction force fell as ``K^-2`` (a rigid body: distance ~ (u - F) T^2); None if unknown.

    Only a guess for the next probe: the search checks every count it keeps with an LP."""
    if sol is None or not (sol.t > F and u_max > F):
        return None
    r = math.sqrt((sol.t - F) / (u_max - F))
    return max(1, math.ceil(K * r * (1.0 + 1e-3))) if r > 1.0 else max(1, math.ceil(K * r))


def fastest_samples(
    lp: FrictionLP, template, K_guess: int, K_min: int = 1, K_max: int | None = None, stick: bool = False
) -> FrictionSolution | None:
    """Fewest samples (searched, not proved) with least peak ``<= u_max``; patterns from ``template``.

    One signed LP per probed count with the current pattern (the template,
    then the last pattern that worked, mapped by normalised time): up
    geometrically until a count works, down geometrically until one does
    not, then bisection.  Where the current pattern fails (the first probe,
    and one count below the count found) the pattern is iterated to
    consistency (:func:`consistent_pattern`); a better pattern restarts the
    search down from there (a few rounds).  ``stick``: the fixed point holds
    the body where it would go back (see :func:`consistent_pattern`).
    """
    um = lp.problem.u_max * (1.0 + 1e-12)
    K_max = K_max if K_max is not None else max(8 * K_guess, K_guess + 200)
    tried: dict[int, FrictionSolution | None] = {}
    state = {"template": template}

    def remember(sol: FrictionSolution) -> None:
        state["template"] = pattern_template(sol.pattern)

    def feasible(sol: FrictionSolution | None) -> bool:
        return sol is not None and sol.t <= um

    def ok(K: int) -> bool:
        if K not in tried:
            tried[K] = lp.solve(K, template_pattern(state["template"], K))
            if feasible(tried[K]):
                remember(tried[K])
        return feasible(tried[K])

    def fixed_point(K: int) -> bool:
        sol = consistent_pattern(lp, K, template_pattern(state["template"], K), stick, peak_max=um)
        if not feasible(sol):
            return False
        tried[K] = sol
        remember(sol)
        return True

    def relaxed_beyond(K: int) -> bool:
        # no signed solution at K: the LP without sign rows (a relaxation, so its least peak is a lower
        # bound for this pattern at K) says how far up a count could be; past K_max, stop here (the caller
        # tries coarser samples) instead of probing every count up to K_max (fuzz case 39 of seed 18:
        # 24 infeasible LPs at 10 ms samples for a 9.2 s move)
        if "relaxed" in state:
            return False  # once per search
        sol = lp.solve(K, template_pattern(state["template"], K), signs=False)
        state["relaxed"] = sol
        guess = count_for_peak(K, sol, lp.F, um)
        return guess is not None and guess > 2 * K_max  # a wide margin: the peak is not monotone in K

    K = max(K_guess, K_min)
    step = max(1, K // 50)
    first = True
    flat, last = 0, None
    while not ok(K):
        if (first or stick) and fixed_point(K):
            break
        first = False
        if tried[K] is not None and last is not None:
            # more samples, the same least peak (three times): the end game cannot be resolved at this
            # period (samples too long for the modes to be brought to rest), so no count will do;
            # finer samples are the caller's move
            flat = flat + 1 if abs(tried[K].t - last) <= 1e-6 * last else 0
            if flat >= 3:
                lp.stalled = True
                return None
        last = tried[K].t if tried[K] is not None else None
        if K >= K_max:
            return None
        if tried[K] is None and not stick and relaxed_beyond(K):
            return None
        # (jumping to the count where the peak would reach u_max, t - F ~ K^-2, was tried: fewer LPs, but the
        # least peak is not monotone in K, and a jump past a feasible count lengthened some moves 1.8-2.6 x
        # in the fuzz: fuzz cases 65 and 178 of seed 18; the steps stay geometric)
        K = min(K_max, K + step)
        step *= 2
    hi = K
    for _ in range(3):
        lo, step = None, max(1, hi // 50)
        while lo is None:
            cand = hi - step
            if cand < K_min:
                lo = K_min - 1
            elif ok(cand):
                hi = cand
                step *= 2
            else:
                lo = cand
        lo = max([lo] + [k for k in tried if k < hi and not feasible(tried[k])])
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if ok(mid):
                hi = mid
            else:
                lo = mid
        if hi - 1 < K_min or not fixed_point(hi - 1):
            break
        # a better pattern: counts below may work now
        hi -= 1
        for k in [k for k in tried if k < hi]:
            del tried[k]
    return tried[hi]
