"""Excitation design: a bounded command sequence that makes the fit well-conditioned over a band.

The command is a Schroeder-phased multisine (Schroeder 1970: flat amplitude
spectrum, low crest factor) with lines spaced ``2 pi / T`` across the band
``[omega_lo, omega_hi]`` (rad/s), tapered at both ends, sampled and held at
the command rate.  Flat input power over the band gives every mode in it a
comparable Fisher information, whatever its frequency.

It must leave the machine where it started, at rest: the final state of a
held sequence from rest is linear in it, ``x_K = G u`` (``G``'s columns are
``Phi^{K-1-k} Gamma``), so the least change that makes ``G u = 0`` is the
projection onto ``G``'s null space.  Scaling keeps ``G u = 0``, so the
sequence is then scaled to the larger of the two bounds it may touch: the
actuator (``|u| <= u_max``) and the position limits (the rigid-body position's
exact extremes between samples, from the start position).  A quiet tail
follows (zero command: at rest per the model; on a machine whose model is off,
a ringdown the fit uses).

The final state is checked by the exact matrix-exponential propagation of
:func:`~flexmotion_ros.core.simulation.exact.simulate_samples` (independent of
the closed forms used to build ``G``); a sequence that fails the check is never
returned.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError, SolverError
from ..model.modal_model import ModalModel, check_positive
from ..simulation.error_scale import relative_final_state_error, state_scale
from ..simulation.exact import simulate_samples
from ..simulation.modal_response import ModalResponse
from ..tolerances import FINAL_STATE_RTOL
from .data import IdentificationData, SensorOutput
from .forward import ForwardModel
from .refine import covariance
from .response import OutputKind

#: Default duration: this many periods of the band's lowest frequency.
DEFAULT_CYCLES = 4.0
#: Fraction of the excitation tapered (cosine) at each end.
TAPER = 0.1
#: Default quiet tail after the excitation, as a fraction of its duration.
DEFAULT_TAIL = 0.25
#: The band must stay below this fraction of the Nyquist frequency (as identification requires).
BAND_NYQUIST_FRACTION = 0.8
#: Scaling to the position limits stops this close below them (rounding must not cross them).
POSITION_MARGIN = 1.0 - 1e-9
#: Longest sequence designed (samples).
MAX_EXCITATION_SAMPLES = 2_000_000


@dataclass(frozen=True, kw_only=True)
class Excitation:
    """A designed excitation.

    Attributes
    ----------
    commands : ndarray
        ``u_k`` held on ``[k dt, (k+1) dt)`` (N), excitation then quiet tail.
    dt : float
        Sample time (s).
    band : tuple of float
        ``(omega_lo, omega_hi)`` (rad/s).
    lines : ndarray
        Multisine frequencies (rad/s).
    peak : float
        ``max |u|`` (N).
    bound : str
        ``"u_max"`` or ``"position limits"``: which one set the amplitude.
    excitation_duration, duration : float
        Length of the excitation and of the whole sequence with its tail (s).
    position_range : tuple of float
        Lowest and highest rigid-body position over the sequence (m), exact between samples.
    final_state_error : float
        Relative final-state error of the exact propagation (``<= FINAL_STATE_RTOL``).
    states : ndarray
        Exact states at every sample (``(K + 1, n)``) of the model it was designed for.
    """

    commands: np.ndarray
    dt: float
    band: tuple[float, float]
    lines: np.ndarray
    peak: float
    bound: str
    excitation_duration: float
    duration: float
    position_range: tuple[float, float]
    final_state_error: float
    states: np.ndarray

    @property
    def times(self) -> np.ndarray:
        """Sample times (s)."""
        return self.dt * np.arange(self.commands.size)

    def to_dict(self) -> dict[str, object]:
        return {
            "samples": int(self.commands.size),
            "dt": self.dt,
            "band": list(self.band),
            "lines": int(self.lines.size),
            "peak": self.peak,
            "bound": self.bound,
            "excitation_duration": self.excitation_duration,
            "duration": self.duration,
            "position_range": list(self.position_range),
            "final_state_error": self.final_state_error,
        }


def schroeder_multisine(lines: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``sum_k cos(omega_k t + phi_k)``, ``phi_k = -pi k (k - 1) / K`` (low crest factor)."""
    K = lines.size
    k = np.arange(1, K + 1)
    phase = -math.pi * k * (k - 1) / K
    out = np.zeros(t.size)
    for w, ph in zip(lines, phase):
        out += np.cos(w * t + ph)
    return out


def _final_state_rows(model: ModalModel, dt: float, K: int) -> np.ndarray:
    """``G`` (``n x K``) with ``x_K = G u`` from rest.

    Column ``k`` is ``Phi^{K-1-k} Gamma = I((K-k) dt) - I((K-1-k) dt)`` with
    ``I(tau) = int_0^tau e^{A s} B ds`` in closed form: no recursion, so no
    rounding piles up over a long sequence of an undamped mode.
    """
    integral = ModalResponse(model).input_integral(dt * np.arange(K + 1))  # (K + 1, n)
    steps = np.diff(integral, axis=0)  # row m: Phi^m Gamma
    return steps[::-1].T


def rigid_extremes(states: np.ndarray, u: np.ndarray, b0: float, c: float, dt: float) -> tuple[float, float]:
    """Exact lowest and highest rigid-body position over a held sequence, between samples too (m)."""
    p, v = states[:-1, 0], states[:-1, 1]
    lo = float(states[:, 0].min())
    hi = float(states[:, 0].max())
    a = b0 * u
    with np.errstate(divide="ignore", invalid="ignore"):
        if c == 0.0:
            tau = -v / a
            inside = (a != 0.0) & (tau > 0.0) & (tau < dt)
            pe = p[inside] - v[inside] ** 2 / (2.0 * a[inside])
        else:
            # v(tau) = v e^{c tau} + a (e^{c tau} - 1) / c = 0  <=>  e^{c tau} = a / (a + c v)
            ratio = a / (a + c * v)
            tau = np.log(ratio) / c
            inside = (ratio > 0.0) & (tau > 0.0) & (tau < dt)
            e = np.exp(c * tau[inside])
            vi, ai = v[inside], a[inside]
            pe = p[inside] + vi * (e - 1.0) / c + ai / c * ((e - 1.0) / c - tau[inside])
    if pe.size:
        lo, hi = min(lo, float(pe.min())), max(hi, float(pe.max()))
    return lo, hi


def design_excitation(
    model: ModalModel,
    u_max: float,
    rate_hz: float,
    band: tuple[float, float],
    *,
    duration: float | None = None,
    tail: float | None = None,
    position_limits: tuple[float, float] = (-math.inf, math.inf),
    start: float = 0.0,
) -> Excitation:
    """A bounded excitation of ``band`` that ends where it started, at rest (module docstring).

    Parameters
    ----------
    model : ModalModel
        The model believed now (rest-to-rest is exact for it).
    u_max : float
        Actuator bound (N).
    rate_hz : float
        Command rate (Hz).
    band : (float, float)
        ``omega_lo < omega_hi`` (rad/s), below 0.8 of the Nyquist frequency.
    duration : float, optional
        Excitation length (s); default :data:`DEFAULT_CYCLES` periods of ``omega_lo``.
    tail : float, optional
        Quiet tail (s); default :data:`DEFAULT_TAIL` of the excitation.
    position_limits : (float, float)
        Allowed rigid-body positions (m); the start must lie inside.
    start : float
        Rigid-body position at the start (m).

    Raises
    ------
    InputError
        A band outside ``(0, 0.8 Nyquist)``, a duration too short for one line, a start outside the limits.
    SolverError
        The exact check of the final state failed (never expected).
    """
    u_max = check_positive("u_max", u_max, "N")
    rate = check_positive("rate_hz", rate_hz, "Hz")
    dt = 1.0 / rate
    nyq = math.pi / dt
    try:
        w_lo, w_hi = (float(x) for x in band)
    except (TypeError, ValueError):
        raise InputError("band", f"must be two frequencies LO:HI in rad/s, got {band!r}") from None
    if not (math.isfinite(w_lo) and math.isfinite(w_hi) and 0.0 < w_lo < w_hi):
        raise InputError("band", f"needs 0 < LO < HI (rad/s), got {w_lo}:{w_hi}")
    if w_hi > BAND_NYQUIST_FRACTION * nyq:
        raise InputError(
            "band", f"HI = {w_hi:.6g} rad/s exceeds {BAND_NYQUIST_FRACTION} of the Nyquist frequency {nyq:.6g} rad/s"
        )
    lo_lim, hi_lim = (float(x) for x in position_limits)
    if not lo_lim < start < hi_lim:
        raise InputError("start", f"{start} is not strictly inside the position limits [{lo_lim}, {hi_lim}]")
    T = DEFAULT_CYCLES * 2.0 * math.pi / w_lo if duration is None else check_positive("duration", duration, "s")
    K = int(round(T / dt))
    tail_s = DEFAULT_TAIL * K * dt if tail is None else float(tail)
    if not (math.isfinite(tail_s) and tail_s >= 0.0):
        raise InputError("tail", f"must be a duration >= 0 s, got {tail}")
    K_tail = int(round(tail_s / dt))
    if K + K_tail > MAX_EXCITATION_SAMPLES:
        raise InputError(
            "duration",
            f"{(K + K_tail) * dt:.6g} s at {rate:g} Hz is {K + K_tail} samples, more than {MAX_EXCITATION_SAMPLES}: "
            "raise the band's low end, shorten it, or lower the rate",
        )
    dw = 2.0 * math.pi / (K * dt)
    lines = dw * np.arange(math.ceil(w_lo / dw), math.floor(w_hi / dw) + 1)
    if lines.size == 0:
        raise InputError(
            "duration", f"{K * dt:.6g} s is too short for a line in the band: at least {2 * math.pi / w_lo:.6g} s"
        )
    t = dt * np.arange(K)
    u = schroeder_multisine(lines, t)
    n_taper = max(1, int(TAPER * K))
    ramp = 0.5 * (1.0 - np.cos(math.pi * np.arange(n_taper) / n_taper))
    u[:n_taper] *= ramp
    u[K - n_taper :] *= ramp[::-1]
    G = _final_state_rows(model, dt, K)
    Q, _ = np.linalg.qr((G / np.linalg.norm(G, axis=1, keepdims=True)).T)
    u = u - Q @ (Q.T @ u)
    u = u - Q @ (Q.T @ u)  # twice: the projection's own rounding
    u = np.concatenate([u, np.zeros(K_tail)])
    x0 = model.rest_state(start)
    unit = simulate_samples(model, model.rest_state(0.0), u / np.max(np.abs(u)), dt)
    lo, hi = rigid_extremes(unit, u / np.max(np.abs(u)), model.b0, model.c, dt)
    scale = u_max
    bound = "u_max"
    for room, reach in ((hi_lim - start, hi), (start - lo_lim, -lo)):
        if reach > 0.0 and math.isfinite(room) and room / reach < scale:
            scale, bound = room / reach * POSITION_MARGIN, "position limits"
    u = np.clip(u / np.max(np.abs(u)) * scale, -u_max, u_max)  # the clip moves at most the last ulp
    states = simulate_samples(model, x0, u, dt)
    err = relative_final_state_error(
        states[-1] - x0, state_scale(ModalResponse(model), np.zeros(model.n_states), scale, u.size * dt)
    )
    if err > FINAL_STATE_RTOL:
        raise SolverError(
            f"excitation: final state misses rest at the start by {err:.3g} (relative), above {FINAL_STATE_RTOL}"
        )
    p_lo, p_hi = rigid_extremes(states, u, model.b0, model.c, dt)
    if p_lo < lo_lim or p_hi > hi_lim:
        raise SolverError(f"excitation: reaches [{p_lo}, {p_hi}] outside the position limits [{lo_lim}, {hi_lim}]")
    return Excitation(
        commands=u,
        dt=dt,
        band=(w_lo, w_hi),
        lines=lines,
        peak=float(np.max(np.abs(u))),
        bound=bound,
        excitation_duration=K * dt,
        duration=u.size * dt,
        position_range=(p_lo, p_hi),
        final_state_error=float(err),
        states=states,
    )


def predicted_std_errors(
    model: ModalModel,
    commands: np.ndarray,
    dt: float,
    noise_std: float,
    kind: OutputKind = OutputKind.POSITION,
    weights: tuple[float, ...] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Cramer-Rao standard errors of each mode's ``omega`` and ``zeta`` for a planned excitation.

    The sensor reads ``p + sum_i a_i q_i`` (``weights`` ``a_i``, default 1)
    as ``kind`` with white noise ``noise_std``: what the identification would
    reach at best from this command sequence on ``model``.
    """
    a = np.ones(model.n_modes) if weights is None else np.asarray(weights, dtype=float)
    commands = np.asarray(commands, dtype=float)
    data = IdentificationData(
        dt=dt, t0=0.0, u=commands, outputs=(SensorOutput(samples=np.zeros(commands.size), kind=OutputKind(kind)),)
    )
    fm = ForwardModel(data, model.n_modes)
    theta = fm.join(model.c, model.omega, model.zeta, model.b0, a * np.asarray(model.b), [0.0])
    _, (J,) = fm.predict_and_jacobian(theta)
    se = np.sqrt(np.maximum(np.diag(covariance(J / noise_std)), 0.0))
    _, s_omega, s_zeta, _, _, _ = fm.split(se)
    return s_omega, s_zeta
