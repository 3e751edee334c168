"""The sequence accepted at a sample count of the limited planner: the smoothest in the count's structure.

:func:`accept` solves the smooth LP (total variation; under a slew limit
alone any vertex) at ``K`` samples in the level's own windows, then in the
probe's, then with every sample free; the sequence's arrival is corrected to
rounding and every limit is checked at and between the samples on the exact
matrix-exponential simulation (:func:`~.limits.check_limits`).  A deflection
peak between samples above its limit becomes a cut and the search resumes.
:func:`accept_predicted`: at the final rate, the coarser levels' count accepted
without its own probe when ``K - 1`` is shown above the limits' scale.  The
search over counts: :mod:`.planner`.
"""

from __future__ import annotations

import math

from .level import Level
from .limits import check_limits
from .lp import LimitLP, LPUndecided
from .segments import LPSolution, Segments
from .structure import map_runs

#: Window half-width (samples) of the predicted count's smooth LP (:func:`accept_predicted`), around the runs of
#: ``K - 1``'s solution at the same rate: 2 frees 176 samples of the bench's all-three move at 1 kHz, 0.15 s
#: CPU, against 336 and 0.29 s with the probes' width (4); a sequence missing a check there is tried again
#: with the probes' width.
ACCEPT_WIDTH = 2


def accept(level: Level, K: int):
    """The smoothest sequence at ``K`` in ``K``'s structure, exact arrival, exact checks; cuts added on the way.

    Returns ``(u, peaks, free)`` (``free``: the free samples of the accepted LP), or None (no sequence
    here: try more samples), or ``"cuts"`` (new cuts: search again).
    """
    lp = level.lp
    narrow = narrow_segments(level, K)
    if narrow is not None:
        # first in the level's own windows; only a sequence that passes every exact check as it is
        # counts, anything else (no solution, a cut, a missed sample) is left to the probe's windows as
        # before, so the search goes on as if this LP had not been tried
        got = smooth_passes(lp, K, narrow, start=level.sols[K])
        if got is not None:
            return got
    probe = level.sols[K]
    seg = probe.segments
    for _attempt in ("this structure", "every sample free"):
        try:
            sol = lp.solve(K, seg, mode="smooth", start=probe)
            if sol is None and seg.n_free < K:
                seg = Segments.all_free(K)
                sol = lp.solve(K, mode="smooth", start=probe)
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
            return u, peaks, seg.n_free
        seg = Segments.all_free(K)  # a sample limit missed after the correction: the full LP
    return None


def smooth_passes(lp: LimitLP, K: int, seg: Segments, start: LPSolution | None = None) -> tuple | None:
    """``(u, peaks, free)``: the smoothest sequence at ``K`` in ``seg`` if it passes every exact check as it
    is (no cut, no missed sample); None otherwise (nothing learnt: no cut is kept).  ``start``: a solution
    whose commands start the LP (:meth:`.lp.LimitLP.solve`)."""
    try:
        sol = lp.solve(K, seg, mode="smooth", start=start)
    except LPUndecided:
        return None
    if sol is None:
        return None
    u = lp.exact_commands(sol.u)
    peaks, cuts, ok = check_limits(lp.model, lp.problem.x0, u, lp.dt, lp.limits)
    return (u, peaks, seg.n_free) if ok and not cuts else None


def accept_predicted(level: Level, K: int, lo: int, slope: float | None) -> tuple | None:
    """At the final rate: ``K`` (the coarser levels' prediction) accepted without its own scaled probe.

    The search below would probe ``K`` (windows mapped from the coarser level), then ``K - 1`` (windows of
    that solution), prove ``K - 1`` and solve the smooth LP at ``K``: at 1 kHz three LPs of 300-600 free
    samples, 0.2-0.3 s each.  Here ``K - 1`` is probed first (mapped windows); if its ``t`` is above 1 and,
    with the coarser level's slope of ``t`` per sample (``slope``, scaled to this rate), ``K``'s would be
    below it, the smooth LP at ``K`` is solved in the windows of ``K - 1``'s solution.  A sequence that
    passes every exact check shows ``K`` feasible, and then ``t(K - 1) > 1`` makes ``K`` the count the
    search would return; ``K - 1`` is proved (or not) as the search would (:meth:`Level.prove`).

    Returns ``(K, proof, (u, peaks, free))``, or None: the search goes on from what was learnt (probes
    and proofs are kept) when ``K - 1`` is at or below ``lo``, its window LP meets the limits or gives
    no verdict, ``K`` is not predicted feasible, its sequence misses a check, or ``K - 1`` turns out
    feasible.
    """
    if level.full or slope is None or K - 1 <= lo or K > level.K_cap:
        return None
    t = level.probe(K - 1)
    if not (1.0 < t < math.inf and t + slope < 1.0):
        return None
    for width in dict.fromkeys((ACCEPT_WIDTH, level.width)):  # each width once
        got = smooth_passes(level.lp, K, map_runs(level.ref[0], level.ref[1], K, width), start=level.sols[K - 1])
        if got is not None:
            break
    if got is None:
        return None
    res = level.prove(K - 1)
    return None if res is False else (K, res, got)


def narrow_segments(level: Level, K: int) -> Segments | None:
    """The level's own (narrowest) windows at ``K`` if they free fewer samples than the probe's, else None.

    The accepted smooth LP is the largest of the final rate: the bench's all-three move at 1 kHz had
    588 free samples in the first probe's windows (mapped from the coarser rate), 0.35 s CPU; the
    windows from that probe's own optimum (those of the ``K - 1`` probe) free 338, 0.17 s.
    """
    if level.full or not level.own or K not in level.sols:
        return None
    seg = level.segments(K)
    return seg if seg.n_free < level.sols[K].segments.n_free else None
