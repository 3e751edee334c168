"""Identification on the machine, ROS-free: the records, the pairing of readings with commands, the update rule.

What the planner node does for ``~/identify`` and ``identification.learn_from_moves``
(:mod:`flexmotion_ros.nodes.planner_identify` keeps the ROS side):

* the records (:mod:`.records`): the commands sent and the readings
  received, paired by sample;
* :func:`identification_settings` -- ``identification.*`` validated;
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
from .records import RECORD_CAPACITY_S, Record

#: A learning record starts only at a move from a state this still (velocity and every modal amplitude, m or rad):
#: the fit assumes rest before its first sample.
REST_TOL = 1e-6

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
        One line per changed parameter (old -> new +- the 95 % half-width).
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
            changes.append(f"omega[{i}] {omega[i]:.7g} -> {m.omega.value:.7g} +- {_half(m.omega):.2g} rad/s")
            omega[i] = m.omega.value
        if not m.zeta.contains(zeta[i]):
            z = min(max(m.zeta.value, 0.0), MAX_MODEL_ZETA)
            changes.append(f"zeta[{i}] {zeta[i]:.5g} -> {z:.5g} +- {_half(m.zeta):.2g}")
            zeta[i] = z
    b0, c = current.b0, current.c
    if not result.b0.contains(b0):
        changes.append(f"b0 {b0:.7g} -> {result.b0.value:.7g} +- {_half(result.b0):.2g}")
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
    """One line with the numbers: each mode's frequency and damping +- their 95 % half-widths, b0, noise, fit."""
    modes = "; ".join(
        f"mode {i}: omega {m.omega.value:.7g} +- {_half(m.omega):.2g} rad/s, zeta {m.zeta.value:.5g} +- "
        f"{_half(m.zeta):.2g}"
        for i, m in enumerate(result.modes)
    )
    return (
        f"{modes}{'; ' if modes else ''}b0 {result.b0.value:.7g} +- {_half(result.b0):.2g}, c "
        f"{result.c.value:.3g} +- {_half(result.c):.2g} (95 % intervals); noise {result.noise_std:.3g}, fit "
        f"{result.outputs[0].fit_percent:.2f} %, {result.samples} samples, fitted in {result.solve_time_s:.2f} s"
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
    "default_band",
    "fit_record",
    "identification_settings",
    "model_update",
    "outputs_of",
    "summary",
]
