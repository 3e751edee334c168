"""The stream's per-sample trace and the gap classification the storm reports (bench/gap_trace.py)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from flexmotion_ros.execution.stream_trace import COLUMNS, StreamTrace

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
from gap_trace import classify  # noqa: E402 -- a bench script


def test_the_trace_records_a_row_per_sample_and_appends_across_configurations(tmp_path):
    path = str(tmp_path / "trace.npy")
    trace = StreamTrace(path, rows=4)
    for k in range(6):  # two past the capacity: not recorded
        trace.published(1_000 + k, trace.run_delay())
        trace.slack(1.0, 2.0, 0 if k == 1 else -1)
        trace.step_done(k, 0.1 * k, 0.1 * k + 0.01)
    trace.save()
    trace.published(2_000, 0.0)
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
        rows[k] = (k, deadline, woke, int(woke * 1e9), published, published, published, -1, step_end, 0.0, 0.0)
    return rows


def test_gaps_are_told_apart_late_wake_blocked_publish_and_transport():
    threshold = 2_000_000
    trace = _trace(100, late={20: 4e-3, 60: 5e-3}, publish={59: 6e-3})
    sent = trace[:, COLUMNS.index("publish_ns")].astype(np.int64)
    received = np.delete(sent + 100_000, [41, 42, 43])  # three samples lost or delayed in transport
    causes = [g["cause"] for g in classify(received, trace, threshold)]
    assert causes == ["late wake", "transport", "step overran"]
