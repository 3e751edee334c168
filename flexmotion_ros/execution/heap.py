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
"""

from __future__ import annotations

import ctypes
import ctypes.util


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


__all__ = ["release_free_heap"]
