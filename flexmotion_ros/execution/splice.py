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
:data:`SPLICE_ATTEMPTS` times.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from ..core.errors import GoalError
from .timeline import Segment, predicted_state

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
#: Attempts to splice a preemption before giving up (the look-ahead doubles each time).
SPLICE_ATTEMPTS = 4


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


# ------------------------------------------------------------------------------ ready stops
#
# A stop request must change the stream within a few samples, but a certified
# time-optimal stop takes tens of milliseconds to plan (seconds near the end of
# some moves).  So while a move plays, :class:`StopPreparer` keeps stops ready:
# each planned (by the node's own planner, so verified like every plan) from
# the state the timeline predicts at a future *checkpoint* sample, a few
# checkpoints ahead of the stream.  A stop request splices the earliest ready
# stop whose checkpoint is still at least :data:`STOP_MARGIN_SAMPLES` ahead
# and whose predicted state is still exactly what the timeline predicts there
# (same timeline, same configuration); otherwise the node plans the stop as
# before.

#: A ready stop is used only if its first sample is at least this many samples ahead (the stream thread must see it).
STOP_MARGIN_SAMPLES = 2
#: The preparer plans at most this fraction of the time (it sleeps the rest), so that the stream and the
#: goals keep CPU for themselves; checkpoints are then ``plan time / duty`` apart (the stop latency is at
#: most about that).  It does not plan at all while a goal is being planned (``paused``).
STOP_PREP_DUTY = 0.5
#: Ready stops kept ahead of the stream (then the preparer waits for the stream to pass one).
STOP_AHEAD = 2
#: A ready stop is taken if it starts within this many look-aheads of the request (a stop planned now would
#: start one look-ahead on, if its plan kept to it); one further on (the preparer fell behind): planned now.
READY_STOP_LEADS = 2
#: While paused, the preparer looks again this often (s).
PAUSE_POLL_S = 0.01


@dataclass(frozen=True, kw_only=True)
class ReadyStop:
    """A verified stop plan, ready to be spliced at its checkpoint.

    Attributes
    ----------
    sample : int
        The checkpoint: global index (samples) of its first command.
    state : ndarray
        The state the timeline predicted there, the plan's initial state.
    segment : Segment
        The stop plan (commands, predicted states, the planner's record).
    plan_time_s : float
        How long planning it took (s).
    key : object
        What it was planned with (the node's configuration object): it is
        usable only while that is still the one in use.
    """

    sample: int
    state: np.ndarray
    segment: Segment
    plan_time_s: float
    key: object


def ready_stop_usable(stop: ReadyStop, timeline: Sequence[Segment], k_next: int, key: object) -> bool:
    """Can ``stop`` be spliced now: far enough ahead, same configuration, the timeline still predicts its state?

    Parameters
    ----------
    stop : ReadyStop
    timeline : sequence of Segment
        The stream's queued segments now.
    k_next : int
        The sample (samples) the stream sends next.
    key : object
        The configuration in use now (compared by identity).
    """
    if key is not stop.key or not timeline or stop.sample < k_next + STOP_MARGIN_SAMPLES:
        return False
    if stop.sample >= timeline[-1].end:  # the move is over by then: nothing to stop
        return False
    x = predicted_state(timeline, stop.sample)
    return x is not None and x.shape == stop.state.shape and bool(np.array_equal(x, stop.state))


def next_checkpoint(k_next: int, last: int | None, plan_time_s: float, rate_hz: float) -> tuple[int, int]:
    """The next checkpoint to plan a stop for, and the spacing of checkpoints (samples).

    The first is just beyond what planning it takes (1.5 x ``plan_time_s``
    plus :data:`STOP_MARGIN_SAMPLES`); the next ones follow every
    ``plan_time_s / STOP_PREP_DUTY`` (the preparer's pace at its duty cycle),
    at least 2 samples apart.

    Parameters
    ----------
    k_next : int
        The sample (samples) the stream sends next.
    last : int or None
        The latest checkpoint with a ready stop (None if none).
    plan_time_s : float
        The expected planning time of one stop (s).
    rate_hz : float
        Stream rate (Hz).
    """
    head = k_next + STOP_MARGIN_SAMPLES + math.ceil(PLAN_TIME_FACTOR * plan_time_s * rate_hz)
    spacing = max(2, math.ceil(plan_time_s / STOP_PREP_DUTY * rate_hz))
    return (head if last is None else max(head, last + spacing)), spacing


class StopPreparer:
    """Keeps time-optimal stops ready for the move the stream plays (a background thread).

    Parameters
    ----------
    plan : callable
        ``plan(x0, key) -> Segment``: the verified stop from state ``x0`` with
        configuration ``key`` (raises if it cannot; the checkpoint is skipped).
    snapshot : callable
        ``snapshot() -> (k_next, timeline)``: the stream's
        :meth:`~.command_stream.CommandStream.snapshot`.
    key : callable
        ``key()``: the configuration in use now.
    wanted : callable
        ``wanted(timeline) -> bool``: prepare stops for this timeline (the node
        does not for a timeline that already ends in a stop).
    rate_hz : float
        Stream rate (Hz).
    paused : callable, optional
        ``paused() -> bool``: while true (the node is planning a goal), plan
        no stop: the goal gets the CPU, and a stop planned now would be for a
        timeline about to change.
    """

    def __init__(
        self,
        plan: Callable[[np.ndarray, object], Segment],
        snapshot: Callable[[], tuple[int, list[Segment]]],
        key: Callable[[], object],
        wanted: Callable[[Sequence[Segment]], bool],
        rate_hz: float,
        paused: Callable[[], bool] | None = None,
    ) -> None:
        self._plan = plan
        self._paused = paused if paused is not None else (lambda: False)
        self._snapshot = snapshot
        self._key = key
        self._wanted = wanted
        self.rate_hz = float(rate_hz)
        self._cond = threading.Condition()
        self._ready: list[ReadyStop] = []
        self._stop = False
        self._kick = False
        self._busy = False
        self._thread: threading.Thread | None = None
        #: Recent stop planning times (s).
        self.plan_times: deque[float] = deque(maxlen=PLAN_TIME_WINDOW)
        #: Stops planned, and planned in vain (the checkpoint passed or the timeline changed meanwhile).
        self.planned = 0
        self.wasted = 0
        #: Times the preparer found itself paused (a goal being planned).
        self.pauses = 0

    def start(self) -> None:
        """Start the thread."""
        with self._cond:
            self._stop = False
            self._ready = []
        self._thread = threading.Thread(target=self._run, name="flexmotion-stop-preparer", daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 1.0) -> None:
        """End the thread (a plan in progress finishes in the background; its result is dropped)."""
        with self._cond:
            self._stop = True
            self._ready = []
            self._cond.notify_all()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout)

    def notify(self, plan_time_s: float | None = None) -> None:
        """The timeline changed (a move was installed): look again.

        ``plan_time_s`` (s): how long that move took to plan, the first
        guess of a stop's planning time before any stop has been timed.
        """
        with self._cond:
            if plan_time_s is not None and not self.plan_times:
                self.plan_times.append(float(plan_time_s))
            self._kick = True
            self._cond.notify_all()

    def take(self, wait_s: float = 0.0, latest: int | None = None) -> ReadyStop | None:
        """Remove and return the earliest stop usable now (against the stream's snapshot); None if none.

        Parameters
        ----------
        wait_s : float
            If none is usable but one is being planned, wait up to this long (s) for it.
        latest : int or None
            The latest first sample worth taking (samples): a stop planned on demand would start there,
            so a ready stop starting later is no gain (None: any).
        """
        key = self._key()
        end = time.monotonic() + wait_s
        while True:
            k_next, timeline = self._snapshot()
            with self._cond:
                for i, stop in enumerate(self._ready):
                    if latest is not None and stop.sample > latest:
                        break  # earliest first: the others start later still
                    if ready_stop_usable(stop, timeline, k_next, key):
                        del self._ready[: i + 1]
                        return stop
                left = end - time.monotonic()
                if not self._busy or left <= 0.0 or self._stop:
                    return None
                self._cond.wait(left)

    def ready(self) -> list[ReadyStop]:
        """The ready stops (earliest first)."""
        with self._cond:
            return list(self._ready)

    def _expected_plan_time(self) -> float:
        # the median, not the slowest: a plan that overruns its checkpoint is only wasted, the next one is sooner
        return float(np.median(self.plan_times)) if self.plan_times else DEFAULT_PLAN_TIME_S / 4

    def _wait(self, seconds: float | None) -> bool:
        """Sleep up to ``seconds`` (None: until notified); False if stopping."""
        with self._cond:
            if not self._kick and not self._stop:
                self._cond.wait(seconds)
            self._kick = False
            return not self._stop

    def _run(self) -> None:
        while True:
            with self._cond:
                if self._stop:
                    return
            k_next, timeline = self._snapshot()
            key = self._key()
            with self._cond:
                self._ready = [s for s in self._ready if ready_stop_usable(s, timeline, k_next, key)]
                ready = list(self._ready)
            if not timeline or not self._wanted(timeline):
                if not self._wait(None if not timeline else 0.05):
                    return
                continue
            if self._paused():  # a goal is being planned: look again shortly
                self.pauses += 1
                if not self._wait(PAUSE_POLL_S):
                    return
                continue
            expected = self._expected_plan_time()
            at, spacing = next_checkpoint(k_next, ready[-1].sample if ready else None, expected, self.rate_hz)
            if len(ready) >= STOP_AHEAD or at >= timeline[-1].end:
                # far enough ahead, or the move ends first: look again when the stream has moved on
                if not self._wait(max(spacing / self.rate_hz, 0.005)):
                    return
                continue
            x0 = predicted_state(timeline, at)
            with self._cond:
                self._busy = True
            t0 = time.perf_counter()
            try:
                seg = self._plan(x0, key)
            except Exception:  # noqa: BLE001 -- no ready stop here: a stop request plans it then
                seg = None
            took = time.perf_counter() - t0
            self.plan_times.append(took)
            stop = None if seg is None else ReadyStop(sample=at, state=x0, segment=seg, plan_time_s=took, key=key)
            k_now, now_timeline = self._snapshot()
            with self._cond:
                self._busy = False
                self.planned += 1
                if stop is not None and ready_stop_usable(stop, now_timeline, k_now, self._key()):
                    self._ready.append(stop)
                else:
                    self.wasted += 1
                self._cond.notify_all()
            if not self._wait(took * (1.0 / STOP_PREP_DUTY - 1.0)):
                return


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
