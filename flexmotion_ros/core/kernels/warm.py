"""Compile (or load from numba's on-disk cache) every kernel signature the planners call."""

from __future__ import annotations

import time

import numpy as np

from . import backend, roots, smoothed


def warm_up() -> float:
    """Run every compiled kernel once on a tiny 1-mode switching function; the seconds (CPU) it took.

    Called by a node when it is configured, so that its first plan does not
    compile: with numba's cache present this loads machine code (tens of ms),
    with an empty cache it compiles (seconds).  Does nothing (returns 0) on
    the numpy path.
    """
    if not backend.ACTIVE:
        return 0.0
    start = time.process_time()
    sig, wd = np.array([0.1]), np.array([2.0])
    coef = np.array(
        [
            [1.0, -0.2, -3.9, 1.2, 15.4, -8.7, -57.2, 52.6, 197.0],
            [0.5, 2.0, -0.4, -8.0, 3.2, 31.0, -21.0, -112.0, 125.0],
        ]
    )
    coef.flags.writeable = False  # the planners pass ModalResponse's memoised (read-only) coefficients
    rigid = (0.5, 0.0, 1.0, -0.25, True)
    a = np.linspace(0.0, 3.0, 9)[:-1]
    b = a + 3.0 / 8.0
    K = coef.shape[1] - 1
    Da = roots.switching_orders(a, K, *rigid, sig, wd, coef)
    Db = roots.switching_orders(b, K, *rigid, sig, wd, coef)
    inv_fact = np.array([1.0 / np.prod(np.arange(1.0, j)) for j in range(2, K + 1)])
    amp = np.array([float(np.hypot(coef[0, 0], coef[1, 0])) * 2.0**9])
    roots.isolate_and_refine(
        a, b, Da, Db[0].copy(), Db[1].copy(), *rigid, sig, wd, coef,
        0.0, amp, 1e-13, 1000, 40, inv_fact, 1.0 / 40320.0, 1e-15,
    )  # fmt: skip
    GZ = np.column_stack([np.cos(a), np.sin(a), a])
    Z = np.linalg.qr(np.eye(4))[0][:, 1:].copy()
    uw, S = np.full(a.size, 0.1), np.sin(a) + 0.5
    sq = np.hypot(S, 0.01)
    smoothed.smoothed_newton(GZ, Z, uw, np.array([1.0, 0.0, 0.5, 0.1]), S, sq, float(uw @ sq), 0.01, 0.08, 1e-9, 50)
    return time.process_time() - start
