"""The fixed-rate command stream: absolute deadlines, no sample ever skipped.

Sample ``k`` is due at ``t_anchor + (k - k_anchor) / rate_hz`` on the
stream's clock, so lateness never accumulates (no drift); a late sample is
sent at once and none is ever skipped (a lockstep plant counts them).

The stream plays a *timeline* (:mod:`.timeline`): a queue of
:class:`~.timeline.Segment` s, each a planned command sequence starting at a
global sample index.  Preemption inserts a segment at a future index (a
*splice*, :mod:`.splice`); the segments before it keep playing until then,
so the state the new plan started from is exactly the state the machine is
predicted to reach there.  After the last command of a move the stream sends
one explicit hold sample (:data:`~.timeline.HOLD`: the targets are
equilibria, no force is needed at rest); while idle it either keeps sending
the hold at the rate (``hold_when_idle``) or sends nothing and sleeps until
the next move, which then starts on the next sample.

The clock, the sleep and the "publish one sample" callable are injected:
:meth:`CommandStream.start` runs :meth:`CommandStream.step` in a dedicated
thread; a test calls :meth:`~CommandStream.step` itself with a fake clock.
"""

from __future__ import annotations

import os
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .timeline import HOLD, Segment, predicted_state


@dataclass(frozen=True, kw_only=True)
class StreamStep:
    """What one step of the stream did.

    Attributes
    ----------
    sample : int
        Global sample index (samples).
    deadline : float
        When it was due (clock s).
    time : float
        When it was handled, after the sleep (clock s).
    value : float or None
        The command published (N); None if nothing was sent (idle, silent).
    """

    sample: int
    deadline: float
    time: float
    value: float | None


class CommandStream:
    """Publish one command per period, at absolute deadlines.

    Parameters
    ----------
    rate_hz : float
        Samples per second (Hz).
    publish : callable
        ``publish(value)`` sends one sample (N); called from the stream thread.
    hold_when_idle : bool
        Keep sending :data:`~.timeline.HOLD` while idle.
    on_start, on_finish : callable, optional
        ``f(segment)`` when a segment sends its first command / when the
        timeline runs out (after the explicit hold).  Called from the stream thread.
    clock : callable
        Monotonic clock (s).
    record : int
        Keep the send times of the last ``record`` samples (for jitter statistics).
    priority : int
        1..99: run the thread under ``SCHED_FIFO`` at this priority (Linux; needs
        ``CAP_SYS_NICE`` or an rtprio limit), so that a loaded machine does not
        delay its wake-ups; 0: normal scheduling.  If refused, the stream runs
        normally and :attr:`priority_error` says why.
    sleep : callable
        ``sleep(seconds)`` on the same time base as ``clock``.
    """

    def __init__(
        self,
        rate_hz: float,
        publish: Callable[[float], None],
        hold_when_idle: bool = True,
        on_start: Callable[[Segment], None] | None = None,
        on_finish: Callable[[Segment], None] | None = None,
        clock: Callable[[], float] = time.monotonic,
        record: int = 200_000,
        priority: int = 0,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        self.dt = 1.0 / float(rate_hz)
        self._publish = publish
        self._hold_when_idle = bool(hold_when_idle)
        self._on_start = on_start
        self._on_finish = on_finish
        self._clock = clock
        self._sleep = sleep
        self._cond = threading.Condition()
        self._queue: list[Segment] = []
        self._k_next = 0
        self._t_anchor = clock()  # start() re-anchors: sample 0 is due when the stream starts
        self._k_anchor = 0
        self._stop = False
        self._thread: threading.Thread | None = None
        self.sent_times: deque[float] = deque(maxlen=record)  # send times (s), all samples
        self.lateness: deque[float] = deque(maxlen=record)  # send time - deadline (s)
        self.samples_sent = 0
        self.priority = int(priority)
        self.priority_error: str | None = None
        self._started = threading.Event()

    # ------------------------------------------------------------------ control
    def start(self) -> None:
        """Start the stream thread (sample 0 is due now)."""
        with self._cond:
            self._t_anchor = self._clock()
            self._k_anchor = 0
        self._thread = threading.Thread(target=self._run, name="flexmotion-stream", daemon=True)
        self._thread.start()
        self._started.wait(2.0)  # priority_error is known when start() returns

    def stop(self, timeout: float = 2.0) -> None:
        """Stop the thread (returns within ``timeout`` s)."""
        with self._cond:
            self._stop = True
            self._cond.notify_all()
        if self._thread is not None:
            self._thread.join(timeout)

    @property
    def hold_when_idle(self) -> bool:
        """Keep sending the hold while idle."""
        return self._hold_when_idle

    @hold_when_idle.setter
    def hold_when_idle(self, value: bool) -> None:
        with self._cond:
            self._rebase_if_sleeping()  # a sleeping stream resumes now, without a burst
            self._hold_when_idle = bool(value)
            self._cond.notify_all()

    # ----------------------------------------------------------------- timeline
    def snapshot(self) -> tuple[int, list[Segment]]:
        """``(k_next, segments)``: the next index to send (samples) and the queued timeline."""
        with self._cond:
            return self._k_next, list(self._queue)

    @property
    def idle(self) -> bool:
        """No segment is queued."""
        with self._cond:
            return not self._queue

    def predicted_state(self, k: int, segments: list[Segment] | None = None) -> np.ndarray | None:
        """The state the timeline (default: the queued one) reaches at sample ``k`` (None if idle)."""
        if segments is None:
            _, segments = self.snapshot()
        return predicted_state(segments, k)

    def start_now(self, segment: Segment) -> int:
        """Start ``segment`` on the next sample of an idle stream; returns its start index (samples)."""
        with self._cond:
            if self._queue:
                raise RuntimeError("stream is not idle; splice instead")
            self._rebase_if_sleeping()
            segment.start = self._k_next
            self._queue.append(segment)
            self._cond.notify_all()
            return segment.start

    def splice(self, segment: Segment, at: int) -> bool:
        """Play ``segment`` from global sample ``at``, replacing whatever was planned from there.

        Returns False (and changes nothing) if sample ``at`` has already been
        sent (planning overran its look-ahead) or the stream went idle
        meanwhile (then :meth:`start_now` applies).
        """
        with self._cond:
            if not self._queue or at < self._k_next:
                return False
            self._queue = [s for s in self._queue if s.start < at]
            segment.start = at
            self._queue.append(segment)
            self._cond.notify_all()
            return True

    def time_of(self, k: int) -> float:
        """Deadline (clock s) of global sample ``k``."""
        with self._cond:
            return self._t_anchor + (k - self._k_anchor) * self.dt

    def recent_timing(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Send times (clock s) and lateness (s) of the last ``n`` samples sent.

        Both empty for ``n <= 1`` (a single sample has no period); at most
        the ``record`` samples kept.
        """
        if n <= 1:
            return np.empty(0), np.empty(0)
        return np.array(list(self.sent_times)[-n:]), np.array(list(self.lateness)[-n:])

    # --------------------------------------------------------------------- loop
    def step(self) -> StreamStep | None:
        """Handle the next sample: sleep until its deadline, then publish its command.

        A late sample is handled at once (never skipped); the deadlines stay
        on the absolute grid.  The thread started by :meth:`start` calls this
        in a loop; a test may call it instead (never both).

        Returns
        -------
        StreamStep or None
            None, without sleeping, if nothing is due: stopped, or idle with
            ``hold_when_idle`` off (the thread then waits for work).
        """
        with self._cond:
            if self._stop or self._sleeping():
                return None
            k = self._k_next
            deadline = self._t_anchor + (k - self._k_anchor) * self.dt
        delay = deadline - self._clock()
        if delay > 0.0:
            self._sleep(delay)
        with self._cond:
            if self._stop:
                return None
            # chosen after the sleep: a splice at k made meanwhile takes effect at k
            value, started, finished = self._next_value(k)
            self._k_next = k + 1
        now = self._clock()
        if value is not None:
            self._publish(value)
            self.sent_times.append(now)
            self.lateness.append(now - deadline)
            self.samples_sent += 1
        if started is not None:
            started.started_at = now
            if self._on_start is not None:
                self._on_start(started)
        if finished is not None and self._on_finish is not None:
            self._on_finish(finished)
        return StreamStep(sample=k, deadline=deadline, time=now, value=value)

    def _sleeping(self) -> bool:
        # idle and silent: nothing is due until start_now or the setter
        return not self._queue and not self._hold_when_idle

    def _rebase_if_sleeping(self) -> None:
        # A silent idle stream sleeps; when work arrives, sample k_next is due now.
        if self._sleeping():
            self._t_anchor = self._clock()
            self._k_anchor = self._k_next

    def _next_value(self, k: int) -> tuple[float | None, Segment | None, Segment | None]:
        """Command for sample ``k`` (None: send nothing), and the segment that starts / finishes."""
        q = self._queue
        while len(q) > 1 and q[1].start <= k:  # a splice takes over
            q.pop(0)
        idle_value = HOLD if self._hold_when_idle else None
        if not q:
            return idle_value, None, None
        seg = q[0]
        i = k - seg.start
        if i < 0:  # waiting for a segment queued behind an ended one: at rest
            return idle_value, None, None
        if i < seg.samples:
            return float(seg.commands[i]), (seg if i == 0 else None), None
        if i == seg.samples:  # the explicit hold that ends a move
            started = seg if seg.samples == 0 else None
            if len(q) == 1:
                q.pop(0)
                return HOLD, started, seg
            return HOLD, started, None
        return idle_value, None, None

    def _set_priority(self) -> None:
        if self.priority <= 0:
            return
        try:
            os.sched_setscheduler(threading.get_native_id(), os.SCHED_FIFO, os.sched_param(self.priority))
        except (AttributeError, OSError) as exc:  # not Linux, or not permitted
            self.priority_error = f"SCHED_FIFO priority {self.priority} refused ({exc}); normal scheduling"

    def _run(self) -> None:
        self._set_priority()
        self._started.set()
        while True:
            with self._cond:
                while not self._stop and self._sleeping():
                    self._cond.wait()  # start_now / the setter re-anchor the deadlines
                if self._stop:
                    return
            self.step()


__all__ = ["CommandStream", "StreamStep"]
