"""A bare deadline loop in a process of its own: what this machine gives a periodic thread that does nothing else.

The stream benchmarks (``storm.py``, ``ros_streaming.py``) run it beside the
nodes, at the command rate and the stream thread's priority, and compare:
a stream gap that coincides with a gap of this loop is the machine's (the
scheduler, another process, the hypervisor taking the CPU away), not the
planner's.  The loop sleeps to absolute deadlines ``t0 + k / rate`` (as the
stream thread does) and records each wake-up on the wall clock (ns, the time
base of DDS source timestamps); on SIGINT/SIGTERM or after ``--seconds`` it
writes them to ``--out`` (``.npy``, int64).  With ``--cpu`` it is pinned to
that CPU: ``storm.py`` runs one per CPU, so that a stream gap can be compared
with the CPU the stream thread slept and woke on (a stall of one virtual CPU
is seen only by the threads that run on it).

    python bench/deadline_probe.py --rate 1000 --seconds 10 --out /tmp/probe.npy --priority 50 --cpu 1
"""

from __future__ import annotations

import argparse
import os
import signal
import time

import numpy as np


def steal_ticks() -> int:
    """Total CPU time stolen by the hypervisor so far (USER_HZ ticks, from ``/proc/stat``; 0 if unknown)."""
    try:
        with open("/proc/stat") as f:
            fields = f.readline().split()
        return int(fields[8]) if len(fields) > 8 else 0
    except OSError:
        return 0


def overlapping_gaps(stream_ns: np.ndarray, probe_ns: np.ndarray, threshold_ns: int) -> tuple[np.ndarray, np.ndarray]:
    """Stream gaps over ``threshold_ns`` and, for each, whether a probe gap over the same threshold overlaps it.

    Parameters
    ----------
    stream_ns, probe_ns : ndarray
        Sorted send / wake-up instants on one clock (ns).
    threshold_ns : int
        The gap that counts (two periods, ns).

    Returns
    -------
    gaps : ndarray, shape (g, 2)
        Start instant and length (ns) of each stream gap.
    shared : ndarray of bool, shape (g,)
        True where the bare loop had a gap overlapping the stream's.
    """
    s = np.asarray(stream_ns, dtype=np.int64)
    p = np.asarray(probe_ns, dtype=np.int64)
    ds = np.diff(s)
    idx = np.flatnonzero(ds > threshold_ns)
    gaps = np.column_stack([s[idx], ds[idx]]) if idx.size else np.zeros((0, 2), dtype=np.int64)
    dp = np.diff(p)
    pidx = np.flatnonzero(dp > threshold_ns)
    p0, p1 = p[pidx], p[pidx + 1]
    shared = np.array([bool(np.any((p0 < s[i + 1]) & (p1 > s[i]))) for i in idx], dtype=bool)
    return gaps, shared


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rate", type=float, required=True, help="loop rate (Hz)")
    p.add_argument("--seconds", type=float, default=600.0, help="longest run (s)")
    p.add_argument("--priority", type=int, default=0, help="SCHED_FIFO priority (0: normal scheduling)")
    p.add_argument("--out", required=True, help="where the wake-up instants go (.npy)")
    p.add_argument("--cpu", type=int, default=-1, help="pin the loop to this CPU (-1: wherever the scheduler puts it)")
    a = p.parse_args()
    if a.cpu >= 0:
        os.sched_setaffinity(0, {a.cpu})  # before the priority: a SCHED_FIFO loop never runs elsewhere
    if a.priority > 0:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(a.priority))
        except (OSError, AttributeError):
            pass  # normal scheduling, as the stream thread falls back to
    n_max = int(a.seconds * a.rate) + 1
    wakes = np.zeros(n_max, dtype=np.int64)
    done = {"stop": False}

    def _stop(*_: object) -> None:
        done["stop"] = True

    signal.signal(signal.SIGINT, _stop)
    signal.signal(signal.SIGTERM, _stop)
    period = 1.0 / a.rate
    t0 = time.monotonic()
    n = 0
    while n < n_max and not done["stop"]:
        delay = t0 + n * period - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        wakes[n] = time.time_ns()
        n += 1
    np.save(a.out, wakes[:n])


if __name__ == "__main__":
    main()
