"""Identification on the machine, ROS-free: the records, the pairing of readings with commands, the update rule.

What the planner node does for ``~/identify`` and ``identification.learn_from_moves``
(:mod:`flexmotion_ros.nodes.planner_identify` keeps the ROS side):

* :class:`SignalLog` -- a ring of time-stamped rows allocated once: the
  commands the stream actually sent (system time just before each publish,
  value) and the readings received on ``measurements`` (their stamps, one
  value per channel);
* :func:`paired_record` -- the readings of a window paired with the command
  each was read after (the sample convention of
  :mod:`flexmotion_ros.core.model.measurement`: ``y_k`` is read just after
  ``u_k`` is applied).  A lockstep plant stamps ``y_k`` with the send time of
  command ``k``, so each reading pairs with the last command sent at or before
  its stamp, one to one; a missing reading is refused.  A real-time plant
  reads on its own clock: each reading is paired with the command held then
  (approximate: the command acts from its arrival, a fraction of a sample
  later), and the record says so;
* :func:`fit_record` -- :func:`~flexmotion_ros.core.identification.identify`
  on a record, one :class:`SensorOutput` per measured channel (its kind, its
  rigid-body weight from ``measurement.map``);
* :func:`model_update` -- what to adopt: each parameter the data contradict
  (the current value outside its 95 % interval) takes the estimate, the
  others stay; a learned estimate counts only when it is confident (every
  frequency's 95 % half-width below ``identification.max_omega_interval`` of
  it, every damping ratio's below ``identification.max_zeta_interval``).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core.errors import ConfigError, InputError
from ..core.identification.data import SensorOutput
from ..core.identification.identify import identify
from ..core.identification.response import OutputKind
from ..core.identification.result import MAX_MODEL_ZETA, IdentificationResult
from ..core.model.measurement import MeasurementMap
from ..core.model.modal_model import ModalModel

#: Most samples a record holds (s of the command rate): the ring buffers are allocated for this.
RECORD_CAPACITY_S = 120.0
#: A learning record starts only at a move from a state this still (velocity and every modal amplitude, m or rad):
#: the fit assumes rest before its first sample.
REST_TOL = 1e-6
#: A lockstep plant stamps each reading with its command's send time: paired readings lie this close (s) after it.
LOCKSTEP_STAMP_TOL = 1e-3

DEFAULTS: dict[str, Any] = {
    "identification.band": [],
    "identification.modes": -1,
    "identification.duration_s": 0.0,
    "identification.adopt": False,
    "identification.learn_from_moves": False,
    "identification.ringdown_s": 2.0,
    "identification.max_omega_interval": 0.01,
    "identification.max_zeta_interval": 0.01,
    "identification.max_record_s": 60.0,
}


@dataclass(frozen=True, kw_only=True)
class IdentificationSettings:
    """The planner's ``identification.*`` parameters, validated.

    Attributes
    ----------
    band : tuple of float or None
        Excitation band ``(lo, hi)`` (rad/s); None: around the model's modes (:func:`default_band`).
    modes : int
        Modes to fit; -1: as many as the model has.
    duration_s : float or None
        Excitation length (s); None: four periods of the band's low end.
    adopt : bool
        ``~/identify`` adopts what the data contradict.
    learn_from_moves : bool
        Every move's record refines the model when confident.
    ringdown_s : float
        Idle time (s) recorded after a move before its record is fitted.
    max_omega_interval : float
        Confident: every frequency's 95 % half-width below this fraction of it.
    max_zeta_interval : float
        Confident: every damping ratio's 95 % half-width below this.
    max_record_s : float
        Longest learning record (s of samples); longer, it waits for the next start from rest.
    """

    band: tuple[float, float] | None = None
    modes: int = -1
    duration_s: float | None = None
    adopt: bool = False
    learn_from_moves: bool = False
    ringdown_s: float = 2.0
    max_omega_interval: float = 0.01
    max_zeta_interval: float = 0.01
    max_record_s: float = 60.0

    def modes_for(self, model: ModalModel) -> int:
        """Modes to fit for ``model``."""
        return model.n_modes if self.modes < 0 else self.modes


def _positive(values: Mapping[str, Any], name: str, allow_zero: bool = False, upper: float = math.inf) -> float:
    v = values.get(name, DEFAULTS[name])
    try:
        x = float(v)
    except (TypeError, ValueError):
        x = math.nan
    ok = math.isfinite(x) and (x >= 0.0 if allow_zero else x > 0.0) and x <= upper
    if not ok:
        rng = f"[0, {upper:g}]" if allow_zero else f"(0, {upper:g}]"
        raise ConfigError(name, f"must be in {rng}, got {v!r}")
    return x


def identification_settings(values: Mapping[str, Any]) -> IdentificationSettings:
    """Validate ``identification.*`` from flat parameters (missing: :data:`DEFAULTS`).

    Raises
    ------
    ConfigError
        Naming the parameter, what was wrong and the allowed range.
    """
    band_raw = list(values.get("identification.band") or [])
    band = None
    if band_raw:
        try:
            lo, hi = (float(x) for x in band_raw)
        except (TypeError, ValueError):
            raise ConfigError(
                "identification.band", f"must be two frequencies [lo, hi] in rad/s, got {band_raw!r}"
            ) from None
        if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo < hi):
            raise ConfigError("identification.band", f"needs 0 < lo < hi (rad/s), got [{lo}, {hi}]")
        band = (lo, hi)
    modes = values.get("identification.modes", DEFAULTS["identification.modes"])
    if isinstance(modes, bool) or not isinstance(modes, (int, np.integer)) or not -1 <= modes <= 8:
        raise ConfigError("identification.modes", f"must be an integer in [-1, 8] (-1: the model's), got {modes!r}")
    duration = _positive(values, "identification.duration_s", allow_zero=True, upper=RECORD_CAPACITY_S)
    return IdentificationSettings(
        band=band,
        modes=int(modes),
        duration_s=duration or None,
        adopt=bool(values.get("identification.adopt", False)),
        learn_from_moves=bool(values.get("identification.learn_from_moves", False)),
        ringdown_s=_positive(values, "identification.ringdown_s", allow_zero=True, upper=60.0),
        max_omega_interval=_positive(values, "identification.max_omega_interval", upper=1.0),
        max_zeta_interval=_positive(values, "identification.max_zeta_interval", upper=1.0),
        max_record_s=_positive(values, "identification.max_record_s", upper=RECORD_CAPACITY_S),
    )


def default_band(model: ModalModel, rate_hz: float) -> tuple[float, float]:
    """Half the lowest to 1.5 x the highest modal frequency, below 0.8 x Nyquist (rad/s).

    Raises
    ------
    ConfigError
        A model without modes (give ``identification.band``).
    """
    if not model.omega:
        raise ConfigError("identification.band", "the model has no mode to centre a band on: give [lo, hi] in rad/s")
    hi = min(1.5 * max(model.omega), 0.75 * math.pi * rate_hz)
    return 0.5 * min(model.omega), hi


class SignalLog:
    """Time-stamped rows in a ring allocated once; one writer thread, any readers.

    Parameters
    ----------
    capacity : int
        Rows kept.
    width : int
        Values per row.
    """

    def __init__(self, capacity: int, width: int) -> None:
        self._t = np.zeros(max(1, int(capacity)), dtype=np.int64)
        self._v = np.zeros((max(1, int(capacity)), max(1, int(width))))
        self._n = 0
        self._lock = threading.Lock()

    @property
    def capacity(self) -> int:
        return int(self._t.size)

    @property
    def count(self) -> int:
        """Rows appended so far (the next row's index)."""
        return self._n

    def append(self, t_ns: int, values) -> None:
        """Append one row (``t_ns``: integer ns)."""
        with self._lock:
            i = self._n % self._t.size
            self._t[i] = t_ns
            self._v[i] = values
            self._n += 1

    def rows(self, first: int, last: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Rows ``first .. last`` (inclusive; None: the newest) as copies ``(t_ns, values)``.

        Raises
        ------
        InputError
            Rows already overwritten (the record is longer than the ring).
        """
        with self._lock:
            n, cap = self._n, self._t.size
            last = n - 1 if last is None else min(int(last), n - 1)
            if first < n - cap:
                raise InputError(
                    "identification.max_record_s",
                    f"the record is longer than the {cap} samples kept; shorten it",
                )
            idx = np.arange(int(first), last + 1) % cap
            return self._t[idx].copy(), self._v[idx].copy()

    def first_at_or_after(self, t_ns: int) -> int:
        """Index of the first kept row stamped at or after ``t_ns`` (``count`` if none)."""
        with self._lock:
            n, cap = self._n, self._t.size
            start = max(0, n - cap)
            idx = np.arange(start, n)
            t = self._t[idx % cap]
        k = int(np.searchsorted(t, t_ns, side="left"))
        return start + k


@dataclass(frozen=True, kw_only=True)
class Record:
    """Commands and readings paired by sample (``u[k]`` applied, then ``y[k]`` read).

    Attributes
    ----------
    u : ndarray, shape ``(K,)``
        Commands (N).
    y : ndarray, shape ``(K, m)``
        Readings, one column per channel.
    dt : float
        Sample time (s).
    exact : bool
        One reading per command (a lockstep plant); False: readings on the
        plant's own clock, paired with the command held then.
    commands : int
        Commands sent in the window.
    """

    u: np.ndarray
    y: np.ndarray
    dt: float
    exact: bool
    commands: int

    @property
    def samples(self) -> int:
        return int(self.u.size)

    @property
    def t(self) -> np.ndarray:
        """Uniform sample times (s) from 0."""
        return self.dt * np.arange(self.u.size)


def paired_record(
    sent: SignalLog, readings: SignalLog, first: int, last: int, t_end_ns: int | None, dt: float
) -> Record:
    """Pair the readings of a window with the commands they were read after.

    Parameters
    ----------
    sent : SignalLog
        Commands sent (system time ns just before publishing, value).
    readings : SignalLog
        Readings received (stamp ns, one value per channel).
    first, last : int
        Indices in ``sent`` of the window's first and last commands.
    t_end_ns : int or None
        Readings stamped at or after this are outside the window (None: one
        sample after the last command).
    dt : float
        Sample time (s).

    Raises
    ------
    InputError
        Parameter ``measurements``: no reading in the window, readings missing
        for some commands of a lockstep plant, or none for the end of the window (stale).
    """
    tc, uc = sent.rows(first, last)
    uc = uc[:, 0]
    if tc.size == 0:
        raise InputError("measurements", "no command was sent in the window")
    dt_ns = int(round(dt * 1e9))
    end = int(tc[-1]) + dt_ns if t_end_ns is None else int(t_end_ns)
    if sent.count > last + 1:  # the next command's reading is outside the window, however soon it was sent
        end = min(end, int(sent.rows(last + 1, last + 1)[0][0]))
    j0 = readings.first_at_or_after(int(tc[0]))
    if j0 >= readings.count:
        raise InputError(
            "measurements",
            "no reading received since the first command of the window: missing (is the plant publishing "
            "'measurements'?) or stale",
        )
    tr, yr = readings.rows(j0)
    keep = tr < end
    tr, yr = tr[keep], yr[keep]
    if np.any(np.diff(tr) < 0):
        raise InputError("measurements", "reading stamps go back in time: two publishers on 'measurements'?")
    j = np.searchsorted(tc, tr, side="right") - 1  # the last command sent at or before each reading
    ok = (j >= 0) & (j < tc.size)
    tr, yr, j = tr[ok], yr[ok], j[ok]
    if tr.size == 0:
        raise InputError("measurements", "no reading in the window: missing or stale")
    lag = (tr - tc[j]) * 1e-9
    exact = bool(np.median(lag) < LOCKSTEP_STAMP_TOL)
    if exact:
        counts = np.bincount(j, minlength=tc.size)
        missing = int(np.count_nonzero(counts == 0))
        if missing or np.any(counts > 1):
            first_missing = int(np.argmax(counts == 0)) if missing else -1
            raise InputError(
                "measurements",
                f"{missing} of {tc.size} commands have no reading (first: sample {first_missing} of the window), "
                f"{int(np.count_nonzero(counts > 1))} more than one: readings lost or stale; nothing identified",
            )
        return Record(u=uc.copy(), y=yr, dt=dt, exact=True, commands=int(tc.size))
    if (end - int(tr[-1])) * 1e-9 > 3.0 * dt and t_end_ns is not None:
        raise InputError(
            "measurements",
            f"the last reading is {(end - int(tr[-1])) * 1e-9:.3g} s before the end of the window: stale",
        )
    return Record(u=uc[j], y=yr, dt=dt, exact=False, commands=int(tc.size))


def outputs_of(record: Record, mmap: MeasurementMap) -> list[SensorOutput]:
    """One :class:`SensorOutput` per measured channel (its kind, its rigid-body weight)."""
    w = mmap.rigid_weights()
    return [
        SensorOutput(samples=record.y[:, j], kind=OutputKind(kind.value), rigid_weight=float(w[j]), name=name)
        for j, (name, kind) in enumerate(zip(mmap.names, mmap.kinds))
    ]


def fit_record(
    record: Record, mmap: MeasurementMap, model: ModalModel, modes: int, u_max: float
) -> IdentificationResult:
    """Identify ``modes`` modes from ``record`` (``model`` as the prior).

    Raises
    ------
    InputError
        Parameter ``measurement.map`` when no channel reads a mode; else the
        core's refusal (too short, no excitation, a mode not shown, ...).
    """
    if modes > 0 and not np.any(mmap.sees_modes()):
        raise InputError(
            "measurement.map",
            f"no measured channel ({', '.join(mmap.names)}) reads a mode: nothing to identify the modes from; "
            "give measurement.names/map (flexmotion model ... writes them)",
        )
    return identify(record.t, record.u, outputs_of(record, mmap), modes=modes, prior=model, u_max=u_max)


@dataclass(frozen=True, kw_only=True)
class ModelUpdate:
    """What an identification changes in the planner's model.

    Attributes
    ----------
    model : ModalModel
        The model to plan with (the current one where the data agree with it).
    changes : tuple of str
        One line per changed parameter (old -> new, the 95 % interval).
    confident : bool
        Every interval is within the thresholds.
    reason : str
        Why not confident ("" if confident).
    parameters : dict
        What to set: the changed ``model.*`` and the frequency intervals
        ``auto_robust.omega_min`` / ``auto_robust.omega_max`` (rad/s) that method ``auto_robust`` covers.
    """

    model: ModalModel
    changes: tuple[str, ...]
    confident: bool
    reason: str = ""
    parameters: dict = field(default_factory=dict)


def _half(est) -> float:
    lo, hi = est.interval
    return 0.5 * (hi - lo)


def model_update(current: ModalModel, result: IdentificationResult, settings: IdentificationSettings) -> ModelUpdate:
    """The update rule (module docstring): a parameter changes only where the data contradict it.

    A result with a different number of modes than ``current`` changes
    nothing (``identification.modes`` sets how many are fitted).
    """
    if result.n_modes != current.n_modes:
        return ModelUpdate(
            model=current,
            changes=(),
            confident=False,
            reason=f"identified {result.n_modes} mode(s), the model has {current.n_modes}: not adopted",
        )
    reasons = []
    for i, m in enumerate(result.modes):
        rel = _half(m.omega) / m.omega.value
        if not rel <= settings.max_omega_interval:
            reasons.append(
                f"omega[{i}] 95 % half-width {rel:.2%} > identification.max_omega_interval {settings.max_omega_interval:.2%}"
            )
        if not _half(m.zeta) <= settings.max_zeta_interval:
            reasons.append(
                f"zeta[{i}] 95 % half-width {_half(m.zeta):.3g} > identification.max_zeta_interval "
                f"{settings.max_zeta_interval:g}"
            )
    order = np.argsort(current.omega)  # identified modes come sorted by frequency
    omega, zeta = list(current.omega), list(current.zeta)
    lo, hi = [0.0] * len(omega), [0.0] * len(omega)
    changes = []
    for k, i in enumerate(order):
        m = result.modes[k]
        lo[i], hi[i] = (max(float(x), 1e-12) for x in m.omega.interval)
        if not m.omega.contains(omega[i]):
            changes.append(
                f"omega[{i}] {omega[i]:.6g} -> {m.omega.value:.6g} rad/s (95 %: {m.omega.interval[0]:.6g}.."
                f"{m.omega.interval[1]:.6g})"
            )
            omega[i] = m.omega.value
        if not m.zeta.contains(zeta[i]):
            z = min(max(m.zeta.value, 0.0), MAX_MODEL_ZETA)
            changes.append(
                f"zeta[{i}] {zeta[i]:.4g} -> {z:.4g} (95 %: {m.zeta.interval[0]:.4g}..{m.zeta.interval[1]:.4g})"
            )
            zeta[i] = z
    b0, c = current.b0, current.c
    if not result.b0.contains(b0):
        changes.append(
            f"b0 {b0:.6g} -> {result.b0.value:.6g} (95 %: {result.b0.interval[0]:.6g}..{result.b0.interval[1]:.6g})"
        )
        b0 = result.b0.value
    if not result.c.contains(c) and min(result.c.value, 0.0) != c:
        changes.append(f"c {c:.4g} -> {min(result.c.value, 0.0):.4g} 1/s")
        c = min(result.c.value, 0.0)
    model = current.with_changes(b0=b0, c=c, omega=tuple(omega), zeta=tuple(zeta))
    params: dict[str, Any] = {}
    if model.omega != current.omega:
        params["model.omega"] = list(model.omega)
    if model.zeta != current.zeta:
        params["model.zeta"] = list(model.zeta)
    if model.b0 != current.b0:
        params["model.b0"] = model.b0
    if model.c != current.c:
        params["model.c"] = model.c
    if lo:  # the frequencies' 95 % intervals: what method auto_robust must be insensitive over
        params.update({"auto_robust.omega_min": lo, "auto_robust.omega_max": hi})
    return ModelUpdate(
        model=model, changes=tuple(changes), confident=not reasons, reason="; ".join(reasons), parameters=params
    )


def summary(result: IdentificationResult) -> str:
    """One line with the numbers: each mode's frequency and damping with their 95 % intervals, b0, noise, fit."""
    modes = "; ".join(
        f"mode {i}: omega {m.omega.value:.6g} rad/s [{m.omega.interval[0]:.6g}, {m.omega.interval[1]:.6g}], "
        f"zeta {m.zeta.value:.4g} [{m.zeta.interval[0]:.4g}, {m.zeta.interval[1]:.4g}]"
        for i, m in enumerate(result.modes)
    )
    return (
        f"{modes}{'; ' if modes else ''}b0 {result.b0.value:.6g} [{result.b0.interval[0]:.6g}, "
        f"{result.b0.interval[1]:.6g}], c {result.c.value:.3g}; noise {result.noise_std:.3g}, fit "
        f"{result.outputs[0].fit_percent:.2f} %, {result.samples} samples, {result.solve_time_s:.2f} s"
    )


@dataclass
class ExcitationRecord:
    """What an excitation segment on the stream is (``Segment.info``); ``first`` is set when it starts.

    Attributes
    ----------
    band : tuple of float
        (rad/s).
    first : int or None
        Index in the sent-command log of its first command (None until sent).
    started : threading.Event
        Set when its first command is sent.
    """

    band: tuple[float, float]
    first: int | None = None
    started: threading.Event = field(default_factory=threading.Event)


__all__ = [
    "DEFAULTS",
    "REST_TOL",
    "ExcitationRecord",
    "IdentificationSettings",
    "ModelUpdate",
    "Record",
    "SignalLog",
    "default_band",
    "fit_record",
    "identification_settings",
    "model_update",
    "outputs_of",
    "paired_record",
    "summary",
]
