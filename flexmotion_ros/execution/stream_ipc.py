"""The stream process's protocol: length-prefixed pickles over pipes, and its progress in shared memory.

Three pipes (requests in, answers out, events out: a fault) carry
length-prefixed pickles (:func:`send`, :func:`recv`); an anonymous shared
memory (:class:`SharedProgress`), created before the fork, is written by the
child and read by the parent: the next sample index, the samples sent, the
publisher's matched subscriptions, the deadline anchor, and a ring with one
row per sample sent (index, send time, lateness, the segment that started /
finished there, the model input, the system time just before publishing).
The child never waits for the parent: a parent that falls behind by a whole
ring loses rows (counted), never a sample.
"""

from __future__ import annotations

import mmap
import os
import pickle
import struct
from typing import Any

import numpy as np

from .heap import make_resident

#: Rows kept in the shared sample ring (65 s at 1 kHz): how far the parent may fall behind.
RING_ROWS = 1 << 16
#: Values per sample the shared ring has room for (a machine with more inputs streams in-process).
MAX_INPUTS = 8
#: No segment started / finished at this sample (the ring's id columns).
NO_SEGMENT = -1.0

# header slots of SharedProgress
_ROWS, _K_NEXT, _SENT, _MATCHED, _T_ANCHOR, _K_ANCHOR, _INPUTS = range(7)
_HEADER = 8
# ring columns before the m command values
_K, _TIME, _LATE, _STARTED, _FINISHED = range(5)
_FIXED = 5
_LEN = struct.Struct("<I")


def send(fd: int, obj: Any) -> None:
    """Write one length-prefixed pickle to pipe ``fd`` (whole, even if the pipe takes it in parts)."""
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    view = memoryview(_LEN.pack(len(data)) + data)
    while view:
        view = view[os.write(fd, view) :]


def _read_exact(fd: int, n: int) -> bytes:
    parts, left = [], n
    while left:
        chunk = os.read(fd, left)
        if not chunk:
            raise EOFError("the other end closed the pipe")
        parts.append(chunk)
        left -= len(chunk)
    return b"".join(parts)


def recv(fd: int) -> Any:
    """Read one length-prefixed pickle from pipe ``fd`` (EOFError at end of file)."""
    (n,) = _LEN.unpack(_read_exact(fd, _LEN.size))
    return pickle.loads(_read_exact(fd, n))  # noqa: S301 -- our own child / parent, never a stranger


class SharedProgress:
    """The child's progress in anonymous shared memory (created before the fork, read by the parent).

    Parameters
    ----------
    max_inputs : int
        Room for this many command values per sample (the configuration says how many are used).
    rows : int
        Rows of the sample ring.
    """

    def __init__(self, max_inputs: int = MAX_INPUTS, rows: int = RING_ROWS) -> None:
        self.max_inputs = int(max_inputs)
        self.rows = int(rows)
        width = _FIXED + self.max_inputs
        size = 8 * (_HEADER + self.rows * width + self.rows)
        self._map = mmap.mmap(-1, size)  # MAP_SHARED | MAP_ANONYMOUS: the child's writes are the parent's reads
        buf = np.frombuffer(self._map, dtype=np.float64, count=_HEADER + self.rows * width)
        self.header = buf[:_HEADER]
        self.ring = buf[_HEADER:].reshape(self.rows, width)
        self.ring_ns = np.frombuffer(
            self._map, dtype=np.int64, count=self.rows, offset=8 * (_HEADER + self.rows * width)
        )
        make_resident(buf)  # every page now: a flat RSS, and no first-touch fault in the deadline loop
        make_resident(self.ring_ns)

    # ------------------------------------------------------------- the child
    def write_row(self, k: int, t: float, late: float, started: float, finished: float, value, t_ns: int) -> None:
        """Append one sample sent (the row first, then the count: a reader never sees a half-written row)."""
        n = int(self.header[_ROWS])
        i = n % self.rows
        row = self.ring[i]
        row[_K], row[_TIME], row[_LATE], row[_STARTED], row[_FINISHED] = k, t, late, started, finished
        row[_FIXED : _FIXED + int(self.header[_INPUTS])] = value
        self.ring_ns[i] = t_ns
        self.header[_ROWS] = n + 1
        self.header[_SENT] += 1

    def set_inputs(self, m: int) -> None:
        self.header[_INPUTS] = m

    def set_next(self, k_next: int) -> None:
        self.header[_K_NEXT] = k_next

    def set_matched(self, n: int) -> None:
        self.header[_MATCHED] = n

    def set_anchor(self, t_anchor: float, k_anchor: int) -> None:
        self.header[_T_ANCHOR], self.header[_K_ANCHOR] = t_anchor, k_anchor

    # ------------------------------------------------------------ the parent
    @property
    def written(self) -> int:
        """Rows written so far (samples sent by the child's stream)."""
        return int(self.header[_ROWS])

    @property
    def inputs(self) -> int:
        """Command values per sample of the current configuration."""
        return int(self.header[_INPUTS])

    @property
    def k_next(self) -> int:
        """The next sample index the child will send."""
        return int(self.header[_K_NEXT])

    @property
    def matched(self) -> int:
        """The ``commands`` publisher's matched subscriptions (writer side)."""
        return int(self.header[_MATCHED])

    @property
    def anchor(self) -> tuple[float, int]:
        """``(t_anchor, k_anchor)``: sample ``k_anchor`` is due at monotonic time ``t_anchor`` (s)."""
        return float(self.header[_T_ANCHOR]), int(self.header[_K_ANCHOR])

    def rows_from(self, first: int, last: int) -> tuple[np.ndarray, np.ndarray]:
        """Copies of ring rows ``first..last-1`` (their global counts; those overwritten are gone)."""
        idx = np.arange(max(first, last - self.rows), last) % self.rows
        return self.ring[idx].copy(), self.ring_ns[idx].copy()


__all__ = ["MAX_INPUTS", "NO_SEGMENT", "RING_ROWS", "SharedProgress", "recv", "send"]
