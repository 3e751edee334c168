"""Freed heap memory handed back to the operating system, so that a long-running node's RSS stays flat.

glibc keeps the memory a process frees (numpy arrays of every size, messages,
plans) in its heaps for reuse and returns it to the system only from the top
of a heap.  Under a storm of requests the planner's RSS crept by ~0.7 MB per
1,000 requests once warm (``bench/storm.py``, 200 Hz, 3,000 requests: 189.3,
190.0, 190.7 MB at 1,000, 2,000, 3,000) with no Python object growing; with
``malloc_trim(0)`` every 2 s it stayed at 187.1, 186.4, 185.9 MB.  So the
creep is memory held free, not a leak, and :func:`release_free_heap` gives it
back; the request worker calls it when it goes idle.  A no-op where the C
library has no ``malloc_trim`` (not glibc).

The other half of a flat RSS is the bounded rings (the stream's shared sample
ring, its send-time record, the identification logs): zeroed memory of that
size is mapped lazily, page by page as the ring first fills, so a ring of
7 MB looked like growth for the first 65,536 samples.  :func:`resident_zeros`
and :func:`make_resident` fault every page in when the ring is made: the RSS
is paid at start-up, and the stream's deadline loop never takes a page fault
on a fresh page of its ring.
"""

from __future__ import annotations

import ctypes
import ctypes.util

import numpy as np


def _malloc_trim():
    name = ctypes.util.find_library("c")
    try:
        libc = ctypes.CDLL(name) if name else None
    except OSError:  # no loadable C library under that name: nothing to trim
        return None
    return getattr(libc, "malloc_trim", None)


_TRIM = _malloc_trim()


def release_free_heap() -> bool:
    """Return the C heap's free memory to the system (glibc ``malloc_trim(0)``).

    Returns
    -------
    bool
        True if memory was released, False if none could be (or not glibc).
    """
    if _TRIM is None:
        return False
    return bool(_TRIM(0))  # ctypes releases the interpreter lock for the call


def make_resident(array: np.ndarray) -> np.ndarray:
    """Write ``array`` (zeros) once, so that its pages are resident now rather than at first use.

    Parameters
    ----------
    array : numpy.ndarray
        A freshly made array (its contents are overwritten with zeros).

    Returns
    -------
    numpy.ndarray
        The same array.
    """
    array.fill(0)  # a write to every page: reading the kernel's zero page would map nothing
    return array


def resident_zeros(shape, dtype=np.float64) -> np.ndarray:
    """``numpy.zeros(shape, dtype)`` with every page resident (see :func:`make_resident`)."""
    return make_resident(np.empty(shape, dtype=dtype))


__all__ = ["make_resident", "release_free_heap", "resident_zeros"]
