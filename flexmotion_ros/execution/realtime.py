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
in-process planning fallback) go back to normal scheduling.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Iterable


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


def normal_scheduling() -> None:
    """The calling thread back to normal scheduling (a thread about to do numerical work; best effort)."""
    try:
        os.sched_setscheduler(threading.get_native_id(), os.SCHED_OTHER, os.sched_param(0))
    except (AttributeError, OSError):
        pass


__all__ = ["lower_threads", "normal_scheduling", "raise_threads"]
