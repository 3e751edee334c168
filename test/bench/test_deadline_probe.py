"""The stream benchmarks' comparison with a bare deadline loop (``bench/deadline_probe.py``)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
from deadline_probe import overlapping_gaps  # noqa: E402 -- a script beside the package


def test_a_stream_gap_is_the_machines_only_where_the_bare_loop_stalled_over_it_too():
    ms = 1_000_000
    stream = np.array([0, 1, 2, 6, 7, 8, 20, 21, 22, 40]) * ms  # gaps: 2->6, 8->20, 22->40
    probe = np.array([*range(21), 23, 26, 41]) * ms
    gaps, shared = overlapping_gaps(stream, probe, 2 * ms)
    assert gaps[:, 1].tolist() == [4 * ms, 12 * ms, 18 * ms]
    # the probe ran on time through 2->6 and 8->20 (the stream's own gaps), and stalled 20->23 and 26->41 (the machine)
    assert shared.tolist() == [False, False, True]


def test_no_gap_no_overlap():
    ms = 1_000_000
    gaps, shared = overlapping_gaps(np.arange(10) * ms, np.arange(10) * ms, 2 * ms)
    assert gaps.shape == (0, 2) and shared.size == 0
