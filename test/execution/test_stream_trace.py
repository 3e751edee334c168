"""The stream's per-sample trace and the gap classification the storm reports (bench/gap_trace.py)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

from flexmotion_ros.execution.stream_trace import COLUMNS, REQUEST_OPS, StreamTrace, requests_path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
from gap_trace import classify, stall_counts  # noqa: E402 -- a bench script


def test_the_trace_records_a_row_per_sample_and_appends_across_configurations(tmp_path):
    path = str(tmp_path / "trace.npy")
    trace = StreamTrace(path, rows=4)
    for k in range(6):  # two past the capacity: not recorded
        trace.before_publish()
        trace.published(1_000 + k)
        trace.slack(1.0, 2.0, 0 if k == 1 else -1)
        trace.step_done(k, 0.1 * k, 0.1 * k + 0.01)
    trace.save()
    trace.published(2_000)
    trace.step_done(6, 0.6, 0.61)
    trace.save()  # a second configuration of the child: appended
    rows = np.load(path)
    assert rows.shape == (5, len(COLUMNS))
    assert rows[:, 0].tolist() == [0, 1, 2, 3, 6]
    assert rows[1, COLUMNS.index("collected")] == 0 and rows[0, COLUMNS.index("collected")] == -1
    assert rows[4, COLUMNS.index("slack_start")] == 0.0  # no slack work recorded for that step


def _trace(n: int, late: dict[int, float], publish: dict[int, float]) -> np.ndarray:
    """A 1 kHz trace; sample k woke ``late[k]`` s after its deadline, its publish took ``publish[k]`` s."""
    rows = np.zeros((n, len(COLUMNS)))
    for k in range(n):
        deadline = 10.0 + 1e-3 * k
        woke = deadline + late.get(k, 1e-5)
        published = woke + publish.get(k, 5e-5)
        step_end = published + 2e-5
        rows[k, :11] = (k, deadline, woke, int(woke * 1e9), published, published, published, -1, step_end, 0.0, 0.0)
    rows[:, [COLUMNS.index("cpu_step"), COLUMNS.index("cpu_published")]] = -1  # unknown unless a test sets them
    return rows


def test_gaps_are_told_apart_late_wake_blocked_publish_and_transport():
    threshold = 2_000_000
    trace = _trace(100, late={20: 4e-3, 60: 5e-3}, publish={59: 6e-3})
    sent = trace[:, COLUMNS.index("publish_ns")].astype(np.int64)
    received = np.delete(sent + 100_000, [41, 42, 43])  # three samples lost or delayed in transport
    causes = [g["cause"] for g in classify(received, trace, threshold)]
    assert causes == ["late wake", "transport", "step overran"]


def test_the_sleep_records_the_cpus_and_what_the_thread_went_through_and_a_due_sample_records_none(tmp_path):
    path = str(tmp_path / "trace.npy")
    trace = StreamTrace(path, rows=4)
    trace.sleep(0.002)
    trace.before_publish()
    trace.published(1_000)
    trace.step_done(0, 0.0, 0.0)
    trace.before_publish()
    trace.published(2_000)  # due already: no sleep called
    trace.step_done(1, 0.0, 0.0)
    trace.request("splice", 1.0, 1.5)
    trace.request("not a request", 2.0, 2.5)
    trace.save()
    rows = np.load(path)
    col = {c: rows[:, COLUMNS.index(c)] for c in COLUMNS}
    cpus = range(os.cpu_count() or 1)
    assert col["slept_at"][0] > 0.0 and col["cpu_slept"][0] in cpus and col["cpu_woke"][0] in cpus
    assert col["sleep_switches"][0] >= 1  # the sleep itself switched the thread out
    assert col["sleep_runs"][0] >= 1 and col["sleep_cpu_ns"][0] >= 0.0 and col["sleep_faults"][0] >= 0
    assert (col["slept_at"][1], col["cpu_slept"][1], col["cpu_woke"][1], col["sleep_switches"][1]) == (0, -1, -1, 0)
    requests = np.load(requests_path(path))
    assert requests.tolist() == [[REQUEST_OPS.index("splice"), 1.0, 1.5], [-1, 2.0, 2.5]]


def test_a_gap_is_a_machine_stall_only_where_the_loop_pinned_to_the_stream_threads_cpu_was_late_too():
    threshold = 2_000_000
    trace = _trace(100, late={20: 4e-3, 50: 4e-3, 80: 4e-3}, publish={})
    cpu = COLUMNS.index("cpu_woke")
    trace[:, COLUMNS.index("cpu_slept")] = trace[:, cpu] = trace[:, COLUMNS.index("cpu_step")] = 0
    trace[50, COLUMNS.index("cpu_slept")] = trace[50, cpu] = trace[50, COLUMNS.index("cpu_step")] = 1
    trace[80, COLUMNS.index("sleep_switches")] = 3  # blocked again after the timer woke it
    sent = trace[:, COLUMNS.index("publish_ns")].astype(np.int64)
    ms = 1_000_000
    t0 = int(sent[0])
    on_time = np.arange(-5, 105) * ms + t0

    def stalled(*windows: tuple[float, float]) -> np.ndarray:  # a pinned loop late over each (start, length) ms
        w = on_time
        for at, length in windows:
            w = np.append(w[(w < t0 + at * ms) | (w > t0 + (at + length) * ms)], t0 + int((at + length) * ms))
        return np.sort(w)

    # the gap at sample 20 (CPU 0): the loop on CPU 0 late; at 50 (CPU 1): only CPU 0's loop late; at 80: none
    probes = {0: stalled((19.5, 4.0), (49.5, 4.0)), 1: on_time}
    requests = np.array([[REQUEST_OPS.index("splice"), trace[79, COLUMNS.index("step_end")] + 1e-4, trace[80, 2]]])
    gaps = classify(sent, trace, threshold, probes_by_cpu=probes, requests=requests)
    assert [g["cause"] for g in gaps] == ["late wake"] * 3
    assert [g["stall"] for g in gaps] == ["same CPU", "other CPU", "none"]
    assert [g["cpu_woke"] for g in gaps] == [0, 1, 0]
    assert gaps[2]["sleep_switches"] == 3 and gaps[2]["requests"] == ["splice"] and gaps[0]["requests"] == []
    assert gaps[0]["probe_ms_by_cpu"][0] > 3.0 and gaps[0]["probe_ms_by_cpu"][1] == 1.0
    assert stall_counts(gaps) == {"same CPU": 1, "other CPU": 1, "none": 1}
    # no pinned loops: unknown
    assert {g["stall"] for g in classify(sent, trace, threshold)} == {"unknown"}


def test_a_sample_due_before_any_sleep_is_placed_by_the_cpu_its_step_started_on_and_a_blocked_publish_is_shown():
    threshold = 2_000_000
    trace = _trace(100, late={30: 4e-3, 70: 2.5e-3}, publish={69: 3e-3})
    for c in ("cpu_slept", "cpu_woke"):
        trace[:, COLUMNS.index(c)] = -1  # every sample was due already: no sleep, no sleep CPU
    trace[:, COLUMNS.index("cpu_step")] = trace[:, COLUMNS.index("cpu_published")] = 1
    trace[69, COLUMNS.index("publish_switches")] = 2  # blocked inside publish
    sent = trace[:, COLUMNS.index("publish_ns")].astype(np.int64)
    ms, t0 = 1_000_000, int(sent[0])
    on_time = np.arange(-5, 105) * ms + t0
    late = np.sort(np.append(on_time[(on_time < t0 + 29 * ms) | (on_time > t0 + 33 * ms)], t0 + 33 * ms))
    requests = np.array([[REQUEST_OPS.index("splice"), trace[69, 2] + 1e-4, trace[69, 2] + 2e-4]])
    gaps = classify(sent, trace, threshold, probes_by_cpu={0: on_time, 1: late}, requests=requests)
    assert [g["cause"] for g in gaps] == ["late wake", "step overran"]
    assert [g["stall"] for g in gaps] == ["same CPU", "none"]  # was "unknown" without the step's CPU
    assert gaps[1]["publish_switches"] == 2 and gaps[1]["publish_requests"] == ["splice"]
    assert gaps[0]["publish_requests"] == []


def test_the_trace_records_the_cpu_and_the_context_switches_around_publish(tmp_path):
    path = str(tmp_path / "trace.npy")
    trace = StreamTrace(path, rows=2)
    trace.before_publish()
    trace.published(1_000)
    trace.step_done(0, 0.0, 0.0)
    trace.save()
    row = np.load(path)[0]
    cpus = range(os.cpu_count() or 1)
    assert row[COLUMNS.index("cpu_step")] in cpus and row[COLUMNS.index("cpu_published")] in cpus
    assert row[COLUMNS.index("publish_switches")] >= 0 and row[COLUMNS.index("publish_preempted")] >= 0
