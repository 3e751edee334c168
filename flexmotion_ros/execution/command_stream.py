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

Whatever ends the stream -- :meth:`CommandStream.stop` (shutdown,
deactivation) or a fault in the stream thread (the publisher or a callback
raised) -- the last command sent is the hold: a move in progress is cut off
and one hold sample follows at once (:class:`StreamHalt` says what happened).
A stopped stream can be started again (:meth:`CommandStream.start`).

The clock, the sleep and the "publish one sample" callable are injected:
:meth:`CommandStream.start` runs :meth:`CommandStream.step` in a dedicated
thread; a test calls :meth:`~CommandStream.step` itself with a fake clock.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum

import numpy as np

from .heap import resident_zeros
from .timeline import HOLD, Segment, command_text, is_hold, predicted_state

#: How often ``on_idle`` runs while a silent stream sleeps (s).
IDLE_TICK_S = 0.1


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


class StreamStopped(RuntimeError):
    """A segment offered to a stream that has halted (shutdown, deactivation, a fault): nothing is installed.

    A request still being planned when the node shuts down ends so: the caller
    answers it as not planned, not as an internal failure.
    """


class HaltCause(Enum):
    """Why the stream ended (the values are the strings the log shows)."""

    STOPPED = "stopped"  # stop() was called: shutdown, deactivation
    FAULT = "fault"  # the publisher or a callback raised in the stream thread


@dataclass(frozen=True, kw_only=True)
class StreamHalt:
    """How the stream ended: the hold that closed it.

    Attributes
    ----------
    cause : HaltCause
        ``stopped`` (:meth:`CommandStream.stop`) or ``fault``.
    why : str
        The caller's reason (``"shutdown"``, ``"deactivated"``) or the fault (exception and message).
    held : bool
        The last command sent is the hold (:data:`~.timeline.HOLD`); False only if
        publishing the hold failed too (see ``hold_error``).
    hold_sent : bool
        A hold sample was sent to end it (False: the last command sent was already the hold, or none was sent).
    interrupted : bool
        A move was in progress: its remaining commands were dropped.
    sample : int
        Global index (samples) of the next sample not sent.
    last_value : float or None
        The last command sent before the halt (N); None if none was ever sent.
    hold_error : str
        Why publishing the hold failed ("" if it did not).
    """

    cause: HaltCause
    why: str
    held: bool
    hold_sent: bool
    interrupted: bool
    sample: int
    last_value: float | None
    hold_error: str = ""

    def describe(self) -> str:
        """One line for the log: what ended the stream and what the actuator got last."""
        if self.hold_sent:
            what = f"hold ({HOLD:g}) sent at sample {self.sample - 1}"
        elif self.held:
            what = f"the last command sent was already the hold ({HOLD:g})"
        elif self.last_value is None:
            what = "no command was ever sent"
        else:
            what = (
                f"the hold could NOT be sent ({self.hold_error}); the last command sent was "
                f"{command_text(self.last_value)}"
            )
        cut = "; the move in progress was cut off" if self.interrupted else ""
        return f"command stream {self.cause.value} ({self.why}): {what}{cut}"


class SampleRecord:
    """The send time and lateness (s) of the last ``capacity`` samples, in a ring allocated once.

    Constant memory from the start (2 x 8 bytes per sample; a deque of Python
    floats grew the node by ~13 MB over its first 200,000 samples, which the
    storm's RSS measured as a leak).  Appended by the stream thread, read by
    others: a reader takes the count first, so it never sees a slot being
    written except the newest.
    """

    def __init__(self, capacity: int) -> None:
        self._buf = resident_zeros((max(1, int(capacity)), 2))  # resident now: a flat RSS
        self._n = 0  # samples appended so far

    def __len__(self) -> int:
        return min(self._n, len(self._buf))

    def append(self, time_s: float, late_s: float) -> None:
        """Record one sample's send time and lateness (s)."""
        row = self._buf[self._n % len(self._buf)]
        row[0] = time_s
        row[1] = late_s
        self._n += 1

    def last(self, n: int, before: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Send times and lateness of the ``n`` samples that end ``before`` samples ago (those still kept)."""
        total, cap = self._n, len(self._buf)
        end = max(0, total - max(0, before))
        start = max(end - max(0, n), total - cap, 0)
        rows = self._buf[np.arange(start, end) % cap]
        return rows[:, 0].copy(), rows[:, 1].copy()


class RecordedTiming:
    """The timing read-outs of a stream that keeps a :class:`SampleRecord` as ``self._record``."""

    _record: SampleRecord

    def recent_timing(self, n: int, before: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Send times (clock s) and lateness (s) of the last ``n`` samples sent, ``before`` samples ago.

        Both empty for ``n <= 1`` (a single sample has no period); at most
        the samples kept.  ``before``: the samples sent since the window
        ended (a report made later, off the stream thread).
        """
        if n <= 1:
            return np.empty(0), np.empty(0)
        return self._record.last(n, before)

    @property
    def sent_times(self) -> np.ndarray:
        """Send times (clock s) of the samples kept, oldest first."""
        return self._record.last(len(self._record))[0]

    @property
    def lateness(self) -> np.ndarray:
        """Send time minus deadline (s) of the samples kept, oldest first."""
        return self._record.last(len(self._record))[1]


class CommandStream(RecordedTiming):
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
    on_fault : callable, optional
        ``f(halt)`` after a fault in the stream thread ended the stream (the
        hold already sent, :class:`StreamHalt`).  Called from the stream thread.
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
    after_sample : callable, optional
        ``f(slack)`` after each sample, with the time left until the next
        deadline (s): work that must not delay a sample (e.g.
        :class:`~.realtime.SlackCollector`).  Called from the stream thread.
    on_idle : callable, optional
        ``f()`` every :data:`IDLE_TICK_S` while the stream sleeps (idle and
        silent: no deadline to keep), in the stream thread: the periodic work of
        a process whose only thread that must run is this one.
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
        on_fault: Callable[[StreamHalt], None] | None = None,
        after_sample: Callable[[float], None] | None = None,
        on_idle: Callable[[], None] | None = None,
    ) -> None:
        self.dt = 1.0 / float(rate_hz)
        self._publish = publish
        self._hold_when_idle = bool(hold_when_idle)
        self._on_start = on_start
        self._on_finish = on_finish
        self._on_fault = on_fault
        self._after_sample = after_sample
        self._on_idle = on_idle
        self._clock = clock
        self._sleep = sleep
        self._cond = threading.Condition()
        self._queue: list[Segment] = []
        self._version = 0  # segments installed: a plan from an older snapshot must not be installed
        self._k_next = 0
        self._t_anchor = clock()  # start() re-anchors: sample 0 is due when the stream starts
        self._k_anchor = 0
        self._stop = False
        self._stop_why = "stopped"
        self._thread: threading.Thread | None = None
        self._record = SampleRecord(record)  # send times and lateness (s) of the last `record` samples
        self.samples_sent = 0
        self.priority = int(priority)
        self.priority_error: str | None = None
        self._started = threading.Event()
        #: The last command published (N); None before the first.
        self.last_value: float | None = None
        #: How the stream last ended (None while it has not).
        self.halted: StreamHalt | None = None
        self._halt_lock = threading.Lock()  # one hold per halt, from whichever thread gets there first

    # ------------------------------------------------------------------ control
    def start(self) -> None:
        """Start the stream thread: the next sample (sample 0 at first) is due now.

        After :meth:`stop` (or a fault) this starts it again, idle, with the
        global sample index continuing.
        """
        if self._thread is not None and self._thread.is_alive():
            raise RuntimeError("the command stream is already running")
        with self._cond:
            self._stop = False
            self._queue = []
            self._t_anchor = self._clock()
            self._k_anchor = self._k_next
            self.halted = None
        self._started.clear()
        self._thread = threading.Thread(target=self._run, name="flexmotion-stream", daemon=True)
        self._thread.start()
        self._started.wait(2.0)  # priority_error is known when start() returns

    @property
    def running(self) -> bool:
        """The stream thread is alive and not stopping."""
        return self._thread is not None and self._thread.is_alive() and not self._stop

    def stop(self, why: str = "stopped", timeout: float = 2.0) -> StreamHalt:
        """End the stream with the hold: drop what is queued, send one hold sample, stop the thread.

        The stream thread sends the hold at once (at most one period after
        this call, when its sleep ends); if the thread is not running (never
        started, already ended) or does not end within ``timeout`` s, the
        hold is sent from the calling thread.  Idempotent: a second call
        returns the first halt.

        Parameters
        ----------
        why : str
            The reason, for the log (``"shutdown"``, ``"deactivated"``).
        timeout : float
            How long to wait for the thread (s).

        Returns
        -------
        StreamHalt
            What was cut off and whether the hold went out.
        """
        with self._cond:
            self._stop = True
            self._stop_why = why
            self._cond.notify_all()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)
        return self._halt(HaltCause.STOPPED, why)

    def _halt(self, cause: HaltCause, why: str) -> StreamHalt:
        """Drop the timeline and send the hold unless it was the last command sent (once per halt)."""
        # the stream thread publishes under this lock: nothing it sends can follow the hold
        acquired = self._halt_lock.acquire(timeout=1.0)  # a publish stuck for 1 s: send the hold anyway
        try:
            if self.halted is not None:
                return self.halted
            with self._cond:
                self._stop = True
                interrupted = bool(self._queue)
                self._queue = []
                last = self.last_value
                k = self._k_next
            hold_sent, error = False, ""
            if last is not None and not is_hold(last):
                try:
                    self._publish(HOLD)
                    hold_sent = True
                    self.last_value = HOLD
                    with self._cond:
                        self._k_next = k = k + 1
                    self.samples_sent += 1
                except Exception as exc:  # noqa: BLE001 -- reported in the halt, never raised
                    error = f"{type(exc).__name__}: {exc}"
            self.halted = StreamHalt(
                cause=cause,
                why=why,
                held=last is None or is_hold(last) or hold_sent,
                hold_sent=hold_sent,
                interrupted=interrupted,
                sample=k,
                last_value=last,
                hold_error=error,
            )
            return self.halted
        finally:
            if acquired:
                self._halt_lock.release()

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

    def versioned_snapshot(self) -> tuple[int, list[Segment], int]:
        """``(k_next, segments, version)``: :meth:`snapshot` and the timeline's version, read together.

        The version counts the segments installed (:meth:`start_now`, :meth:`splice`): a plan made from a
        snapshot is still valid to install only while the version is unchanged (two planners, one timeline).
        """
        with self._cond:
            return self._k_next, list(self._queue), self._version

    @property
    def version(self) -> int:
        """How many segments have been installed (the timeline's version)."""
        with self._cond:
            return self._version

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

    def _check_not_halted(self) -> None:
        if self._stop:
            halt = self.halted
            raise StreamStopped(
                "the command stream is stopped" + (f" ({halt.cause.value}: {halt.why})" if halt is not None else "")
            )

    def start_now(self, segment: Segment) -> int:
        """Start ``segment`` on the next sample of an idle stream; returns its start index (samples).

        Raises
        ------
        RuntimeError
            The stream is not idle, or it is stopped (:meth:`stop`, a fault).
        """
        with self._cond:
            self._check_not_halted()
            if self._queue:
                raise RuntimeError("stream is not idle; splice instead")
            self._rebase_if_sleeping()
            segment.start = self._k_next
            self._queue.append(segment)
            self._version += 1
            self._cond.notify_all()
            return segment.start

    def splice(self, segment: Segment, at: int) -> bool:
        """Play ``segment`` from global sample ``at``, replacing whatever was planned from there.

        Returns False (and changes nothing) if sample ``at`` has already been
        sent (planning overran its look-ahead) or the stream went idle
        meanwhile (then :meth:`start_now` applies).
        """
        with self._cond:
            self._check_not_halted()
            if not self._queue or at < self._k_next:
                return False
            self._queue = [s for s in self._queue if s.start < at]
            segment.start = at
            self._queue.append(segment)
            self._version += 1
            self._cond.notify_all()
            return True

    def time_of(self, k: int) -> float:
        """Deadline (clock s) of global sample ``k``."""
        with self._cond:
            return self._t_anchor + (k - self._k_anchor) * self.dt

    def anchor(self) -> tuple[float, int]:
        """``(t_anchor, k_anchor)``: sample ``k_anchor`` is due at ``t_anchor`` (clock s); see :meth:`time_of`."""
        with self._cond:
            return self._t_anchor, self._k_anchor

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
            with self._halt_lock:
                if self.halted is not None:  # stop() gave up waiting and sent the hold: nothing after it
                    return None
                self._publish(value)
                self.last_value = value
            self._record.append(now, now - deadline)
            self.samples_sent += 1
        if started is not None:
            started.started_at = now
            if self._on_start is not None:
                self._on_start(started)
        if finished is not None and self._on_finish is not None:
            self._on_finish(finished)
        if self._after_sample is not None:
            self._after_sample(deadline + self.dt - self._clock())
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
            return seg.command(i), (seg if i == 0 else None), None
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
        try:
            while True:
                with self._cond:
                    while not self._stop and self._sleeping():
                        # start_now / the setter re-anchor the deadlines
                        if self._on_idle is None:
                            self._cond.wait()
                        elif not self._cond.wait(IDLE_TICK_S):
                            self._on_idle()
                    if self._stop:
                        break
                self.step()
        except Exception as exc:  # noqa: BLE001 -- a fault ends the stream with the hold, never a traceback
            halt = self._halt(HaltCause.FAULT, f"{type(exc).__name__}: {exc}")
            if self._on_fault is not None:
                try:
                    self._on_fault(halt)
                except Exception:  # noqa: BLE001, S110 -- e.g. the logger is gone at shutdown
                    pass
            return
        self._halt(HaltCause.STOPPED, self._stop_why)


__all__ = ["CommandStream", "HaltCause", "RecordedTiming", "SampleRecord", "StreamHalt", "StreamStep", "StreamStopped"]
