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

With one bare deadline loop pinned to each CPU beside the nodes
(``deadline_probe.py --cpu``), each gap is also told a *machine stall* or not:
``stall`` is ``same CPU`` when the loop pinned to a CPU the stream thread
slept or woke on around the gap (the trace's ``cpu_slept`` / ``cpu_woke``) was
late too (an interval over 1.5 periods overlapping the gap), ``other CPU``
when only a loop on another CPU was, ``none`` when no loop was late, and
``unknown`` without per-CPU loops or the thread's CPUs.  What the thread went
through inside the sleep call that ended the gap comes with it
(``sleep_switches``: 1 is the sleep itself, more is a block after the timer
woke it -- the interpreter lock; ``sleep_run_delay_ms``, ``sleep_faults``), and
the stream process's requests handled during the gap (``requests``).

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
    CPU_PUBLISHED,
    CPU_SLEPT,
    CPU_STEP,
    CPU_WOKE,
    DEADLINE,
    MATCHED_END,
    PUBLISH_NS,
    PUBLISH_PREEMPTED,
    PUBLISH_SWITCHES,
    PUBLISHED,
    REQUEST_COLUMNS,
    REQUEST_OPS,
    RUN_DELAY_AFTER,
    RUN_DELAY_BEFORE,
    SLACK_START,
    SLEEP_FAULTS,
    SLEEP_PREEMPTED,
    SLEEP_RUN_DELAY,
    SLEEP_RUNS,
    SLEEP_SWITCHES,
    STEP_END,
    STEP_FAULTS,
    WOKE,
    requests_path,
)

#: A bare loop's interval over this many periods, overlapping a gap, makes it late too.
PROBE_LATE_PERIODS = 1.5


def longest_interval(probe_ns: np.ndarray, start_ns: int, end_ns: int) -> float | None:
    """The longest interval (ms) between the bare loop's wake-ups that overlaps ``[start_ns, end_ns]`` (None: none)."""
    p = np.asarray(probe_ns, dtype=np.int64)
    if p.size < 2:
        return None
    lo = max(int(np.searchsorted(p, start_ns)) - 1, 0)
    hi = min(int(np.searchsorted(p, end_ns)) + 1, p.size)
    return round(float(np.diff(p[lo:hi]).max()) * 1e-6, 2) if hi - lo > 1 else None


def stall_of(cpus: set[int], late_ms: dict[int, float | None], late_over_ms: float) -> str:
    """``same CPU``, ``other CPU``, ``none`` or ``unknown`` (module docstring) from each pinned loop's interval."""
    if not late_ms or not cpus:
        return "unknown"
    late = {c for c, ms in late_ms.items() if ms is not None and ms > late_over_ms}
    if late & cpus:
        return "same CPU"
    return "other CPU" if late else "none"


def classify(
    t_ns: np.ndarray,
    trace: np.ndarray,
    threshold_ns: int,
    probe_ns: np.ndarray | None = None,
    *,
    probes_by_cpu: dict[int, np.ndarray] | None = None,
    requests: np.ndarray | None = None,
) -> list[dict]:
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
    probes_by_cpu : dict, optional
        CPU -> wake-ups (ns) of a bare loop pinned to it: each gap then gets ``probe_ms_by_cpu`` and ``stall``
        (module docstring); ``probe_ms``, if not given by ``probe_ns``, is their longest.
    requests : ndarray, shape (r, 3), optional
        The stream process's request record (:data:`~flexmotion_ros.execution.stream_trace.REQUEST_COLUMNS`).

    Returns
    -------
    list of dict
        ``at_ns``, ``ms`` (the received gap), ``own_ms`` (the sender's gap over the same samples), ``wake_late_ms``,
        ``prev_step_ms`` (the step before: wake-up to its end; its parts ``prev_callbacks_ms``, ``prev_matched_ms``,
        ``prev_collect_ms``, ``prev_collected``: the generation collected, -1 none), ``publish_ms`` (the sample after
        the gap), ``cause``; with the trace's sleep columns ``cpu_slept``, ``cpu_woke``, ``sleep_switches``,
        ``sleep_preempted``, ``sleep_runs``, ``sleep_run_delay_ms``, ``sleep_faults``, ``prev_step_faults``,
        ``requests``; and ``stall`` (``unknown`` without pinned loops).
    """
    t = np.asarray(t_ns, dtype=np.int64)
    out: list[dict] = []
    if t.size < 2:
        return out
    sent = trace[:, PUBLISH_NS].astype(np.int64) if len(trace) else np.zeros(0, np.int64)
    period = np.median(np.diff(trace[:, DEADLINE])) if len(trace) > 2 else 0.0
    p = np.asarray(probe_ns if probe_ns is not None else [], dtype=np.int64)
    by_cpu = {int(c): np.asarray(v, dtype=np.int64) for c, v in (probes_by_cpu or {}).items()}
    late_over_ms = PROBE_LATE_PERIODS * threshold_ns * 0.5e-6
    wide = trace.shape[1] > STEP_FAULTS if trace.ndim == 2 else False  # a trace with the sleep columns
    steps = trace.shape[1] > PUBLISH_PREEMPTED if trace.ndim == 2 else False  # ... and the step / publish columns
    req = np.asarray(requests if requests is not None else np.zeros((0, len(REQUEST_COLUMNS))))
    for i in np.flatnonzero(np.diff(t) > threshold_ns):
        gap: dict = {"at_ns": int(t[i]), "ms": round((t[i + 1] - t[i]) * 1e-6, 2)}
        if p.size > 1:
            gap["probe_ms"] = longest_interval(p, int(t[i]), int(t[i + 1]))
        if by_cpu:
            gap["probe_ms_by_cpu"] = {c: longest_interval(v, int(t[i]), int(t[i + 1])) for c, v in by_cpu.items()}
            if p.size <= 1:
                known = [ms for ms in gap["probe_ms_by_cpu"].values() if ms is not None]
                gap["probe_ms"] = max(known) if known else None
        j = int(np.searchsorted(sent, t[i], side="right")) - 1
        if j < 0 or j + 1 >= len(sent) or t[i] - sent[j] > threshold_ns:
            out.append({**gap, "cause": "untraced", "stall": stall_of(set(), gap.get("probe_ms_by_cpu", {}), 0.0)})
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
        if wide:
            # a late wake: where it slept (its timer) and woke; otherwise the step before ran late too, where it woke
            around = (b[CPU_SLEPT], b[CPU_WOKE]) if cause == "late wake" else (a[CPU_WOKE], b[CPU_SLEPT], b[CPU_WOKE])
            if steps:  # where each step started and published: a sample due before any sleep has no sleep CPU
                around += (b[CPU_STEP],) if cause == "late wake" else (a[CPU_STEP], a[CPU_PUBLISHED], b[CPU_STEP])
            cpus = {int(c) for c in around if c >= 0}
            during = (req[:, 2] >= a[STEP_END]) & (req[:, 1] <= b[WOKE]) if len(req) else np.zeros(0, bool)
            # the publish that took long (this sample's, or the step before's when it overran)
            slow = b if cause == "publish" else a
            in_publish = (req[:, 2] >= slow[WOKE]) & (req[:, 1] <= slow[PUBLISHED]) if len(req) else during
            out[-1].update(
                cpu_slept=int(b[CPU_SLEPT]),
                cpu_woke=int(b[CPU_WOKE]),
                sleep_switches=int(b[SLEEP_SWITCHES]),
                sleep_preempted=int(b[SLEEP_PREEMPTED]),
                sleep_runs=int(b[SLEEP_RUNS]),
                sleep_run_delay_ms=round(b[SLEEP_RUN_DELAY] * 1e-6, 2),
                sleep_faults=int(b[SLEEP_FAULTS]),
                prev_step_faults=int(a[STEP_FAULTS]),
                requests=[REQUEST_OPS[int(o)] if 0 <= o < len(REQUEST_OPS) else "?" for o in req[during, 0]],
                publish_requests=[
                    REQUEST_OPS[int(o)] if 0 <= o < len(REQUEST_OPS) else "?" for o in req[in_publish, 0]
                ],
                stall=stall_of(cpus, gap.get("probe_ms_by_cpu", {}), late_over_ms),
            )
            if steps:
                slow = b if cause == "publish" else a
                out[-1].update(
                    cpu_step=int(b[CPU_STEP]),
                    publish_switches=int(slow[PUBLISH_SWITCHES]),
                    publish_preempted=int(slow[PUBLISH_PREEMPTED]),
                )
        else:
            out[-1]["stall"] = stall_of(set(), gap.get("probe_ms_by_cpu", {}), late_over_ms)
    return out


def stall_counts(explained: list[dict]) -> dict[str, int]:
    """How many of the gaps :func:`classify` explained were each ``stall`` (``same CPU``: a machine stall)."""
    counts: dict[str, int] = {}
    for g in explained:
        counts[g.get("stall", "unknown")] = counts.get(g.get("stall", "unknown"), 0) + 1
    return counts


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
    by_cpu = {int(f.stem.removeprefix("probe_cpu")): np.load(f) for f in d.glob("probe_cpu*.npy")}
    req_file = Path(requests_path(str(d / "stream_trace.npy")))
    requests = np.load(req_file) if req_file.exists() else None
    probe = np.load(d / "probe.npy") if (d / "probe.npy").exists() else None
    for g in classify(t, trace, int(2e9 / a.rate), probe, probes_by_cpu=by_cpu, requests=requests):
        print(g)
        for line in log_near(log, g["at_ns"], a.window):
            print("    ", line)


if __name__ == "__main__":
    main()
