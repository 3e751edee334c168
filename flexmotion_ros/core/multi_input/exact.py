"""Exact simulation of piecewise-constant vector inputs by matrix exponentials.

Over an interval of length ``h`` with constant input vector ``u``::

    x(t + h) = Phi(h) x(t) + Gamma(h) u,   expm([[A, B], [0, 0]] h) = [[Phi, Gamma], [0, I]]

The independent check of every multi-input planner: it forms the full ``A``
and ``B`` of the model and calls :func:`scipy.linalg.expm`; it shares no
formula with :mod:`.response`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.linalg import expm

from .model import MultiModel


@dataclass(frozen=True)
class VectorPiecewise:
    """``u(t) = levels[j]`` (a row of ``m`` values) for ``breaks[j] <= t < breaks[j+1]``.

    Attributes
    ----------
    breaks : ndarray
        Increasing times (s), ``breaks[0] = 0``, ``breaks[-1]`` the duration.
    levels : ndarray, shape ``(len(breaks) - 1, m)``
        Input vector on each interval.
    """

    breaks: np.ndarray
    levels: np.ndarray

    def __post_init__(self) -> None:
        b = np.asarray(self.breaks, dtype=float)
        lv = np.asarray(self.levels, dtype=float)
        if lv.ndim != 2 or b.ndim != 1 or b.size != lv.shape[0] + 1:
            raise ValueError("breaks must have one more entry than the rows of levels")
        if np.any(np.diff(b) < 0.0):
            raise ValueError("breaks must be non-decreasing")
        object.__setattr__(self, "breaks", b)
        object.__setattr__(self, "levels", lv)

    @classmethod
    def from_samples(cls, commands, dt: float) -> VectorPiecewise:
        """A zero-order-hold sequence: row ``k`` held on ``[k dt, (k+1) dt)``."""
        c = np.asarray(commands, dtype=float)
        return cls(dt * np.arange(c.shape[0] + 1), c)

    @property
    def duration(self) -> float:
        """End time (s)."""
        return float(self.breaks[-1])

    def __call__(self, t) -> np.ndarray:
        """``u(t)``, shape ``(len(t), m)``; zero outside ``[0, duration)``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        idx = np.searchsorted(self.breaks, t, side="right") - 1
        inside = (idx >= 0) & (idx < self.levels.shape[0])
        out = np.zeros((t.size, self.levels.shape[1]))
        out[inside] = self.levels[idx[inside]]
        return out


@lru_cache(maxsize=512)
def _step_cached(A_bytes: bytes, B_bytes: bytes, n: int, m: int, h: float) -> tuple[np.ndarray, np.ndarray]:
    A = np.frombuffer(A_bytes).reshape(n, n)
    B = np.frombuffer(B_bytes).reshape(n, m)
    M = np.zeros((n + m, n + m))
    M[:n, :n] = A
    M[:n, n:] = B
    E = expm(M * h)
    return E[:n, :n].copy(), E[:n, n:].copy()


def step_matrices(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """``Phi(h)`` ``(n, n)`` and ``Gamma(h)`` ``(n, m)`` from the augmented matrix exponential (cached)."""
    A = np.ascontiguousarray(A, dtype=float)
    B = np.ascontiguousarray(np.asarray(B, dtype=float).reshape(A.shape[0], -1))
    return _step_cached(A.tobytes(), B.tobytes(), A.shape[0], B.shape[1], float(h))


def system_of(model: MultiModel, kept: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(A, B)`` of the model, restricted to the state entries ``kept`` (an invariant subspace)."""
    A, B = model.A(), model.B()
    if kept is None:
        return A, B
    return A[np.ix_(kept, kept)], B[kept]


def simulate(A: np.ndarray, B: np.ndarray, x0, u: VectorPiecewise, times=None) -> np.ndarray:
    """Exact states under ``u`` at ``times`` (default ``u.breaks``; zero input after the end)."""
    x = np.array(x0, dtype=float)
    times = u.breaks if times is None else np.asarray(times, dtype=float)
    order = np.argsort(times, kind="stable")
    out = np.empty((times.size, x.size))
    m = B.shape[1]
    t_now, k = 0.0, 0
    for j in order:
        target = float(times[j])
        while t_now < target:
            if k < u.levels.shape[0]:
                t_next = min(float(u.breaks[k + 1]), target)
                level = u.levels[k]
            else:
                t_next, level = target, np.zeros(m)
            h = t_next - t_now
            if h > 0.0:
                Phi, Gam = step_matrices(A, B, h)
                x = Phi @ x + Gam @ level
            t_now = t_next
            if k < u.levels.shape[0] and t_now >= u.breaks[k + 1]:
                k += 1
        out[j] = x
    return out


def simulate_samples(A: np.ndarray, B: np.ndarray, x0, commands, dt: float) -> np.ndarray:
    """Exact states at every sample instant of a zero-order-hold sequence ``(K, m)``: ``(K + 1, n)``."""
    Phi, Gam = step_matrices(A, B, dt)
    c = np.asarray(commands, dtype=float)
    out = np.empty((c.shape[0] + 1, A.shape[0]))
    x = np.array(x0, dtype=float)
    out[0] = x
    for k in range(c.shape[0]):
        x = Phi @ x + Gam @ c[k]
        out[k + 1] = x
    return out


def input_integral(A: np.ndarray, B: np.ndarray, tau: float) -> np.ndarray:
    """``Gamma(tau) = int_0^tau e^{A s} B ds`` ``(n, m)`` by the augmented exponential (uncached)."""
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n] = A
    M[:n, n:] = B
    return expm(M * float(tau))[:n, n:]
