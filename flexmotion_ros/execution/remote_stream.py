"""The planner's side of the stream process: :class:`RemoteStream`, a :class:`~.command_stream.CommandStream` by proxy.

The deadline loop and the ``commands`` publisher run in a child process
(:mod:`.stream_process`); the planner keeps every decision.  This object
offers the stream's interface (timeline snapshots and versions, ``start_now``,
``splice``, ``stop`` with its :class:`~.stream_halt.StreamHalt`, the
samples sent and their timing, ``time_of``) and keeps a mirror of the child's
timeline: the planner's own :class:`~.timeline.Segment` objects (with their
records), pruned from the child's progress by the rule the child's loop
applies.  The child is the authority on what is accepted: a splice at a
sample it has already sent is refused there, as in-process.

The stream's callbacks (a segment's first command, a move's end, each
sample sent: the feedback's estimator, the commands-sent log) run in a
follower thread of the planner that replays the child's shared ring a few
milliseconds later, with the child's send times -- never in the deadline loop.
A fault in the child arrives on its event pipe; the child's death is a fault
too (nothing more can be sent; the log says what was sent last).
"""

from __future__ import annotations

import select
import threading
from collections.abc import Callable

import numpy as np

from .sample_record import RecordedTiming, SampleRecord
from .stream_halt import HaltCause, StreamHalt, StreamStopped
from .stream_ipc import NO_SEGMENT, recv
from .stream_process import StreamProcess
from .timeline import Segment, is_hold, predicted_state

#: How often the follower replays the child's samples (s).
FOLLOW_PERIOD_S = 0.002


def settle_tail(segment: Segment, n: int) -> None:
    """Append ``n`` hold samples to ``segment`` once (the plan ends at rest: its last state stays)."""
    if n <= 0 or getattr(segment, "settle_samples", 0):
        return
    hold = np.zeros((n, *segment.commands.shape[1:]))
    segment.commands = np.concatenate([segment.commands, hold])
    segment.states = np.concatenate([segment.states, np.repeat(segment.states[-1:], n, axis=0)])
    segment.settle_samples = n


class RemoteStream(RecordedTiming):
    """The command stream of a child process, seen from the planner (module docstring).

    Parameters
    ----------
    process : StreamProcess
        The child, configured for this stream.
    rate_hz : float
    hold_when_idle : bool
    priority : int
        ``stream_priority`` (applied in the child).
    on_start, on_finish : callable, optional
        ``f(segment)`` after a segment's first command / after the hold that ends the timeline (follower thread).
    on_fault : callable, optional
        ``f(halt)`` after a fault ended the child's stream (the hold already sent), or the child died.
    on_sample : callable, optional
        ``f(k, u, t_ns)`` per sample sent (model input ``u``; ``t_ns``: system time just before publishing).
    on_publish : callable, optional
        ``f(u, t_ns)`` per sample sent, before ``on_sample`` (the commands-sent log).
    on_start_now : callable, optional
        ``f(segment)`` when a move from idle is installed, before its first sample.
    record : int
        Send times kept (as :class:`CommandStream`).
    """

    def __init__(
        self,
        process: StreamProcess,
        rate_hz: float,
        hold_when_idle: bool = True,
        *,
        priority: int = 0,
        on_start: Callable[[Segment], None] | None = None,
        on_finish: Callable[[Segment], None] | None = None,
        on_fault: Callable[[StreamHalt], None] | None = None,
        on_sample: Callable[[int, object, int], None] | None = None,
        on_publish: Callable[[object, int], None] | None = None,
        on_start_now: Callable[[Segment], None] | None = None,
        record: int = 200_000,
    ) -> None:
        self.process = process
        self.dt = 1.0 / float(rate_hz)
        self.priority = int(priority)
        self.priority_error: str | None = None
        self._hold_when_idle = bool(hold_when_idle)
        self._on_start = on_start
        self._on_finish = on_finish
        self._on_fault = on_fault
        self._on_sample = on_sample
        self._on_publish = on_publish
        self._on_start_now = on_start_now
        self._lock = threading.RLock()  # the mirror, the version, the requests (one at a time)
        self._replay_lock = threading.Lock()  # the follower's, or stop's, replay of the child's rows
        self._queue: list[Segment] = []
        self._by_id: dict[int, Segment] = {}
        self._next_id = 0
        self._version = 0
        self._record = SampleRecord(record)
        self._replayed = process.progress.written  # rows of earlier configurations are not ours
        self.rows_lost = 0
        self.samples_sent = 0
        self.last_value: float | None = None
        self.halted: StreamHalt | None = None
        self.settle_samples = 0
        self._active = False
        self._stop_follow = threading.Event()
        self._follower = threading.Thread(target=self._follow, name="flexmotion-stream-follower", daemon=True)
        self._follower.start()

    # ------------------------------------------------------------------ control
    def start(self) -> None:
        """Start the child's deadline loop (again after a stop: idle, the sample index continuing)."""
        with self._lock:
            self._queue = []
            self.halted = None
            self.priority_error = self.process.call("start")
            self._active = True

    @property
    def running(self) -> bool:
        """The child's loop runs and has not halted."""
        return self._active and self.halted is None and not self.process.dead

    def stop(self, why: str = "stopped", timeout: float = 2.0) -> StreamHalt:
        """End the child's stream with the hold (idempotent: a second call returns the first halt)."""
        with self._lock:
            if self.halted is not None:
                return self.halted
            self._active = False
            try:
                halt = self.process.call("stop", why, timeout, timeout=timeout + 3.0)
            except RuntimeError as exc:
                halt = self._lost(str(exc))
            self._queue = []
            self.halted = halt
        self.replay()  # the hold's row: the commands-sent log and the count include it
        return halt

    def _lost(self, error: str) -> StreamHalt:
        """The halt of a child that cannot answer: nothing more could be sent."""
        last = self.last_value
        return StreamHalt(
            cause=HaltCause.FAULT,
            why=f"the stream process is gone ({error})",
            held=last is None or is_hold(last),
            hold_sent=False,
            interrupted=bool(self._queue),
            sample=self.process.progress.k_next,
            last_value=last,
            hold_error="the stream process is gone",
        )

    def close(self) -> None:
        """Stop the follower (the node's cleanup; the child stays for the next configuration)."""
        self._stop_follow.set()
        if self._follower is not threading.current_thread():
            self._follower.join(1.0)

    @property
    def hold_when_idle(self) -> bool:
        """Keep sending the hold while idle."""
        return self._hold_when_idle

    @hold_when_idle.setter
    def hold_when_idle(self, value: bool) -> None:
        with self._lock:
            self.process.call("hold_when_idle", bool(value))
            self._hold_when_idle = bool(value)

    # ----------------------------------------------------------------- timeline
    def _pruned(self) -> list[Segment]:
        """The mirror as the child's loop has left it after its last sample (``CommandStream._next_value``)."""
        k = self.process.progress.k_next - 1  # the last sample chosen
        q = self._queue
        while len(q) > 1 and q[1].start <= k:
            q.pop(0)
        if len(q) == 1 and k >= q[0].end:
            q.pop(0)
        return q

    def snapshot(self) -> tuple[int, list[Segment]]:
        """``(k_next, segments)``: the next index the child sends and the queued timeline."""
        with self._lock:
            return self.process.progress.k_next, list(self._pruned())

    def versioned_snapshot(self) -> tuple[int, list[Segment], int]:
        """:meth:`snapshot` and the timeline's version (segments installed), read together."""
        with self._lock:
            return self.process.progress.k_next, list(self._pruned()), self._version

    @property
    def version(self) -> int:
        """How many segments have been installed."""
        with self._lock:
            return self._version

    @property
    def idle(self) -> bool:
        """No segment is queued."""
        with self._lock:
            return not self._pruned()

    def predicted_state(self, k: int, segments: list[Segment] | None = None) -> np.ndarray | None:
        """The state the timeline (default: the queued one) reaches at sample ``k`` (None if idle)."""
        if segments is None:
            _, segments = self.snapshot()
        return predicted_state(segments, k)

    def _register(self, segment: Segment) -> int:
        settle_tail(segment, self.settle_samples)
        ident = self._next_id
        self._next_id += 1
        self._by_id[ident] = segment
        if len(self._by_id) > 64:  # segments long played are forgotten (bounded)
            for old in sorted(self._by_id)[:-64]:
                del self._by_id[old]
        return ident

    def _check_not_halted(self) -> None:
        if self.halted is not None or not self._active:
            halt = self.halted
            raise StreamStopped(
                "the command stream is stopped" + (f" ({halt.cause.value}: {halt.why})" if halt is not None else "")
            )

    def start_now(self, segment: Segment) -> int:
        """Start ``segment`` on the child's next sample (idle only); returns its start index."""
        with self._lock:
            self._check_not_halted()
            if self._pruned():
                raise RuntimeError("stream is not idle; splice instead")
            ident = self._register(segment)
            if self._on_start_now is not None:
                segment.start = self.process.progress.k_next  # where it will start (set again below)
                self._on_start_now(segment)
            start = self.process.call("start_now", ident, segment.commands, segment.states[:1])
            segment.start = int(start)
            self._queue = [segment]
            self._version += 1
            return segment.start

    def splice(self, segment: Segment, at: int) -> bool:
        """Play ``segment`` from sample ``at`` if the child has not sent it yet (False: nothing changed)."""
        with self._lock:
            self._check_not_halted()
            if not self._pruned() or at < self.process.progress.k_next:
                return False
            ident = self._register(segment)
            if not self.process.call("splice", ident, segment.commands, segment.states[:1], int(at)):
                del self._by_id[ident]
                return False
            segment.start = int(at)
            self._queue = [s for s in self._queue if s.start < at] + [segment]
            self._version += 1
            return True

    def time_of(self, k: int) -> float:
        """Deadline (monotonic s) of global sample ``k``."""
        t_anchor, k_anchor = self.process.progress.anchor
        return t_anchor + (k - k_anchor) * self.dt

    # ---------------------------------------------------------------- follower
    def replay(self) -> None:
        """Replay the samples the child sent since the last call: record, counts, callbacks (one thread at a time)."""
        with self._replay_lock:
            progress = self.process.progress
            last = progress.written
            first = self._replayed
            if last <= first:
                return
            rows, ns = progress.rows_from(first, last)
            self.rows_lost += (last - first) - len(rows)
            self._replayed = last
            inputs = progress.inputs
            for row, t_ns in zip(rows, ns, strict=True):
                k, t, late, started, finished = int(row[0]), row[1], row[2], row[3], row[4]
                u = float(row[5]) if inputs == 1 else row[5 : 5 + inputs].copy()
                if self._on_publish is not None:
                    self._on_publish(u, int(t_ns))
                self.last_value = u
                self._record.append(t, late)
                self.samples_sent += 1
                if started != NO_SEGMENT:
                    seg = self._by_id.get(int(started))
                    if seg is not None:
                        seg.started_at = t
                        if self._on_start is not None:
                            self._on_start(seg)
                if finished != NO_SEGMENT:
                    seg = self._by_id.get(int(finished))
                    if seg is not None and self._on_finish is not None:
                        self._on_finish(seg)
                if self._on_sample is not None:
                    self._on_sample(k, u, int(t_ns))

    def _fault(self, halt: StreamHalt) -> None:
        with self._lock:
            self._active = False
            self._queue = []
            self.halted = halt
        self.replay()
        if self._on_fault is not None:
            self._on_fault(halt)

    def _follow(self) -> None:
        events = self.process.events
        while not self._stop_follow.is_set():
            try:
                ready, _, _ = select.select([events], [], [], FOLLOW_PERIOD_S)
            except (OSError, ValueError):
                return
            try:
                self.replay()
            except Exception:  # noqa: BLE001, S112 -- a callback's failure must not end the follower
                continue
            if not ready:
                continue
            try:
                event = recv(events)
            except (EOFError, OSError):
                if not self._stop_follow.is_set() and self._active:
                    self._fault(self._lost("its event pipe closed: it died"))
                return
            if event[0] == "fault":
                self._fault(event[1])


__all__ = ["FOLLOW_PERIOD_S", "RemoteStream", "settle_tail"]
