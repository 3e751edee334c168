"""Identification records, ROS-free: what the stream sent and what the machine read, paired by sample.

* :class:`SignalLog` -- a ring of time-stamped rows allocated once: the
  commands the stream actually sent (system time just before each publish,
  value) and the readings received on ``measurements`` (their stamps, one
  value per channel);
* :func:`paired_record` -- the readings of a window paired with the command
  each was read after (the sample convention of
  :mod:`flexmotion_ros.core.model.measurement`: ``y_k`` is read just after
  ``u_k`` is applied).  A lockstep plant stamps ``y_k`` with the send time of
  command ``k``, so each reading pairs with the last command sent at or before
  its stamp, one to one; a missing reading is refused.  A real-time plant
  reads on its own clock: each reading is paired with the command held then
  (approximate: the command acts from its arrival, a fraction of a sample
  later), and the record says so.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from ..core.errors import InputError
from .heap import resident_zeros

#: Most samples a record holds (s of the command rate): the ring buffers are allocated for this.
RECORD_CAPACITY_S = 120.0
#: A lockstep plant stamps each reading with its command's send time: paired readings lie this close (s) after it.
LOCKSTEP_STAMP_TOL = 1e-3


class SignalLog:
    """Time-stamped rows in a ring allocated once; one writer thread, any readers.

    Parameters
    ----------
    capacity : int
        Rows kept.
    width : int
        Values per row.
    """

    def __init__(self, capacity: int, width: int) -> None:
        self._t = resident_zeros(max(1, int(capacity)), dtype=np.int64)
        self._v = resident_zeros((max(1, int(capacity)), max(1, int(width))))
        self._n = 0
        self._lock = threading.Lock()

    @property
    def capacity(self) -> int:
        return int(self._t.size)

    @property
    def count(self) -> int:
        """Rows appended so far (the next row's index)."""
        return self._n

    def append(self, t_ns: int, values) -> None:
        """Append one row (``t_ns``: integer ns)."""
        with self._lock:
            i = self._n % self._t.size
            self._t[i] = t_ns
            self._v[i] = values
            self._n += 1

    def rows(self, first: int, last: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Rows ``first .. last`` (inclusive; None: the newest) as copies ``(t_ns, values)``.

        Raises
        ------
        InputError
            Rows already overwritten (the record is longer than the ring).
        """
        with self._lock:
            n, cap = self._n, self._t.size
            last = n - 1 if last is None else min(int(last), n - 1)
            if first < n - cap:
                raise InputError(
                    "identification.max_record_s",
                    f"the record is longer than the {cap} samples kept; shorten it",
                )
            idx = np.arange(int(first), last + 1) % cap
            return self._t[idx].copy(), self._v[idx].copy()

    def first_at_or_after(self, t_ns: int) -> int:
        """Index of the first kept row stamped at or after ``t_ns`` (``count`` if none)."""
        with self._lock:
            n, cap = self._n, self._t.size
            start = max(0, n - cap)
            idx = np.arange(start, n)
            t = self._t[idx % cap]
        k = int(np.searchsorted(t, t_ns, side="left"))
        return start + k


@dataclass(frozen=True, kw_only=True)
class Record:
    """Commands and readings paired by sample (``u[k]`` applied, then ``y[k]`` read).

    Attributes
    ----------
    u : ndarray, shape ``(K,)``
        Commands (N).
    y : ndarray, shape ``(K, m)``
        Readings, one column per channel.
    dt : float
        Sample time (s).
    exact : bool
        One reading per command (a lockstep plant); False: readings on the
        plant's own clock, paired with the command held then.
    commands : int
        Commands sent in the window.
    """

    u: np.ndarray
    y: np.ndarray
    dt: float
    exact: bool
    commands: int

    @property
    def samples(self) -> int:
        return int(self.u.size)

    @property
    def t(self) -> np.ndarray:
        """Uniform sample times (s) from 0."""
        return self.dt * np.arange(self.u.size)


def paired_record(
    sent: SignalLog, readings: SignalLog, first: int, last: int, t_end_ns: int | None, dt: float
) -> Record:
    """Pair the readings of a window with the commands they were read after.

    Parameters
    ----------
    sent : SignalLog
        Commands sent (system time ns just before publishing, value).
    readings : SignalLog
        Readings received (stamp ns, one value per channel).
    first, last : int
        Indices in ``sent`` of the window's first and last commands.
    t_end_ns : int or None
        Readings stamped at or after this are outside the window (None: one
        sample after the last command).
    dt : float
        Sample time (s).

    Raises
    ------
    InputError
        Parameter ``measurements``: no reading in the window, readings missing
        for some commands of a lockstep plant, or none for the end of the window (stale).
    """
    tc, uc = sent.rows(first, last)
    uc = uc[:, 0]
    if tc.size == 0:
        raise InputError("measurements", "no command was sent in the window")
    dt_ns = int(round(dt * 1e9))
    end = int(tc[-1]) + dt_ns if t_end_ns is None else int(t_end_ns)
    if sent.count > last + 1:  # the next command's reading is outside the window, however soon it was sent
        end = min(end, int(sent.rows(last + 1, last + 1)[0][0]))
    j0 = readings.first_at_or_after(int(tc[0]))
    if j0 >= readings.count:
        raise InputError(
            "measurements",
            "no reading received since the first command of the window: missing (is the plant publishing "
            "'measurements'?) or stale",
        )
    tr, yr = readings.rows(j0)
    keep = tr < end
    tr, yr = tr[keep], yr[keep]
    if np.any(np.diff(tr) < 0):
        raise InputError("measurements", "reading stamps go back in time: two publishers on 'measurements'?")
    j = np.searchsorted(tc, tr, side="right") - 1  # the last command sent at or before each reading
    ok = (j >= 0) & (j < tc.size)
    tr, yr, j = tr[ok], yr[ok], j[ok]
    if tr.size == 0:
        raise InputError("measurements", "no reading in the window: missing or stale")
    lag = (tr - tc[j]) * 1e-9
    exact = bool(np.median(lag) < LOCKSTEP_STAMP_TOL)
    if exact:
        counts = np.bincount(j, minlength=tc.size)
        missing = int(np.count_nonzero(counts == 0))
        if missing or np.any(counts > 1):
            first_missing = int(np.argmax(counts == 0)) if missing else -1
            raise InputError(
                "measurements",
                f"{missing} of {tc.size} commands have no reading (first: sample {first_missing} of the window), "
                f"{int(np.count_nonzero(counts > 1))} more than one: readings lost or stale; nothing identified",
            )
        return Record(u=uc.copy(), y=yr, dt=dt, exact=True, commands=int(tc.size))
    if (end - int(tr[-1])) * 1e-9 > 3.0 * dt and t_end_ns is not None:
        raise InputError(
            "measurements",
            f"the last reading is {(end - int(tr[-1])) * 1e-9:.3g} s before the end of the window: stale",
        )
    return Record(u=uc[j], y=yr, dt=dt, exact=False, commands=int(tc.size))


__all__ = ["LOCKSTEP_STAMP_TOL", "RECORD_CAPACITY_S", "Record", "SignalLog", "paired_record"]
