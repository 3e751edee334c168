"""The timeline a command stream plays: its queries, the installation of segments, the command due at a sample.

:class:`PlayedTimeline` is the part of :class:`~.command_stream.CommandStream`
that reads and changes its queue of :class:`~.timeline.Segment` s under the
stream's lock: snapshots and the timeline's version (a plan made from an
older snapshot must not be installed), ``start_now`` / ``splice``, the
deadline of a sample, and the command sample ``k`` sends (a splice takes
over at its start; after a move's last command one explicit hold).  The
deadline loop, the thread and the halts are the stream's.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

import numpy as np

from .stream_halt import StreamHalt, StreamStopped
from .timeline import HOLD, Segment, predicted_state


class PlayedTimeline:
    """Mixin of :class:`~.command_stream.CommandStream`: its timeline, under ``self._cond`` (set up by the stream)."""

    _cond: threading.Condition
    _queue: list[Segment]
    _version: int
    _k_next: int
    _t_anchor: float
    _k_anchor: int
    _stop: bool
    _hold_when_idle: bool
    _clock: Callable[[], float]
    dt: float
    halted: StreamHalt | None

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


__all__ = ["PlayedTimeline"]
