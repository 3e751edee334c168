"""The send times and lateness of the samples a stream sent, in a ring allocated once (jitter statistics)."""

from __future__ import annotations

import numpy as np

from .heap import resident_zeros


class SampleRecord:
    """The send time and lateness (s) of the last ``capacity`` samples, in a ring allocated once.

    Constant memory from the start (2 x 8 bytes per sample; a deque of Python
    floats grew the node by ~13 MB over its first 200,000 samples, which the
    storm's RSS measured as a leak).  Appended by the stream thread, read by
    others: a reader takes the count first, so it never sees a slot being
    written except the newest.
    """

    def __init__(self, capacity: int) -> None:
        self._buf = resident_zeros((max(1, int(capacity)), 2))  # resident now: a flat RSS
        self._n = 0  # samples appended so far

    def __len__(self) -> int:
        return min(self._n, len(self._buf))

    def append(self, time_s: float, late_s: float) -> None:
        """Record one sample's send time and lateness (s)."""
        row = self._buf[self._n % len(self._buf)]
        row[0] = time_s
        row[1] = late_s
        self._n += 1

    def last(self, n: int, before: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Send times and lateness of the ``n`` samples that end ``before`` samples ago (those still kept)."""
        total, cap = self._n, len(self._buf)
        end = max(0, total - max(0, before))
        start = max(end - max(0, n), total - cap, 0)
        rows = self._buf[np.arange(start, end) % cap]
        return rows[:, 0].copy(), rows[:, 1].copy()


class RecordedTiming:
    """The timing read-outs of a stream that keeps a :class:`SampleRecord` as ``self._record``."""

    _record: SampleRecord

    def recent_timing(self, n: int, before: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Send times (clock s) and lateness (s) of the last ``n`` samples sent, ``before`` samples ago.

        Both empty for ``n <= 1`` (a single sample has no period); at most
        the samples kept.  ``before``: the samples sent since the window
        ended (a report made later, off the stream thread).
        """
        if n <= 1:
            return np.empty(0), np.empty(0)
        return self._record.last(n, before)

    @property
    def sent_times(self) -> np.ndarray:
        """Send times (clock s) of the samples kept, oldest first."""
        return self._record.last(len(self._record))[0]

    @property
    def lateness(self) -> np.ndarray:
        """Send time minus deadline (s) of the samples kept, oldest first."""
        return self._record.last(len(self._record))[1]


__all__ = ["RecordedTiming", "SampleRecord"]
