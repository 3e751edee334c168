"""Exact simulation of piecewise-constant inputs by matrix exponentials.

Over an interval of length ``h`` with constant input ``u``::

    x(t + h) = Phi(h) x(t) + Gamma(h) u,   expm([[A, B], [0, 0]] h) = [[Phi, Gamma], [0, 1]]

No ODE integrator, no tolerance: the only error is floating-point rounding.
This module is the *independent* check of every planner: it builds the full
``A``, ``B`` and calls :func:`scipy.linalg.expm`; it shares no formulas with
:mod:`flexmotion_ros.core.modal_response`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.linalg import expm

from ..model.modal_model import ModalModel


@dataclass(frozen=True)
class PiecewiseConstant:
    """An input ``u(t) = levels[i]`` for ``breaks[i] <= t < breaks[i+1]``.

    Attributes
    ----------
    breaks : ndarray
        Increasing times (s), ``breaks[0] = 0``, ``breaks[-1]`` = duration.
    levels : ndarray
        Input on each interval (N or the model's input unit); one fewer than ``breaks``.
    """

    breaks: np.ndarray
    levels: np.ndarray

    def __post_init__(self) -> None:
        b = np.asarray(self.breaks, dtype=float)
        lv = np.asarray(self.levels, dtype=float)
        if b.ndim != 1 or lv.ndim != 1 or b.size != lv.size + 1:
            raise ValueError("breaks must have one more entry than levels")
        if np.any(np.diff(b) < 0.0):
            raise ValueError("breaks must be non-decreasing")
        object.__setattr__(self, "breaks", b)
        object.__setattr__(self, "levels", lv)

    @classmethod
    def from_switches(cls, switch_times, levels, duration: float) -> PiecewiseConstant:
        """From interior switch times (s), the level on each interval and the duration (s)."""
        return cls(np.concatenate([[0.0], np.asarray(switch_times, float), [duration]]), levels)

    @classmethod
    def from_samples(cls, samples, dt: float) -> PiecewiseConstant:
        """A zero-order-hold sequence: ``samples[k]`` held on ``[k dt, (k+1) dt)``."""
        samples = np.asarray(samples, dtype=float)
        return cls(dt * np.arange(samples.size + 1), samples)

    @property
    def duration(self) -> float:
        """End time (s)."""
        return float(self.breaks[-1])

    def max_abs(self) -> float:
        """Largest ``|u|``."""
        return float(np.max(np.abs(self.levels))) if self.levels.size else 0.0

    def __call__(self, t) -> np.ndarray:
        """``u(t)``; zero outside ``[0, duration)``."""
        t = np.asarray(t, dtype=float)
        idx = np.searchsorted(self.breaks, t, side="right") - 1
        inside = (idx >= 0) & (idx < self.levels.size)
        out = np.zeros(t.shape)
        out[inside] = self.levels[idx[inside]]
        return out


@lru_cache(maxsize=256)
def _step_cached(A_bytes: bytes, B_bytes: bytes, n: int, h: float) -> tuple[np.ndarray, np.ndarray]:
    A = np.frombuffer(A_bytes).reshape(n, n)
    B = np.frombuffer(B_bytes)
    M = np.zeros((n + 1, n + 1))
    M[:n, :n] = A
    M[:n, n] = B
    E = expm(M * h)
    return E[:n, :n].copy(), E[:n, n].copy()


def step_matrices(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """``Phi(h)``, ``Gamma(h)`` from the augmented matrix exponential (cached)."""
    return step_function(A, B)(h)


def step_function(A: np.ndarray, B: np.ndarray) -> Callable[[float], tuple[np.ndarray, np.ndarray]]:
    """``h -> (Phi(h), Gamma(h))`` of one system: :func:`step_matrices` with the cache key's bytes taken once.

    For loops over the pieces of one input (:func:`simulate`, the certificate's co-state): the
    key's conversion and copy per call cost about as much as a cache hit itself.
    """
    A = np.ascontiguousarray(A, dtype=float)
    key_A = A.tobytes()
    key_B = np.ascontiguousarray(B, dtype=float).ravel().tobytes()
    n = A.shape[0]
    return lambda h: _step_cached(key_A, key_B, n, float(h))


def _system(model_or_AB, include_position: bool = True) -> tuple[np.ndarray, np.ndarray]:
    if isinstance(model_or_AB, ModalModel):
        A, B = model_or_AB.A(), model_or_AB.B()
        if not include_position:
            A, B = A[1:, 1:], B[1:]
        return A, B
    A, B = model_or_AB
    return np.asarray(A, float), np.asarray(B, float).ravel()


def simulate(model_or_AB, x0, u: PiecewiseConstant, times=None, include_position: bool = True):
    """Exact state under a piecewise-constant input.

    Parameters
    ----------
    model_or_AB : ModalModel or (A, B)
        The system.
    x0 : array_like
        Initial state.
    u : PiecewiseConstant
        The input.
    times : array_like, optional
        Times (s) at which to report the state; default: ``u.breaks``.
        Times after ``u.duration`` continue with zero input.
    include_position : bool
        With a :class:`ModalModel`: ``False`` drops the position state.

    Returns
    -------
    ndarray, shape ``(len(times), n)``
    """
    A, B = _system(model_or_AB, include_position)
    step = step_function(A, B)
    x = np.array(x0, dtype=float)
    times = u.breaks if times is None else np.asarray(times, dtype=float)
    order = np.argsort(times, kind="stable")
    out = np.empty((times.size, x.size))
    t_now = 0.0
    k = 0  # current interval
    levels = u.levels
    breaks = u.breaks
    for j in order:
        target = float(times[j])
        while t_now < target:
            # advance to the next break or the target, whichever is first
            if k < levels.size:
                t_next = min(float(breaks[k + 1]), target)
                level = levels[k]
            else:
                t_next, level = target, 0.0
            h = t_next - t_now
            if h > 0.0:
                Phi, Gam = step(h)
                x = Phi @ x + Gam * level
            t_now = t_next
            if k < levels.size and t_now >= breaks[k + 1]:
                k += 1
        out[j] = x
    return out


def final_state(model_or_AB, x0, u: PiecewiseConstant, include_position: bool = True) -> np.ndarray:
    """Exact state at ``u.duration``."""
    return simulate(model_or_AB, x0, u, times=[u.duration], include_position=include_position)[0]


def simulate_samples(model_or_AB, x0, samples, dt: float, include_position: bool = True) -> np.ndarray:
    """Exact states at every sample instant of a zero-order-hold sequence.

    Returns ``(len(samples) + 1, n)``: the state before each sample and after the last.
    """
    A, B = _system(model_or_AB, include_position)
    Phi, Gam = step_matrices(A, B, dt)
    samples = np.asarray(samples, dtype=float)
    n = A.shape[0]
    out = np.empty((samples.size + 1, n))
    x = np.array(x0, dtype=float)
    out[0] = x
    if samples.size < 4 * SAMPLE_BLOCK:
        for k, uk in enumerate(samples):
            x = Phi @ x + Gam * uk
            out[k + 1] = x
        return out
    # blocks of SAMPLE_BLOCK samples: within a block the states are
    # Phi^(i+1) x_start + sum_{j<=i} Phi^(i-j) Gamma u_j, the same products the
    # step-by-step recursion forms (powers of the one expm), done for all
    # blocks at once; only the block starts are propagated in sequence
    P, H = _block_powers(Phi, Gam, SAMPLE_BLOCK)
    nb, rest = divmod(samples.size, SAMPLE_BLOCK)
    U = samples[: nb * SAMPLE_BLOCK].reshape(nb, SAMPLE_BLOCK)
    idx = np.arange(SAMPLE_BLOCK)
    lag = idx[:, None] - idx[None, :]
    T = np.where((lag >= 0)[:, :, None], H[np.clip(lag, 0, None)], 0.0)  # (i, j, n): Phi^(i-j) Gamma
    m = SAMPLE_BLOCK
    forced = (U @ T.transpose(1, 0, 2).reshape(m, m * n)).reshape(nb, m, n)
    starts = np.empty((nb, n))
    last = P[-1]
    for b in range(nb):
        starts[b] = x
        x = last @ x + forced[b, -1]
    free = starts @ P.transpose(2, 0, 1).reshape(n, m * n)  # row b: (Phi^(i+1) x_b)_i, flattened
    out[1 : nb * m + 1] = (free.reshape(nb, m, n) + forced).reshape(-1, n)
    for k in range(nb * SAMPLE_BLOCK, nb * SAMPLE_BLOCK + rest):
        x = Phi @ x + Gam * samples[k]
        out[k + 1] = x
    return out


#: Samples per block of :func:`simulate_samples` (longer sequences only).
SAMPLE_BLOCK = 32


def _block_powers(Phi: np.ndarray, Gam: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """``Phi^1..Phi^m`` (shape ``(m, n, n)``) and ``Phi^0 Gamma..Phi^(m-1) Gamma`` (``(m, n)``), by products."""
    n = Phi.shape[0]
    P = np.empty((m, n, n))
    H = np.empty((m, n))
    P[0] = Phi
    H[0] = Gam
    for i in range(1, m):
        P[i] = Phi @ P[i - 1]
        H[i] = Phi @ H[i - 1]
    return P, H


def modal_amplitudes(model: ModalModel, x) -> np.ndarray:
    """Amplitude of each mode's free vibration from state ``x``.

    For ``q'' + 2 zeta w q' + w^2 q = 0`` the envelope through ``(q, q')`` is
    ``sqrt(q^2 + ((q' + zeta w q) / w_d)^2)`` (same unit as ``q``).  Returns
    shape ``(..., N)``.
    """
    x = np.asarray(x, dtype=float)
    q = x[..., 2::2]
    qd = x[..., 3::2]
    sig = np.asarray(model.zeta) * np.asarray(model.omega)
    return np.hypot(q, (qd + sig * q) / model.omega_d)
