"""Preemption: where a new plan is spliced into a running move, and from which state.

A goal (or a stop) during a move is planned from the state the timeline
predicts at the *splice sample* ``k_s = k_next + lead``, where ``k_next`` is
the sample the stream sends next and the look-ahead ``lead`` (samples)
covers the planning time; the new command sequence then replaces the
timeline from ``k_s`` on.  The commands up to ``k_s`` are sent unchanged, so
the machine is at the predicted state when the new plan starts.

If planning overran the look-ahead (``k_s`` already sent), the splice is
refused; then either the move had ended meanwhile and the plan, made from
the rest at its end, starts at once (:func:`ended_at_rest`), or it is
planned again with a longer look-ahead (:func:`longer_lead`), at most
:data:`SPLICE_ATTEMPTS` times.  The look-ahead policy is :mod:`.lookahead`, the
ready stops :mod:`.ready_stops` (both exported from here too).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..core.errors import GoalError

# The look-ahead policy and the ready stops, exported from here too (the nodes and the package import them so).
from .lookahead import (
    DEFAULT_PLAN_TIME_S,
    MAX_LEAD_S,
    PLAN_TIME_FACTOR,
    PLAN_TIME_MARGIN_S,
    PLAN_TIME_OUTLIERS,
    PLAN_TIME_WINDOW,
    lead_samples,
    longer_lead,
)
from .ready_stops import (
    PAUSE_POLL_S,
    READY_STOP_LEADS,
    STOP_AHEAD,
    STOP_MARGIN_SAMPLES,
    STOP_PREP_DUTY,
    ReadyStop,
    StopPreparer,
    next_checkpoint,
    ready_stop_usable,
)
from .timeline import Segment, predicted_state

#: Attempts to splice a preemption before giving up (the look-ahead doubles each time).
SPLICE_ATTEMPTS = 4


@dataclass(frozen=True, kw_only=True)
class SplicePoint:
    """Where a preempting plan starts.

    Attributes
    ----------
    sample : int
        Global sample index ``k_s`` (samples) of the new plan's first command.
    state : ndarray
        The state the timeline predicts there: the new plan's initial state.
    lead : int
        ``k_s - k_next`` (samples): the time left for planning, in samples.
    """

    sample: int
    state: np.ndarray
    lead: int


def splice_point(timeline: Sequence[Segment], k_next: int, lead: int, n_modes: int | None = None) -> SplicePoint | None:
    """The splice sample and the predicted state there, or None when idle.

    Parameters
    ----------
    timeline : sequence of Segment
        The stream's queued segments, ordered by start index (empty: idle).
    k_next : int
        Global index (samples) of the sample the stream sends next.
    lead : int
        Look-ahead (samples), e.g. from :func:`lead_samples`.
    n_modes : int, optional
        The model the new plan is made with: the predicted state must have
        its ``2 n_modes + 2`` entries.

    Returns
    -------
    SplicePoint or None
        None if the timeline is empty (plan from rest and start on the next sample).

    Raises
    ------
    GoalError
        The predicted state has another number of modes than ``n_modes``
        (the model changed during the move).
    """
    if not timeline:
        return None
    at = k_next + lead
    x0 = predicted_state(timeline, at)
    if n_modes is not None and x0.size != 2 * n_modes + 2:
        raise GoalError(
            "model",
            f"the number of modes changed during a move ({(x0.size - 2) // 2} -> {n_modes}): "
            "stop or wait until idle, then send the goal again",
        )
    return SplicePoint(sample=at, state=x0, lead=lead)


def ended_at_rest(timeline: Sequence[Segment], sample: int, idle: bool) -> bool:
    """After a refused splice at ``sample``: is a plan made from the state predicted there still valid from rest?

    It is if the timeline the plan was made from had ended by ``sample`` (so
    the predicted state was the rest at its end) and the stream is idle now.

    Parameters
    ----------
    timeline : sequence of Segment
        The timeline the splice point was computed from.
    sample : int
        The refused splice sample (samples).
    idle : bool
        The stream has no segment queued now.
    """
    return bool(timeline) and sample >= timeline[-1].end and idle


__all__ = [
    "DEFAULT_PLAN_TIME_S",
    "MAX_LEAD_S",
    "PAUSE_POLL_S",
    "PLAN_TIME_FACTOR",
    "PLAN_TIME_MARGIN_S",
    "PLAN_TIME_OUTLIERS",
    "PLAN_TIME_WINDOW",
    "READY_STOP_LEADS",
    "SPLICE_ATTEMPTS",
    "STOP_AHEAD",
    "STOP_MARGIN_SAMPLES",
    "STOP_PREP_DUTY",
    "ReadyStop",
    "SplicePoint",
    "StopPreparer",
    "ended_at_rest",
    "lead_samples",
    "longer_lead",
    "next_checkpoint",
    "ready_stop_usable",
    "splice_point",
]
