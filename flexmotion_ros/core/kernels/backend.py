"""Which path the numerical kernels take: numba-compiled, or the numpy reference.

Decided once, at import: the compiled kernels run when ``numba`` is
importable (the ``fast`` extra) unless the environment variable
``FLEXMOTION_KERNELS=numpy`` asks for the pure-numpy path.  The numpy
implementations stay at their call sites and remain the reference; a
kernel is only a faster evaluation of the same formulas (it may differ from
numpy in the last bits of ``exp``, ``sin`` and sums).  Tests switch paths by
setting :data:`ACTIVE` (the call sites read it on every call).
"""

from __future__ import annotations

import os

try:  # optional: the ``fast`` extra (pip install 'flexmotion_ros[fast]')
    import numba
except ImportError:  # pragma: no cover - CI installs the extra; the numpy path is the reference
    numba = None

#: ``numba`` could be imported.
AVAILABLE = numba is not None
#: The value of ``FLEXMOTION_KERNELS`` at import (``"numpy"`` forces the numpy path; anything else: compiled if available).
REQUESTED = os.environ.get("FLEXMOTION_KERNELS", "").strip().lower()
#: The compiled kernels run (read by the call sites at every call; tests may set it).
ACTIVE = AVAILABLE and REQUESTED != "numpy"


def njit(fn):
    """``numba.njit(cache=True, error_model="numpy")`` when numba is there, else ``fn`` unchanged.

    No object mode, no parallelism.  ``error_model="numpy"``: a division by
    zero gives ``inf`` / ``nan`` as in numpy (the kernels test for them), not
    an exception.  The on-disk cache (``__pycache__``) makes the first call
    of a new process load the machine code instead of compiling it.
    """
    if numba is None:
        return fn
    return numba.njit(cache=True, error_model="numpy")(fn)
