"""A per-sample trace of the stream process's deadline loop, for the benchmarks (off unless asked for).

A gap in the commands a subscriber receives is either the stream's own (the
loop woke late, or ``publish`` itself blocked) or the transport's / the
receiver's (the sample left on time and arrived late, or not at all).  Only
the sender can tell: with the environment variable :data:`TRACE_ENV` set to a
file name, the stream process records for every sample sent its deadline, the
instant the loop woke, the system time just before ``publish`` and the
instants ``publish`` returned and the step ended (after the slack work: a
garbage collection), and writes them to that file (``.npy``, one row per
sample, columns :data:`COLUMNS`) when its stream ends.  ``bench/storm.py``
sets it and classifies every gap with it.  Memory is allocated once
(:data:`TRACE_ROWS` rows, 88 bytes each); later samples are not recorded.
"""

from __future__ import annotations

import os
import time

import numpy as np

#: Environment variable naming the trace file (unset: no trace).
TRACE_ENV = "FLEXMOTION_STREAM_TRACE"
#: Rows kept (20 min at 1 kHz).
TRACE_ROWS = 1_200_000
#: Columns: the sample index, its deadline, the wake-up after the sleep, the system time before publishing (ns),
#: the instant publish returned, the start of the slack work, the end of the matched-count refresh in it, the
#: generation collected in it (-1: none), the end of the step, and the stream thread's run delay (its time waiting
#: on a run queue, cumulative, ns; ``/proc/thread-self/schedstat``; 0 where not Linux) before and after publishing.
#: Monotonic columns in s.
COLUMNS = (
    "k",
    "deadline",
    "woke",
    "publish_ns",
    "published",
    "slack_start",
    "matched_end",
    "collected",
    "step_end",
    "run_delay_before",
    "run_delay_after",
)
(
    K,
    DEADLINE,
    WOKE,
    PUBLISH_NS,
    PUBLISHED,
    SLACK_START,
    MATCHED_END,
    COLLECTED,
    STEP_END,
    RUN_DELAY_BEFORE,
    RUN_DELAY_AFTER,
) = range(len(COLUMNS))


class StreamTrace:
    """Rows of :data:`COLUMNS`, filled by the stream thread (:meth:`published`, :meth:`step_done`).

    Parameters
    ----------
    path : str
        Where :meth:`save` writes the rows (``.npy``).
    rows : int
        Capacity (samples).
    """

    def __init__(self, path: str, rows: int = TRACE_ROWS) -> None:
        self.path = path
        self._rows = np.zeros((int(rows), len(COLUMNS)))
        self._n = 0
        self._publish_ns = 0
        self._published = 0.0
        self._slack = (0.0, 0.0, -1.0)
        self._delay = (0.0, 0.0)
        self._schedstat: int | None = None

    @classmethod
    def from_environment(cls) -> StreamTrace | None:
        """A trace if :data:`TRACE_ENV` names a file, else None."""
        path = os.environ.get(TRACE_ENV, "")
        return cls(path) if path else None

    def run_delay(self) -> float:
        """The calling thread's cumulative run-queue wait (ns; 0 if unknown): read before and after publishing."""
        try:
            if self._schedstat is None:
                self._schedstat = os.open("/proc/thread-self/schedstat", os.O_RDONLY)
            return float(os.pread(self._schedstat, 64, 0).split()[1])
        except (OSError, IndexError, ValueError):
            return 0.0

    def published(self, publish_ns: int, delay_before: float) -> None:
        """Publish returned (``publish_ns``: the system time just before it, ns; the run delay then, ns)."""
        self._publish_ns = publish_ns
        self._published = time.monotonic()
        self._delay = (delay_before, self.run_delay())

    def slack(self, start: float, matched_end: float, collected: int) -> None:
        """The slack work after a sample: its start, the matched count's end (monotonic s), the generation collected."""
        self._slack = (start, matched_end, float(collected))

    def step_done(self, k: int, deadline: float, woke: float) -> None:
        """The step that sent sample ``k`` ended (deadline and wake-up on the monotonic clock, s)."""
        n = self._n
        if n < len(self._rows):
            self._rows[n] = (
                k,
                deadline,
                woke,
                float(self._publish_ns),
                self._published,
                *self._slack,
                time.monotonic(),
                *self._delay,
            )
            self._n = n + 1
        self._slack = (0.0, 0.0, -1.0)

    def save(self) -> None:
        """Write the rows recorded so far (appending to what an earlier configuration of the child wrote)."""
        rows = self._rows[: self._n]
        if os.path.exists(self.path):
            try:
                rows = np.concatenate([np.load(self.path), rows])
            except (OSError, ValueError):
                pass
        np.save(self.path, rows)
        self._n = 0


__all__ = ["COLUMNS", "TRACE_ENV", "TRACE_ROWS", "StreamTrace"]
