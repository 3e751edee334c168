"""Exact simulation of piecewise-constant inputs by matrix exponentials.

Over an interval of length ``h`` with constant input ``u``::

    x(t + h) = Phi(h) x(t) + Gamma(h) u,   expm([[A, B], [0, 0]] h) = [[Phi, Gamma], [0, 1]]

No ODE integrator, no tolerance: the only error is floating-point rounding.
This module is the *independent* check of every planner: it builds the full
``A``, ``B`` and calls :func:`scipy.linalg.expm`; it shares no formulas with
:mod:`flexmotion_ros.core.modal_response`.
"""

from __future__ import annotations

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
    A = np.ascontiguousarray(A, dtype=float)
    B = np.ascontiguousarray(B, dtype=float).ravel()
    return _step_cached(A.tobytes(), B.tobytes(), A.shape[0], float(h))


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
                Phi, Gam = step_matrices(A, B, h)
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
    out = np.empty((samples.size + 1, A.shape[0]))
    x = np.array(x0, dtype=float)
    out[0] = x
    for k, uk in enumerate(samples):
        x = Phi @ x + Gam * uk
        out[k + 1] = x
    return out


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
