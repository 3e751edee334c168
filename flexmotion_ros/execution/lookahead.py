"""The look-ahead of a preemption: how far ahead of the stream a new plan is spliced, from recent planning times.

A plan made during a move starts at the splice sample ``k_next + lead``
(:mod:`.splice`); ``lead`` must cover the planning time.  The estimate of the
next plan's time is a high quantile of the recent ones (outliers set aside),
scaled and capped (:func:`lead_samples`); a plan that overran its look-ahead
is planned again with it doubled (:func:`longer_lead`).  The ready stops
(:mod:`.ready_stops`) use the same window, default and factor for their own
planning times.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

#: Planning time (s) assumed before any plan has been timed.
DEFAULT_PLAN_TIME_S = 0.2
#: The look-ahead covers this multiple of a high quantile of the recent plans: planning times vary with the state.
PLAN_TIME_FACTOR = 1.5
#: ... plus this margin (s): the stream thread must see the splice before the sample is due.
PLAN_TIME_MARGIN_S = 0.02
#: How many recent plan times the look-ahead policy looks at.
PLAN_TIME_WINDOW = 20
#: The slowest fraction of those it ignores (one 8.9 s stop plan among 20 ms goals is an outlier, not the norm).
PLAN_TIME_OUTLIERS = 0.2
#: The look-ahead (s) never exceeds this (unless ``replan_lead_s`` asks for more): a plan that overruns it is
#: planned again from further ahead (:func:`longer_lead`), instead of every later preemption waiting that long.
MAX_LEAD_S = 1.0


def lead_samples(plan_times: Iterable[float], replan_lead_s: float, rate_hz: float) -> int:
    """The look-ahead (samples) from the splice to the sample sent next.

    Not hostage to an outlier: the estimate of the next plan's time is the
    slowest recent plan once the slowest :data:`PLAN_TIME_OUTLIERS` of them
    are set aside (with fewer than 5 plans, the slowest), and the look-ahead
    is capped at :data:`MAX_LEAD_S`.  Issue 16: with the slowest of the last 5,
    one 8.9 s stop plan made the next preemption splice 13.4 s after its request.

    Parameters
    ----------
    plan_times : iterable of float
        Recent planning times (s), e.g. the last :data:`PLAN_TIME_WINDOW`;
        empty: :data:`DEFAULT_PLAN_TIME_S` is assumed.
    replan_lead_s : float
        The configured minimum look-ahead (s).
    rate_hz : float
        Stream rate (Hz).

    Returns
    -------
    int
        ``ceil(max(replan_lead_s, min(MAX_LEAD_S, 1.5 x estimate + 0.02 s)) x rate_hz)``, at least 1 (samples).
    """
    times = sorted(plan_times)
    if times:
        estimate = times[len(times) - 1 - math.floor(PLAN_TIME_OUTLIERS * len(times))]
    else:
        estimate = DEFAULT_PLAN_TIME_S
    lead_s = max(replan_lead_s, min(MAX_LEAD_S, PLAN_TIME_FACTOR * estimate + PLAN_TIME_MARGIN_S))
    return max(1, math.ceil(lead_s * rate_hz))


def longer_lead(lead: int) -> int:
    """The look-ahead (samples) for the next attempt after planning overran ``lead`` (samples): doubled."""
    return 2 * lead
