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
The halt and step types are :mod:`.stream_halt`'s, the timeline's queries and
installation :mod:`.stream_timeline`'s, the send-time record
:mod:`.sample_record`'s.

The clock, the sleep and the "publish one sample" callable are injected:
:meth:`CommandStream.start` runs :meth:`CommandStream.step` in a dedicated
thread; a test calls :meth:`~CommandStream.step` itself with a fake clock.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable

from .sample_record import RecordedTiming, SampleRecord
from .stream_halt import HaltCause, StreamHalt, StreamStep
from .stream_timeline import PlayedTimeline
from .timeline import HOLD, Segment, is_hold

#: How often ``on_idle`` runs while a silent stream sleeps (s).
IDLE_TICK_S = 0.1


class CommandStream(PlayedTimeline, RecordedTiming):
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


__all__ = ["CommandStream"]
