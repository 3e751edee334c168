"""Optional compiled kernels of the numerical core (numba), and which path runs.

The planners' hot loops (the certificate's root isolation and refinement,
...) are tens of numpy calls of 1-50 us each on a handful of points: the
cost is the interpreter and numpy's per-call overhead, not arithmetic.
Here the same formulas are compiled by numba (``@njit(cache=True)``, no
object mode, no parallelism) and called once per loop.  The numpy
implementations stay at their call sites and remain the reference; the
compiled path runs when numba is importable (``pip install
'flexmotion_ros[fast]'``) unless ``FLEXMOTION_KERNELS=numpy`` is set
(:mod:`.backend`, read once at import).

:func:`warm_up` compiles (or loads from the on-disk cache) every kernel
signature the planners use, so that the first plan of a process does not
pay for it.
"""

from __future__ import annotations

from . import backend
from .backend import AVAILABLE
from .warm import warm_up

__all__ = ["AVAILABLE", "backend", "warm_up"]
