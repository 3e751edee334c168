"""Where a stream gap comes from: the sender's trace against the receiver's record (``bench/storm.py`` uses it).

A gap between consecutive commands recorded by ``command_recorder.py``
(DDS source timestamps) is classified with the stream process's own trace
(:mod:`flexmotion_ros.execution.stream_trace`, written when
``FLEXMOTION_STREAM_TRACE`` names a file):

* ``late wake``: the stream's own -- the loop woke more than a period after
  the sample's deadline, and the step before had ended in time (the thread
  was not run: the scheduler, the interpreter lock);
* ``step overran``: the stream's own -- the step before (its publish or the
  slack work after it) ended after this sample's deadline;
* ``publish``: the stream's own -- the sample's ``publish`` call itself took
  over a period (the source timestamp is taken inside it);
* ``transport``: the samples left on time (the sender's trace has no gap
  there): delivery or the receiver's side;
* ``untraced``: no trace covers it.

    python bench/gap_trace.py /tmp/flexmotion_storm_xxxx     # a storm's log directory: its gaps, explained
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from flexmotion_ros.execution.stream_trace import (  # noqa: E402
    COLLECTED,
    COLUMNS,
    DEADLINE,
    MATCHED_END,
    PUBLISH_NS,
    PUBLISHED,
    RUN_DELAY_AFTER,
    RUN_DELAY_BEFORE,
    SLACK_START,
    STEP_END,
    WOKE,
)


def classify(t_ns: np.ndarray, trace: np.ndarray, threshold_ns: int, probe_ns: np.ndarray | None = None) -> list[dict]:
    """Every gap over ``threshold_ns`` in the received send times ``t_ns`` (ns), with its cause (module docstring).

    Parameters
    ----------
    t_ns : ndarray
        Sorted source timestamps of the commands received (ns, system clock).
    trace : ndarray, shape (n, len(COLUMNS))
        The stream process's trace (:data:`~flexmotion_ros.execution.stream_trace.COLUMNS`).
    threshold_ns : int
        Two periods (ns).
    probe_ns : ndarray, optional
        Wake-ups of the bare deadline loop beside the nodes (``deadline_probe.py``, ns): each gap then gets
        ``probe_ms``, the longest interval of the loop's that overlaps it (one period: the loop was on time).

    Returns
    -------
    list of dict
        ``at_ns``, ``ms`` (the received gap), ``own_ms`` (the sender's gap over the same samples), ``wake_late_ms``,
        ``prev_step_ms`` (the step before: wake-up to its end; its parts ``prev_callbacks_ms``, ``prev_matched_ms``,
        ``prev_collect_ms``, ``prev_collected``: the generation collected, -1 none), ``publish_ms`` (the sample after
        the gap), ``cause``.
    """
    t = np.asarray(t_ns, dtype=np.int64)
    out: list[dict] = []
    if t.size < 2:
        return out
    sent = trace[:, PUBLISH_NS].astype(np.int64) if len(trace) else np.zeros(0, np.int64)
    period = np.median(np.diff(trace[:, DEADLINE])) if len(trace) > 2 else 0.0
    p = np.asarray(probe_ns if probe_ns is not None else [], dtype=np.int64)
    for i in np.flatnonzero(np.diff(t) > threshold_ns):
        gap = {"at_ns": int(t[i]), "ms": round((t[i + 1] - t[i]) * 1e-6, 2)}
        if p.size > 1:
            lo = max(int(np.searchsorted(p, t[i])) - 1, 0)
            hi = min(int(np.searchsorted(p, t[i + 1])) + 1, p.size)
            gap["probe_ms"] = round(float(np.diff(p[lo:hi]).max()) * 1e-6, 2) if hi - lo > 1 else None
        j = int(np.searchsorted(sent, t[i], side="right")) - 1
        if j < 0 or j + 1 >= len(sent) or t[i] - sent[j] > threshold_ns:
            out.append({**gap, "cause": "untraced"})
            continue
        a, b = trace[j], trace[j + 1]
        own_ms = (sent[j + 1] - sent[j]) * 1e-6
        wake_late = b[WOKE] - b[DEADLINE]
        prev_step = a[STEP_END] - a[WOKE]
        publish = b[PUBLISHED] - b[WOKE]
        callbacks = a[SLACK_START] - a[PUBLISHED] if a[SLACK_START] else 0.0
        matched = a[MATCHED_END] - a[SLACK_START] if a[SLACK_START] else 0.0
        collect = a[STEP_END] - a[MATCHED_END] if a[SLACK_START] else 0.0
        # waiting on a run queue (the CPU taken by another thread) vs blocked (a lock: the interpreter's, DDS's)
        queued_wake = (b[RUN_DELAY_BEFORE] - a[RUN_DELAY_AFTER]) * 1e-9
        queued_publish = (a[RUN_DELAY_AFTER] - a[RUN_DELAY_BEFORE]) * 1e-9
        if own_ms * 1e6 <= threshold_ns and publish <= period:
            cause = "transport"
        elif publish > period and own_ms * 1e6 <= threshold_ns:
            cause = "publish"
        elif a[STEP_END] > b[DEADLINE] + period:
            cause = "step overran"
        else:
            cause = "late wake"
        out.append(
            {
                **gap,
                "own_ms": round(own_ms, 2),
                "wake_late_ms": round(wake_late * 1e3, 2),
                "prev_step_ms": round(prev_step * 1e3, 2),
                "publish_ms": round(publish * 1e3, 2),
                "prev_callbacks_ms": round(callbacks * 1e3, 2),
                "prev_matched_ms": round(matched * 1e3, 2),
                "prev_collect_ms": round(collect * 1e3, 2),
                "prev_collected": int(a[COLLECTED]),
                "prev_publish_ms": round((a[PUBLISHED] - a[WOKE]) * 1e3, 2),
                "prev_publish_queued_ms": round(queued_publish * 1e3, 2),
                "wake_queued_ms": round(queued_wake * 1e3, 2),
                "cause": cause,
            }
        )
    return out


def own_gaps(trace: np.ndarray, threshold_ns: int, until_ns: int | None = None) -> np.ndarray:
    """Gaps over ``threshold_ns`` between the sender's consecutive publishes: ``(at_ns, ms)`` rows."""
    sent = trace[:, PUBLISH_NS].astype(np.int64)
    if until_ns is not None:
        sent = sent[sent < until_ns]
    d = np.diff(sent)
    idx = np.flatnonzero(d > threshold_ns)
    return np.column_stack([sent[idx], d[idx] * 1e-6]) if idx.size else np.zeros((0, 2))


def log_near(log: str, at_ns: int, window_s: float = 0.3) -> list[str]:
    """Lines of a ROS log (``[LEVEL] [seconds.nanos] ...``) within ``window_s`` of ``at_ns``."""
    lines = []
    for line in log.splitlines():
        m = re.search(r"\[(\d{9,}\.\d+)\]", line)
        if m and abs(float(m.group(1)) - at_ns * 1e-9) <= window_s:
            lines.append(f"{float(m.group(1)) - at_ns * 1e-9:+.3f} s  {line[:220]}")
    return lines


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("logs", help="a storm's log directory (commands.npz, stream_trace.npy, planner.log)")
    p.add_argument("--rate", type=float, default=200.0)
    p.add_argument("--window", type=float, default=0.3, help="log lines this close to each gap (s)")
    a = p.parse_args()
    d = Path(a.logs)
    t = np.load(d / "commands.npz")["send_ns"]
    trace = np.load(d / "stream_trace.npy") if (d / "stream_trace.npy").exists() else np.zeros((0, len(COLUMNS)))
    log = (d / "planner.log").read_text() if (d / "planner.log").exists() else ""
    for g in classify(t, trace, int(2e9 / a.rate)):
        print(g)
        for line in log_near(log, g["at_ns"], a.window):
            print("    ", line)


if __name__ == "__main__":
    main()
