"""Residual vibration versus model error, and the insensitivity width.

Two measures, both in percent:

* **Shaper vibration** ``V(omega, zeta)`` (:func:`shaper_curve`): the residual
  vibration of a shaped command relative to the *unshaped* one (Singhose's
  percentage vibration).  Independent of the command.
* **Command vibration** (:func:`command_vibration`): the residual vibration of
  a piecewise-constant command ``u`` relative to what a step of ``u_ref``
  (default: the command's peak) leaves.  A piecewise-constant command is the
  integral of an impulse sequence (its jumps ``Delta u_j`` at the breaks,
  including the return to zero at the end), so this is ``V`` of the jumps
  divided by ``u_ref``::

      residual amplitude of mode i = |b_i| u_ref / (omega_i^2 sqrt(1 - zeta_i^2)) * V_cmd

  It applies to any profile (time-optimal, robust, shaped) and makes them
  comparable.  For a shaped command, ``V_cmd = V_shaper * V_cmd(unshaped)``.

The *insensitivity* at a tolerance is the width of the interval of frequency
ratios ``omega_true / omega_model`` around 1 on which the vibration stays at
or below the tolerance (Singhose, Seering & Singer 1994); with several modes
all frequencies are scaled together and the worst mode counts.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from ..errors import InputError
from ..model.modal_model import ModalModel
from ..simulation.exact import PiecewiseConstant, modal_amplitudes, simulate
from ..tolerances import TOLERANCE_SLACK
from .numerical_shapers import impulse_vibration
from .shaped_command import ShapedCommand, factored_vibration
from .shaper import Shaper


@dataclass(frozen=True)
class Insensitivity:
    """Interval of frequency ratios with vibration <= tolerance.

    Attributes
    ----------
    tolerance : float
        Vibration limit (fraction, 0.05 = 5 %).
    low, high : float
        Ends of the interval around the nominal ratio (dimensionless).
    width : float
        ``high - low`` (0 if the nominal point itself exceeds the tolerance).
    """

    tolerance: float
    low: float
    high: float

    @property
    def width(self) -> float:
        return self.high - self.low

    def to_dict(self) -> dict:
        return {"tolerance": self.tolerance, "low": self.low, "high": self.high, "width": self.width}


def command_impulses(u: PiecewiseConstant) -> tuple[np.ndarray, np.ndarray]:
    """The jumps of ``u`` as impulses: times (s) and ``Delta u`` (input units), zero jumps dropped."""
    levels = np.concatenate([[0.0], u.levels, [0.0]])
    jumps = np.diff(levels)
    keep = jumps != 0.0
    if not keep.any():
        return np.zeros(1), np.zeros(1)
    # keep the last break so that the normalisation time is the command's end
    t, a = u.breaks[keep], jumps[keep]
    if t[-1] != u.breaks[-1]:
        t, a = np.append(t, u.breaks[-1]), np.append(a, 0.0)
    return t, a


def command_vibration(u: PiecewiseConstant, omega, zeta, u_ref: float | None = None) -> np.ndarray:
    """Residual vibration (fraction) of command ``u`` for modes ``(omega, zeta)``, relative to a step of ``u_ref``."""
    ref = u.max_abs() if u_ref is None else float(u_ref)
    if not ref > 0.0:
        return np.zeros(np.broadcast(np.asarray(omega), np.asarray(zeta)).shape)
    t, a = command_impulses(u)
    return impulse_vibration(t, a / ref, omega, zeta)


def shaper_curve(shaper: Shaper, ratios, mode: int = 0, zeta: float | None = None) -> np.ndarray:
    """Shaper vibration (percent) versus frequency ratio ``omega / omega_design`` of one mode."""
    w = shaper.omega[mode] * np.asarray(ratios, dtype=float)
    z = shaper.zeta[mode] if zeta is None else zeta
    return 100.0 * shaper.vibration(w, z)


def shaper_damping_curve(shaper: Shaper, zetas, mode: int = 0) -> np.ndarray:
    """Shaper vibration (percent) versus damping ratio at the design frequency of one mode."""
    return 100.0 * shaper.vibration(shaper.omega[mode], np.asarray(zetas, dtype=float))


def command_curve(u: PiecewiseConstant, model: ModalModel, ratios, u_ref: float | None = None) -> np.ndarray:
    """Command vibration (percent) versus a common frequency ratio; shape ``(len(ratios), n_modes)``."""
    r = np.asarray(ratios, dtype=float)[:, None]
    return 100.0 * command_vibration(u, r * np.asarray(model.omega), np.asarray(model.zeta), u_ref)


def command_damping_curve(
    u: PiecewiseConstant, model: ModalModel, zetas, mode: int = 0, u_ref: float | None = None
) -> np.ndarray:
    """Command vibration (percent) of one mode versus its damping ratio."""
    return 100.0 * command_vibration(u, model.omega[mode], np.asarray(zetas, dtype=float), u_ref)


def insensitivity(
    vibration: Callable[[np.ndarray], np.ndarray],
    tolerance: float,
    nominal: float = 1.0,
    span: tuple[float, float] = (0.02, 3.0),
    step: float = 1e-3,
) -> Insensitivity:
    """Interval around ``nominal`` where ``vibration(ratio) <= tolerance`` (both fractions).

    ``vibration`` maps an array of ratios to vibrations (fractions).  The
    interval is found on a grid of ``step`` and its ends refined by Brent's
    method.  A bump touching the tolerance (EI humps) does not end it.
    """
    if not 0.0 < tolerance < 1.0:
        raise InputError("tolerance", f"must be in (0, 1) (fraction), got {tolerance}")
    lim = tolerance * (1.0 + TOLERANCE_SLACK)
    if float(np.asarray(vibration(np.array([nominal])))[0]) > lim:
        return Insensitivity(tolerance, nominal, nominal)

    def edge(direction: int) -> float:
        end = span[1] if direction > 0 else span[0]
        n = int(abs(end - nominal) / step)
        inside = nominal
        start, size = 1, 16
        while start <= n:  # growing chunks: the edge is usually near, and a long command costs per ratio
            grid = nominal + direction * step * np.arange(start, min(start + size, n + 1))
            start, size = start + size, min(2 * size, 256)
            V = np.asarray(vibration(grid))
            out = np.flatnonzero(V > lim)
            if out.size:
                k = out[0]
                inside = inside if k == 0 else grid[k - 1]
                a, b = sorted((inside, grid[k]))
                f = lambda r: float(np.asarray(vibration(np.array([r])))[0]) - tolerance
                if f(a) * f(b) > 0.0:
                    return float(inside)
                return float(brentq(f, a, b, xtol=1e-13, rtol=1e-13))
            inside = grid[-1]
        return float(end)

    return Insensitivity(tolerance, edge(-1), edge(+1))


def ratio_vibration(times, amplitudes, omega, zeta, ratios) -> np.ndarray:
    """:func:`impulse_vibration` of modes ``(ratio * omega, zeta)`` for each ratio: shape ``(len(ratios), n)``.

    On a uniform grid of ratios the exponentials are advanced by one factor
    per step (``e^{(r + h) c} = e^{r c} e^{h c}``, ``c`` per impulse and mode)
    instead of recomputed: a shaped 8-mode command has ~20,000 impulses, and
    the insensitivity search evaluates hundreds of ratios (measured: 92 % of
    an 8-mode ZVD plan).  Other grids, and single ratios (the edge
    refinement), are evaluated directly.
    """
    r = np.atleast_1d(np.asarray(ratios, dtype=float))
    w = np.atleast_1d(np.asarray(omega, dtype=float))
    z = np.broadcast_to(np.asarray(zeta, dtype=float), w.shape)
    h = np.diff(r)
    if r.size < 8 or not np.allclose(h, h[0], rtol=1e-9, atol=0.0):
        return impulse_vibration(times, amplitudes, r[:, None] * w, z)
    t = np.asarray(times, dtype=float)
    a = np.asarray(amplitudes, dtype=float)
    c = w[:, None] * (z[:, None] * (t - t[-1]) + 1j * np.sqrt(1.0 - z[:, None] ** 2) * t)  # (n, impulses)
    step = np.exp(h[0] * c)
    cur = a * np.exp(r[0] * c)
    out = np.empty((r.size, w.size))
    for j in range(r.size):
        out[j] = np.abs(cur.sum(axis=-1))
        cur *= step
    return out


def shaper_insensitivity(shaper: Shaper, tolerance: float = 0.05, mode: int = 0) -> Insensitivity:
    """Insensitivity of a shaper to the frequency of one mode (Singhose's figure of merit)."""
    w, z = shaper.omega[mode], shaper.zeta[mode]

    def V(r):  # a convolution's V is the product of its factors' (each a few impulses)
        out = 1.0
        for t, a in shaper.parts():
            out = out * ratio_vibration(t, a, w, z, r)[:, 0]
        return out

    return insensitivity(V, tolerance)


def command_insensitivity(
    u: PiecewiseConstant, model: ModalModel, tolerance: float = 0.05, u_ref: float | None = None
) -> Insensitivity:
    """Insensitivity of a command to a common scaling of all modal frequencies (worst mode).

    A :class:`~flexmotion_ros.core.shaping.shaped_command.ShapedCommand` is
    evaluated by its factors (:func:`~.shaped_command.factored_vibration`:
    the same figure up to rounding, at the cost of the rigid command's and the
    factors' impulses instead of their product, ~10^6 for 8 modes).
    """
    if not model.n_modes:
        return Insensitivity(tolerance, 0.0, np.inf)

    ref = u.max_abs() if u_ref is None else float(u_ref)
    if not ref > 0.0:
        return insensitivity(lambda r: np.zeros(np.size(r)), tolerance)
    if isinstance(u, ShapedCommand) and u.rigid is not None:  # by its factors: each a few impulses
        w, z = np.asarray(model.omega, dtype=float), np.asarray(model.zeta, dtype=float)

        def V(r):
            return np.max(factored_vibration(u, np.asarray(r, dtype=float)[:, None] * w, z, ref), axis=-1)

        return insensitivity(V, tolerance)
    t, a = command_impulses(u)

    def V(r):
        return np.max(ratio_vibration(t, a / ref, model.omega, model.zeta, r), axis=-1)

    return insensitivity(V, tolerance)


def worst_in_band(
    u: PiecewiseConstant, model: ModalModel, error: float, u_ref: float | None = None, points: int = 401
) -> float:
    """Largest command vibration (fraction, worst mode) for frequency ratios in ``[1 - error, 1 + error]``."""
    if not model.n_modes:
        return 0.0
    r = np.linspace(1.0 - error, 1.0 + error, points)
    return float(np.max(command_curve(u, model, r, u_ref))) / 100.0


def residual_amplitudes(model: ModalModel, x0, u: PiecewiseConstant) -> np.ndarray:
    """Residual vibration amplitude of each mode after ``u`` (modal units), by exact simulation."""
    x = simulate(model, x0, u, times=[u.duration])[0]
    return modal_amplitudes(model, x)
