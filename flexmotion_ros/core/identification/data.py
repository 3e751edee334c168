"""Measured data for identification, and the refusals of data nothing can be identified from.

Every refusal is an :class:`~flexmotion_ros.core.errors.InputError` whose
parameter names the signal (``data.time``, ``data.input``,
``data.output`` or ``data.output[j]``) and whose reason says what was wrong
and what is needed, in one line.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .response import OutputKind

#: Fewest samples accepted: below this no noise level, let alone a mode, can be estimated.
MIN_SAMPLES = 100
#: Each parameter needs this many samples (the Fisher information must dominate the fit's freedom).
SAMPLES_PER_PARAMETER = 10
#: Time stamps may sit this far (fraction of a sample) from the uniform grid: CSV rounding, not jitter.
TIME_GRID_TOL = 0.01
#: A signal whose spread is below this fraction of its size is constant (no excitation / no response).
CONSTANT_RTOL = 1e-12
#: An extreme value held this many samples, and CLIP_RATIO times longer than any other value, is a
#: clipped (saturated) sensor (:func:`check_clipping`).
CLIP_RUN = 5
CLIP_RATIO = 4.0


def _as_signal(name: str, values, n: int | None) -> np.ndarray:
    try:
        x = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise InputError(name, "must be a sequence of numbers") from None
    if x.ndim != 1:
        raise InputError(name, f"must be one signal (1-D), got shape {x.shape}")
    if n is not None and x.size != n:
        raise InputError(name, f"has {x.size} samples, data.time has {n}: give one value per time stamp")
    bad = ~np.isfinite(x)
    if bad.any():
        k = int(np.argmax(bad))
        raise InputError(
            name, f"{int(bad.sum())} samples are NaN or infinite (first at sample {k}): drop or repair them"
        )
    return x


@dataclass(frozen=True, kw_only=True)
class SensorOutput:
    """One measured output.

    Attributes
    ----------
    samples : ndarray
        The readings ``y_k`` (m, m/s or m/s^2), one per time stamp.
    kind : OutputKind
        Position (an encoder), velocity, or acceleration (an accelerometer).
    rigid_weight : float
        How much of the rigid-body coordinate the sensor reads (``a0`` in
        ``y = a0 p + sum a_i q_i``).  1 for any calibrated physical coordinate
        of a body (every body moves with the rigid body), 0 for a relative
        coordinate (a rope angle, a spring deflection).
    name : str
        Name (a CSV column, a joint).
    """

    samples: np.ndarray
    kind: OutputKind = OutputKind.POSITION
    rigid_weight: float = 1.0
    name: str = "y"


@dataclass(frozen=True, kw_only=True)
class IdentificationData:
    """Checked data: uniform sample time ``dt`` (s), held input ``u`` and the outputs.

    ``u[k]`` is the command held on ``[t_k, t_{k+1})``; ``outputs[j].samples[k]``
    the reading at ``t_k`` (after ``u[k]`` is applied: see
    :mod:`~flexmotion_ros.core.identification.response`).  The machine is at
    rest before the first sample.
    """

    dt: float
    t0: float
    u: np.ndarray
    outputs: tuple[SensorOutput, ...]

    @property
    def samples(self) -> int:
        """Number of samples per signal."""
        return int(self.u.size)

    @property
    def duration(self) -> float:
        """Record length ``samples * dt`` (s)."""
        return self.samples * self.dt

    @property
    def nyquist(self) -> float:
        """Nyquist frequency ``pi / dt`` (rad/s)."""
        return math.pi / self.dt


def _check_time(time) -> tuple[float, float, int]:
    t = _as_signal("data.time", time, None)
    if t.size < 2:
        raise InputError("data", f"too short: {t.size} samples, need at least {MIN_SAMPLES}")
    steps = np.diff(t)
    if np.any(steps <= 0.0):
        k = int(np.argmax(steps <= 0.0)) + 1
        raise InputError("data.time", f"must increase: sample {k} is not after sample {k - 1}")
    k = np.arange(t.size)
    dt, t0 = np.polyfit(k, t, 1)  # the uniform grid closest to the stamps
    off = np.abs(t - (t0 + dt * k)) / dt
    if off.max() > TIME_GRID_TOL:
        j = int(np.argmax(off))
        raise InputError(
            "data.time",
            f"time stamps are not uniform (sample {j} is {off[j]:.3g} samples off the grid of dt = {dt:.6g} s; "
            f"allowed {TIME_GRID_TOL}): resample onto a uniform grid first",
        )
    return float(dt), float(t0), t.size


def _spread_is_zero(x: np.ndarray) -> bool:
    return float(np.ptp(x)) <= CONSTANT_RTOL * max(float(np.max(np.abs(x))), 1e-300)


def run_lengths(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Runs of equal consecutive samples: their values, lengths and first indices."""
    change = np.flatnonzero(np.diff(x) != 0.0) + 1
    starts = np.concatenate([[0], change])
    lengths = np.diff(np.concatenate([starts, [x.size]]))
    return x[starts], lengths, starts


def check_clipping(name: str, x: np.ndarray) -> None:
    """Refuse a signal that sits on a rail: a saturated sensor reads a constant at its extreme.

    Clipped: the extreme value is held for at least :data:`CLIP_RUN` samples
    and :data:`CLIP_RATIO` times longer than any other value is held.  Noisy
    readings never repeat, a quantised encoder repeats every level it
    crosses slowly (its peaks too, but not much longer than the levels next to
    them), a rail holds far longer.  A run from the first sample (the machine
    at rest before the excitation) does not count.
    """
    values, lengths, starts = run_lengths(x)
    keep = starts > 0
    values, lengths = values[keep], lengths[keep]
    if values.size == 0:
        return
    for value, where in ((float(np.max(x)), "maximum"), (float(np.min(x)), "minimum")):
        at = values == value
        longest = int(lengths[at].max(initial=0))
        other = int(lengths[~at].max(initial=1))
        if longest >= CLIP_RUN and longest >= CLIP_RATIO * other:
            raise InputError(
                name,
                f"looks clipped: it holds its {where} {value:.6g} for {longest} consecutive samples (no other "
                f"value for more than {other}); a saturated sensor hides the response: record within its range",
            )


def check_data(
    time,
    u,
    outputs: Sequence[SensorOutput],
    *,
    u_max: float | None = None,
    parameters: int = 0,
) -> IdentificationData:
    """Check measured signals and return them as :class:`IdentificationData`.

    Parameters
    ----------
    time : array_like
        Sample times (s), uniform.
    u : array_like
        Input held from each time stamp to the next (N or the model's input unit).
    outputs : sequence of SensorOutput
        The measured outputs, one value per time stamp each.
    u_max : float, optional
        Actuator bound: an input beyond it was saturated by the actuator, so the
        force applied is unknown.
    parameters : int
        Number of parameters to be estimated (the data must be long enough).

    Raises
    ------
    InputError
        Too short, NaN, non-uniform time stamps, no excitation, no response,
        a clipped output, an input beyond ``u_max``.
    """
    dt, t0, n = _check_time(time)
    need = max(MIN_SAMPLES, SAMPLES_PER_PARAMETER * parameters)
    if n < need:
        raise InputError("data", f"too short: {n} samples, need at least {need} for {parameters} parameters")
    uu = _as_signal("data.input", u, n)
    if _spread_is_zero(uu):
        raise InputError("data.input", f"no excitation: the input is constant ({uu[0]:.6g}) over the record")
    if u_max is not None and float(np.max(np.abs(uu))) > u_max * (1.0 + 1e-9):
        k = int(np.argmax(np.abs(uu)))
        raise InputError(
            "data.input",
            f"|u| = {abs(uu[k]):.6g} at sample {k} exceeds u_max = {u_max:.6g}: the actuator saturated and the "
            "force it applied is unknown; excite within the bound",
        )
    if not outputs:
        raise InputError("data.output", "give at least one measured output")
    checked = []
    for j, out in enumerate(outputs):
        name = "data.output" if len(outputs) == 1 else f"data.output[{j}]"
        y = _as_signal(name, out.samples, n)
        try:
            kind = OutputKind(out.kind)
        except ValueError:
            raise InputError(
                f"{name}.kind", f"must be one of {[k.value for k in OutputKind]}, got {out.kind!r}"
            ) from None
        a0 = float(out.rigid_weight)
        if not math.isfinite(a0):
            raise InputError(f"{name}.rigid_weight", f"must be finite, got {a0}")
        if _spread_is_zero(y):
            raise InputError(name, f"does not respond: it is constant ({y[0]:.6g}) over the record")
        check_clipping(name, y)
        checked.append(SensorOutput(samples=y, kind=kind, rigid_weight=a0, name=out.name))
    if all(o.rigid_weight == 0.0 for o in checked):
        raise InputError(
            "data.output",
            "no output reads the rigid body (every rigid_weight is 0): b0 and c cannot be identified; "
            "add a position, velocity or acceleration of a body",
        )
    return IdentificationData(dt=dt, t0=t0, u=uu, outputs=tuple(checked))
