"""The state and slew limits, validated, and their exact maxima between samples.

A rigid-body velocity limit ``|v(t)| <= v_max``, a limit on each mode's
deflection (structural stress) ``|q_i(t)| <= q_max_i`` and a slew-rate limit
on the command ``|u_k - u_{k-1}| <= slew dt`` (from and to the hold value 0
at the ends).  The planner is in :mod:`.limits`, its linear program in
:mod:`.limit_lp`.

Between samples
---------------
* Velocity: under a constant input ``v(t) = v_inf + (v_k - v_inf) e^{c t}``
  (or linear for ``c = 0``) is monotone, so the limit at the samples is the
  limit everywhere: exact, nothing to add.
* Slew rate: a zero-order hold has no in-between command; the limit is on
  successive samples.
* Deflection: ``q_i`` oscillates within a sample.  Its maximum over each
  sample interval has a closed form (the zeros of ``q_i'`` under constant
  input are ``atan2`` expressions), :func:`deflection_peaks`, evaluated on
  the exact matrix-exponential states.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..model.modal_model import ModalModel
from ..simulation.exact import simulate_samples


@dataclass(frozen=True)
class Limits:
    """State and slew limits (``None`` or ``inf``: no limit).

    Attributes
    ----------
    velocity_max : float or None
        Rigid-body velocity limit (m/s or rad/s), ``> 0``.
    deflection_max : tuple of float or None
        Per-mode deflection limit (the modal coordinate's unit), ``> 0``
        each (``inf`` for a mode without limit); one entry per mode.
    slew_rate : float or None
        Command slew-rate limit (N/s), ``> 0``.
    """

    velocity_max: float | None = None
    deflection_max: tuple[float, ...] | None = None
    slew_rate: float | None = None

    def validated(self, model: ModalModel) -> Limits:
        """A copy with infinite limits dropped; raises naming the parameter and range."""
        v = _positive_or_none("limits.velocity_max", self.velocity_max, "m/s")
        s = _positive_or_none("limits.slew_rate", self.slew_rate, "N/s")
        q = None
        if self.deflection_max is not None:
            seq = [self.deflection_max] if np.isscalar(self.deflection_max) else list(self.deflection_max)
            if len(seq) != model.n_modes:
                raise InputError("limits.deflection_max", f"needs one entry per mode ({model.n_modes}), got {len(seq)}")
            vals = [_positive_or_none(f"limits.deflection_max[{i}]", x, "") for i, x in enumerate(seq)]
            q = tuple(math.inf if x is None else x for x in vals)
            if all(math.isinf(x) for x in q):
                q = None
        return Limits(v, q, s)

    @property
    def active(self) -> list[str]:
        """Names of the limits that are set."""
        out = []
        if self.velocity_max is not None:
            out.append("velocity_max")
        if self.deflection_max is not None:
            out.append("deflection_max")
        if self.slew_rate is not None:
            out.append("slew_rate")
        return out

    def only(self, name: str) -> Limits:
        """Just one of the limits."""
        return Limits(**{name: getattr(self, name)})

    def to_dict(self) -> dict:
        return {
            "velocity_max": self.velocity_max,
            "deflection_max": list(self.deflection_max) if self.deflection_max is not None else None,
            "slew_rate": self.slew_rate,
        }


def _positive_or_none(name: str, value, unit: str) -> float | None:
    if value is None:
        return None
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(
            name, f"must be a number > 0{(' ' + unit) if unit else ''} (or .inf: no limit), got {value!r}"
        ) from None
    if math.isinf(x) and x > 0:
        return None
    if not math.isfinite(x) or x <= 0.0:
        raise InputError(name, f"must be > 0{(' ' + unit) if unit else ''} (or .inf: no limit), got {x}")
    return x


# ------------------------------------------------------- in-between maxima
def deflection_peaks(
    model: ModalModel, states: np.ndarray, commands: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """Exact ``max |q_i(t)|`` over each sample interval, and where it occurs.

    Parameters
    ----------
    states : ndarray, shape ``(K + 1, 2N + 2)``
        States at the samples (full state ``[p, v, q_1, q_1', ...]``).
    commands : ndarray, shape ``(K,)``
        The held commands.

    Returns
    -------
    peak, at : ndarray, shape ``(K, N)``
        The peak and the time within the interval (s, in ``[0, dt]``).
    """
    K = commands.size
    N = model.n_modes
    if N == 0 or K == 0:
        return np.zeros((K, N)), np.zeros((K, N))
    w = np.asarray(model.omega)
    sig = np.asarray(model.zeta) * w
    wd = model.omega_d
    b = np.asarray(model.b)
    q0, qd0 = states[:-1, 2::2], states[:-1, 3::2]
    q1 = states[1:, 2::2]
    qss = commands[:, None] * b / w**2
    e0 = q0 - qss
    # e' = exp(-sig s) (P cos(wd s) + Q sin(wd s)): zeros where tan(wd s) = -P/Q
    P = qd0
    Q = (-sig * qd0 - w**2 * e0) / wd
    theta0 = np.mod(np.arctan2(-P, Q), np.pi)
    peak = np.maximum(np.abs(q0), np.abs(q1))
    at = np.where(np.abs(q1) > np.abs(q0), dt, 0.0)
    C1 = (qd0 + sig * e0) / wd
    jmax = math.ceil(float(np.max(wd)) * dt / math.pi) + 1
    for j in range(jmax):
        s = (theta0 + j * np.pi) / wd
        inside = (s > 0.0) & (s < dt)
        if not inside.any():
            continue
        s = np.where(inside, s, 0.0)
        q = qss + np.exp(-sig * s) * (e0 * np.cos(wd * s) + C1 * np.sin(wd * s))
        better = inside & (np.abs(q) > peak)
        peak = np.where(better, np.abs(q), peak)
        at = np.where(better, s, at)
    return peak, at


# ---------------------------------------------------------- the exact check
@dataclass
class Cut:
    """A deflection constraint between samples: mode ``mode`` at ``s`` seconds into interval ``k``."""

    k: int
    mode: int
    s: float


def check_limits(
    model: ModalModel, x0: np.ndarray, commands: np.ndarray, dt: float, limits: Limits
) -> tuple[dict, list[Cut], bool]:
    """Exact peaks of every limited quantity, at and between samples (matrix-exponential states).

    Returns
    -------
    peaks : dict
        ``velocity`` (m/s), ``deflection`` and ``deflection_at_samples`` (one per
        mode), ``slew`` (N/s), for the limits that are set.
    cuts : list of Cut
        Where a deflection exceeds its limit strictly between samples.
    ok : bool
        Every limit holds everywhere (then ``cuts`` is empty).
    """
    u = np.asarray(commands, dtype=float)
    states = simulate_samples(model, x0, u, dt)
    peaks: dict = {}
    cuts: list[Cut] = []
    ok = True
    if limits.velocity_max is not None:  # monotone within a sample: the samples hold the maximum
        peaks["velocity"] = float(np.max(np.abs(states[:, 1])))
        ok &= peaks["velocity"] <= limits.velocity_max
    if limits.deflection_max is not None:
        pk, at = deflection_peaks(model, states, u, dt)
        at_samples = np.max(np.abs(states[:, 2::2]), axis=0)
        peaks["deflection"] = [float(x) for x in np.max(pk, axis=0)] if u.size else [0.0] * model.n_modes
        peaks["deflection_at_samples"] = [float(x) for x in at_samples]
        for i, qm in enumerate(limits.deflection_max):
            if not math.isfinite(qm):
                continue
            ok &= bool(at_samples[i] <= qm)
            for k in np.flatnonzero(pk[:, i] > qm):
                if 0.0 < at[k, i] < dt:
                    cuts.append(Cut(int(k), i, float(at[k, i])))
                else:
                    ok = False
    if limits.slew_rate is not None and u.size:
        steps = np.abs(np.diff(np.concatenate([[0.0], u, [0.0]])))
        peaks["slew"] = float(np.max(steps)) / dt
        ok &= bool(np.max(steps) <= limits.slew_rate * dt)
    ok = bool(ok and not cuts)
    peaks["ok"] = ok
    return peaks, cuts, ok
