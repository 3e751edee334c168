"""Ready stops: verified stop plans kept ahead of the stream during a move, so a stop is spliced within a few samples.

:class:`StopPreparer` (a background thread at a bounded duty cycle, paused
while a goal is planned) plans stops from the states the timeline predicts at
future checkpoints (:func:`next_checkpoint`); :func:`ready_stop_usable`
decides whether one can still be spliced now (far enough ahead, the same
configuration, the timeline still predicting its state).
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .lookahead import DEFAULT_PLAN_TIME_S, PLAN_TIME_FACTOR, PLAN_TIME_WINDOW
from .timeline import Segment, predicted_state

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
