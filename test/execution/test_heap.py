"""Bounded rings are resident from the start: the RSS is paid when they are made, not as they first fill.

Each ring is made in a fresh interpreter: in this one, memory freed by an earlier test is already
resident and glibc would hand it back for the next ring, whatever the ring does.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

MEASURE = """
import numpy as np
from flexmotion_ros.execution.sample_record import SampleRecord
from flexmotion_ros.execution.heap import resident_zeros
from flexmotion_ros.execution.records import SignalLog
from flexmotion_ros.execution.stream_ipc import SharedProgress
from flexmotion_ros.execution.stream_trace import COLUMNS, StreamTrace

def rss():
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) * 1024 for line in f if line.startswith("VmRSS:"))

before = rss()
made = {make}
print(rss() - before, {size})
"""


@pytest.mark.skipif(not os.path.exists("/proc/self/status"), reason="reads VmRSS (Linux)")
@pytest.mark.parametrize(
    "make, size",
    [
        ("resident_zeros((1 << 20, 2))", (1 << 20) * 2 * 8),
        ("SampleRecord(400_000)", 400_000 * 2 * 8),
        ("SignalLog(200_000, 3)", 200_000 * (8 + 3 * 8)),
        ("SharedProgress(rows=1 << 16)", 8 * (1 << 16) * 14),
        ("StreamTrace('/dev/null', rows=100_000)", "100_000 * len(COLUMNS) * 8"),
    ],
    ids=[
        "resident_zeros",
        "stream send-time record",
        "identification log",
        "stream process sample ring",
        "stream trace",
    ],
)
def test_rings_are_resident_when_made(make, size):
    out = subprocess.run(
        [sys.executable, "-c", MEASURE.format(make=make, size=size)],
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    )
    grew, size = (int(v) for v in out.stdout.split()[-2:])
    # made with np.zeros (or a fresh mmap), ~0 of it is resident until first written; numpy asks for huge
    # pages on large arrays, so the deadline loop would take a 2 MiB zeroing fault (4 ms at 1 kHz,
    # every 12,483 trace rows) at each boundary
    assert grew >= 0.9 * size, f"{make}: {grew / 2**20:.2f} MiB resident of {size / 2**20:.2f} MiB"


def test_resident_zeros_are_zeros():
    from flexmotion_ros.execution.heap import resident_zeros

    a = resident_zeros((1000, 3), dtype="int64")
    assert a.shape == (1000, 3) and a.dtype.name == "int64" and not a.any()
