"""The impulse sequence of an input shaper, and its factors when it is a convolution.

A shaper for several modes is usually the convolution of one unit shaper per
mode (:func:`~flexmotion_ros.core.shaping.shapers.design`).  Its impulse count
is the product of the factors' (5^8 = 390,625 for an 8-mode UM-ZVD or EI3),
but everything linear in it factorises: with ``nu = zeta + i sqrt(1 - zeta^2)``,
the vibration sum ``W(omega) = sum_i A_i e^{omega nu (t_i - t_n)}`` of a
convolution is the product of its factors' sums (times and the last time add,
amplitudes multiply), so ``V = prod_j V_j``; likewise the state transition
``sum_i A_i Phi(t_n - t_i) = prod_j sum_i A_ji Phi(t_nj - t_ji)`` (one
``expm`` per factor impulse instead of per impulse).  :class:`Shaper` keeps
its factors (``factors``) so that these are evaluated at the cost of the
factors' impulses, not of their product.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .numerical_shapers import impulse_vibration


@dataclass(frozen=True)
class Shaper:
    """An impulse sequence.

    Attributes
    ----------
    name : str
    times : ndarray
        Impulse times (s), ``times[0] = 0``, increasing.
    amplitudes : ndarray
        Impulse amplitudes (dimensionless), summing to 1.
    omega, zeta : tuple of float
        Design frequencies (rad/s) and damping ratios, one per mode.
    exact : bool
        Closed form (True) or numerically solved constraints (False).
    params : dict
        Design parameters (``tolerance``, ``negative_amplitude``, ...).
    factors : tuple of (ndarray, ndarray)
        For a convolution of shapers: each factor's ``(times, amplitudes)``
        (s, dimensionless), whose convolution is ``(times, amplitudes)`` up to
        merging impulses closer than ``1e-12`` of the duration; empty for a
        shaper that is not a convolution (then it is its own only factor).
    """

    name: str
    times: np.ndarray
    amplitudes: np.ndarray
    omega: tuple[float, ...]
    zeta: tuple[float, ...]
    exact: bool = True
    params: dict = field(default_factory=dict)
    factors: tuple[tuple[np.ndarray, np.ndarray], ...] = ()

    @property
    def duration(self) -> float:
        """Time of the last impulse (s): the delay the shaper adds."""
        return float(self.times[-1])

    @property
    def positive(self) -> bool:
        """All amplitudes >= 0: shaping never raises the peak of a command."""
        return bool(np.all(self.amplitudes >= 0.0))

    @property
    def abs_sum(self) -> float:
        """``sum |A_i|``: the worst-case peak gain on a bounded command."""
        return float(np.sum(np.abs(self.amplitudes)))

    def parts(self) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
        """The factors' ``(times, amplitudes)``, or the shaper itself as its only factor."""
        return self.factors or ((self.times, self.amplitudes),)

    def vibration(self, omega, zeta) -> np.ndarray:
        """Residual vibration ``V`` (fraction, not percent) for modes ``(omega, zeta)`` (broadcast).

        A convolution's ``V`` is the product of its factors' (exact; each
        factor's sum costs its own few impulses).
        """
        out = None
        for t, a in self.parts():
            v = impulse_vibration(t, a, omega, zeta)
            out = v if out is None else out * v
        return out

    def convolve(self, other: Shaper) -> Shaper:
        """The shaper that applies ``self`` then ``other`` (impulses at equal times merged)."""
        t = (self.times[:, None] + other.times[None, :]).ravel()
        a = (self.amplitudes[:, None] * other.amplitudes[None, :]).ravel()
        return _merged(
            f"{self.name}*{other.name}",
            t,
            a,
            self.omega + other.omega,
            self.zeta + other.zeta,
            self.exact and other.exact,
            {**self.params, **other.params},
            self.parts() + other.parts(),
        )

    def to_dict(self) -> dict:
        """JSON-friendly description."""
        return {
            "name": self.name,
            "times": [float(v) for v in self.times],
            "amplitudes": [float(v) for v in self.amplitudes],
            "duration": self.duration,
            "omega": list(self.omega),
            "zeta": list(self.zeta),
            "exact": self.exact,
            "positive": self.positive,
            **{k: v for k, v in self.params.items()},
        }


def _merged(name, t, a, omega, zeta, exact, params, factors) -> Shaper:
    """Impulses sorted, each merged into the previous kept one when within ``1e-12`` of the duration of it."""
    order = np.argsort(t, kind="stable")
    t, a = t[order], a[order]
    tol = 1e-12 * max(float(t[-1]), 1e-300)
    ta, aa = group_impulses(t, a, tol)
    nz = aa != 0.0
    nz[0] = True
    return Shaper(name, ta[nz] - ta[0], aa[nz], tuple(omega), tuple(zeta), exact, params, tuple(factors))


def group_impulses(t: np.ndarray, a: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Sorted impulses grouped: a group starts where ``t`` exceeds its group's first time by ``tol``.

    Runs of gaps ``<= tol`` are found at once; only if one spans more than
    ``tol`` (a chain of near-coincident impulses) is it split one impulse at a
    time (the loop this replaces: 0.5 s per 8-mode convolution).
    """
    start = np.flatnonzero(np.concatenate([[True], np.diff(t) > tol]))
    end = np.append(start[1:], t.size)
    if np.all(t[end - 1] - t[start] <= tol):
        return t[start], np.add.reduceat(a, start)
    keep_t, keep_a = [t[0]], [a[0]]
    for ti, ai in zip(t[1:], a[1:]):
        if ti - keep_t[-1] <= tol:
            keep_a[-1] += ai
        else:
            keep_t.append(ti)
            keep_a.append(ai)
    return np.array(keep_t), np.array(keep_a)
