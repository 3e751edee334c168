"""Scheduling of the threads that share the stream's interpreter lock (Linux ``SCHED_FIFO``).

A real-time stream thread in Python is only as punctual as the thread that
holds the interpreter lock when its deadline comes: if that thread (the
executor answering a request, the diagnostics, a DDS listener callback) runs
under normal scheduling, any other process on the machine can preempt it
while it holds the lock, and the stream waits for a thread that is not
running -- a priority inversion.  Measured with ``bench/storm.py --rate 1000
-p stream_priority:=50`` at load 5: 1,039 stream gaps over two periods in a
60-request storm while a bare deadline loop beside it had 10.  So when the
stream runs under ``SCHED_FIFO`` and planning runs in child processes, every
other thread of the process runs under ``SCHED_FIFO`` one step below the
stream: none of them does heavy work (planning does not happen here) and
none can be preempted by ordinary processes while it holds the lock.
Threads that do numerical work in-process (identification, learning, the
in-process planning fallback) go back to normal scheduling.  And since a
garbage collection holds the lock too, :class:`SlackCollector` runs
collections in the stream's slack after a sample.
"""

from __future__ import annotations

import gc
import os
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable


def _tids() -> list[int]:
    try:
        return [int(t) for t in os.listdir("/proc/self/task")]
    except OSError:  # not Linux
        return [threading.get_native_id()]


def raise_threads(priority: int, *, keep_normal: Iterable[str] = ()) -> str | None:
    """Every thread of this process to ``SCHED_FIFO`` at ``priority``, except the named Python threads.

    Parameters
    ----------
    priority : int
        1..99.
    keep_normal : iterable of str
        Name prefixes of Python threads that stay under normal scheduling.

    Returns
    -------
    str or None
        Why it was refused (not Linux, no permission), else None.
    """
    prefixes = tuple(keep_normal)
    skip = {t.native_id for t in threading.enumerate() if prefixes and t.name.startswith(prefixes)}
    try:
        param = os.sched_param(priority)
        for tid in _tids():
            if tid not in skip:
                try:
                    os.sched_setscheduler(tid, os.SCHED_FIFO, param)
                except ProcessLookupError:  # the thread ended meanwhile
                    pass
    except (AttributeError, OSError) as exc:
        return f"SCHED_FIFO priority {priority} for the node's other threads refused ({exc}); normal scheduling"
    return None


def lower_threads(*, keep_fifo: Iterable[str] = ()) -> None:
    """Every thread of this process but the named Python threads back to normal scheduling (best effort)."""
    prefixes = tuple(keep_fifo)
    kept = {t.native_id for t in threading.enumerate() if prefixes and t.name.startswith(prefixes)}
    try:
        param = os.sched_param(0)
        for tid in _tids():
            if tid not in kept:
                try:
                    os.sched_setscheduler(tid, os.SCHED_OTHER, param)
                except ProcessLookupError:
                    pass
    except (AttributeError, OSError):
        pass


def set_process_priority(pid: int, priority: int) -> str | None:
    """Process ``pid``'s main thread to ``SCHED_FIFO`` ``priority`` (1..99), or with 0 back to normal scheduling.

    Returns why it was refused (not Linux, no permission, no such process), else None.
    """
    try:
        policy = os.SCHED_FIFO if priority > 0 else os.SCHED_OTHER
        os.sched_setscheduler(pid, policy, os.sched_param(max(0, int(priority))))
    except (AttributeError, OSError) as exc:
        return f"SCHED_FIFO priority {priority} for process {pid} refused ({exc})"
    return None


def normal_scheduling() -> None:
    """The calling thread back to normal scheduling (a thread about to do numerical work; best effort)."""
    try:
        os.sched_setscheduler(threading.get_native_id(), os.SCHED_OTHER, os.sched_param(0))
    except (AttributeError, OSError):
        pass


class SlackCollector:
    """Garbage collection in the stream's slack, instead of whenever an allocation crosses a threshold.

    A collection holds the interpreter lock: run by whichever thread happens
    to allocate, it stalls the stream for its whole duration (measured in the
    planner during a 1 kHz storm: young collections of 1.5-3.4 ms, dozens a
    minute).  While enabled, automatic collection is off; after each sample
    the stream thread calls this object with the time left until its next
    deadline, and it collects the oldest generation that is due (its count
    from :func:`gc.get_count` at :func:`gc.get_threshold`) if that
    generation's expected cost fits in ``fraction`` of it.  A generation due
    for longer than ``force_after_s`` is collected anyway, so that cyclic
    garbage stays bounded.  The expected cost is the largest of the last
    eight measured durations of that generation.

    Parameters
    ----------
    fraction : float
        Share of the slack a collection may use.
    force_after_s : tuple of float
        Per generation 0, 1, 2: the longest a due collection waits for slack (s).
    clock : callable
        Wall clock (s) for the durations and the waits.
    """

    def __init__(
        self,
        fraction: float = 0.5,
        force_after_s: tuple[float, float, float] = (1.0, 5.0, 60.0),
        clock: Callable[[], float] = time.perf_counter,
    ) -> None:
        self.fraction = float(fraction)
        self.force_after_s = tuple(float(f) for f in force_after_s)
        self._clock = clock
        self._costs: tuple[deque[float], ...] = tuple(deque(maxlen=8) for _ in range(3))
        self._due_since: list[float | None] = [None, None, None]
        self._was_enabled = True
        self.enabled = False
        #: Collections run per generation, and how many of them were forced (no slack in time).
        self.collections = [0, 0, 0]
        self.forced = [0, 0, 0]

    def enable(self, *, prime: bool = False, freeze: bool = False) -> None:
        """Automatic collection off; collections from now on in the slack (:meth:`__call__`, :meth:`idle`).

        Parameters
        ----------
        prime : bool
            Collect every generation now and measure each (:meth:`prime`): call it before the deadlines start.
        freeze : bool
            With ``prime``: move the survivors of the full collection to the permanent generation
            (:func:`gc.freeze`), so that a later full collection scans only what was allocated since.
        """
        if not self.enabled:
            self._was_enabled = gc.isenabled()
            gc.disable()
            self.enabled = True
        if prime:
            self.prime(freeze=freeze)

    def prime(self, *, freeze: bool = False) -> None:
        """Collect everything now and measure the cost of each generation (no deadline may be running).

        Before a generation's first measurement its expected cost is 0, so the
        first sample after it became due would collect it, however long it
        takes: in the stream process, whose heap holds rclpy and numpy, the
        first full collection took 55-96 ms under load (traced: the storm's
        first gap, at the stream's start).  Primed, the costs are known before
        the first sample, and with ``freeze`` (the stream process: its heap
        at the start lives as long as it does) a full collection later
        scans only the objects made since.
        """
        gc.collect()
        if freeze:
            gc.freeze()
        for g in (0, 1, 2):
            t0 = self._clock()
            gc.collect(g)
            self._costs[g].append(self._clock() - t0)
            self._due_since[g] = None

    def disable(self) -> None:
        """Automatic collection as it was before :meth:`enable`."""
        if self.enabled:
            self.enabled = False
            if self._was_enabled:
                gc.enable()

    def expected_cost(self, generation: int) -> float:
        """Expected duration of a collection of ``generation`` (s; 0 before the first)."""
        costs = self._costs[generation]
        return max(costs) if costs else 0.0

    def __call__(self, slack_s: float) -> None:
        """After a sample: collect what is due if it fits in ``fraction * slack_s`` (s), or has waited too long."""
        if not self.enabled:
            return
        counts, thresholds = gc.get_count(), gc.get_threshold()
        now = self._clock()
        for g in (2, 1, 0):  # the oldest due generation first (a collection of it includes the younger)
            if counts[g] < thresholds[g]:
                self._due_since[g] = None
                continue
            since = self._due_since[g]
            if since is None:
                self._due_since[g] = since = now
            forced = now - since > self.force_after_s[g]
            if forced or self.expected_cost(g) <= self.fraction * slack_s:
                self._collect(g, forced)
                return

    def idle(self) -> None:
        """Collect whatever is due now (the stream sends nothing: no deadline to keep)."""
        if not self.enabled:
            return
        counts, thresholds = gc.get_count(), gc.get_threshold()
        for g in (2, 1, 0):
            if counts[g] >= thresholds[g]:
                self._collect(g, False)
                return

    def _collect(self, generation: int, forced: bool) -> None:
        t0 = self._clock()
        gc.collect(generation)
        self._costs[generation].append(self._clock() - t0)
        for g in range(generation + 1):
            self._due_since[g] = None
        self.collections[generation] += 1
        self.forced[generation] += int(forced)


__all__ = ["SlackCollector", "lower_threads", "normal_scheduling", "raise_threads", "set_process_priority"]
