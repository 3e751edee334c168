"""Closed-loop replanning in a node: the state estimator fed by the stream, and its settings (ROS-free).

``feedback.replan_period_s > 0``: during a move the planner estimates the
machine's state with a Kalman filter on its own modal model
(:mod:`flexmotion_ros.core.estimation.kalman`), fed with the commands it sent
and the measurements, and every period replans from the estimate
(:func:`~.replan.replan`), spliced ahead of the planning time as a preemption
is.  :class:`StreamEstimator` keeps the filter in step with the stream:

* every command sent, ``(k, u)`` in send order (the stream thread calls
  :meth:`StreamEstimator.command`);
* every measurement, in arrival order (:meth:`StreamEstimator.measurement`):
  the state *after* a command -- the lockstep plant's ``joint_states`` (one
  reliable message per command, in order, ``effort`` = the command it
  applied, which pairs them: :class:`StreamEstimator`);
* a move from idle restarts the filter at the plan's start state when its
  first command is sent (:meth:`StreamEstimator.restart`).

:meth:`StreamEstimator.estimate` filters as far as the measurements go, then
predicts with the commands sent since (no measurement yet): the estimate of
the state before the next sample, with its covariance.

Measurements: the full state ``[p, v, q_1, q_1', ...]`` of ``joint_states``
(``C = I``, std ``feedback.measurement_std``), the fallback until the plant's
``measurements`` topic of physical coordinates (issue 13) is wired here.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.errors import ConfigError
from ..core.estimation.kalman import Estimate, KalmanModel, kalman_model, predict, update
from ..core.model.modal_model import ModalModel

#: A measurement pairs with its command if the command it reports applying agrees to this (relative to 1 + |u|).
PAIRING_RTOL = 1e-9


@dataclass(frozen=True, kw_only=True)
class FeedbackSettings:
    """``feedback.*``.

    Attributes
    ----------
    replan_period_s : float
        Replan every this many seconds during a move (0: off).
    measurement_std : float
        Standard deviation of each measured coordinate (its unit).
    input_noise_std : float
        Standard deviation of the input disturbance per sample (the input's unit, N).
    min_deviation : float
        Replan only when the estimate deviates from the plan by more than this fraction of the move.
    """

    replan_period_s: float = 0.0
    measurement_std: float = 1e-6
    input_noise_std: float = 0.01
    min_deviation: float = 1e-6

    @property
    def enabled(self) -> bool:
        """Replanning is on."""
        return self.replan_period_s > 0.0


def feedback_settings(values: Mapping[str, Any]) -> FeedbackSettings:
    """Validate ``feedback.*``; :class:`ConfigError` names the bad one."""
    period = float(values.get("feedback.replan_period_s", 0.0))
    if not (math.isfinite(period) and period >= 0.0):
        raise ConfigError("feedback.replan_period_s", f"must be finite and >= 0 s (0: off), got {period}")
    std = float(values.get("feedback.measurement_std", 1e-6))
    if not (math.isfinite(std) and std > 0.0):
        raise ConfigError("feedback.measurement_std", f"must be finite and > 0, got {std}")
    w = float(values.get("feedback.input_noise_std", 0.01))
    if not (math.isfinite(w) and w >= 0.0):
        raise ConfigError("feedback.input_noise_std", f"must be finite and >= 0, got {w}")
    dev = float(values.get("feedback.min_deviation", 1e-6))
    if not (math.isfinite(dev) and 0.0 < dev < 1.0):
        raise ConfigError("feedback.min_deviation", f"must be in (0, 1) (a fraction of the move), got {dev}")
    return FeedbackSettings(replan_period_s=period, measurement_std=std, input_noise_std=w, min_deviation=dev)


@dataclass(frozen=True, kw_only=True)
class StreamEstimate:
    """The filter's estimate of the state before sample ``sample``.

    Attributes
    ----------
    x : ndarray
        ``[p, v, q_1, q_1', ...]``.
    P : ndarray
        Its covariance.
    sample : int
        Global sample index the estimate is for (before its command).
    measured_to : int
        Global index of the first sample after the last measurement used (``sample - measured_to``:
        the commands predicted without a measurement).
    """

    x: np.ndarray
    P: np.ndarray
    sample: int
    measured_to: int


class StreamEstimator:
    """A Kalman filter kept in step with the command stream (module docstring).

    Pairing: the ``m``-th measurement received is the state after command
    ``m - offset`` (both counted in arrival / send order).  The offset is
    found once per move from idle: the first measurement after the restart
    that reports applying the move's first non-zero command (bit for bit)
    answers that command -- earlier measurements (idle holds, samples lost
    before DDS matched) are dropped.  Every later pair is checked the same way.

    Parameters
    ----------
    model : ModalModel
        The planner's model.
    dt : float
        Sample period (s).
    settings : FeedbackSettings
    """

    def __init__(self, model: ModalModel, dt: float, settings: FeedbackSettings) -> None:
        n = model.n_states
        self.km: KalmanModel = kalman_model(
            model, dt, np.eye(n), settings.measurement_std, input_noise_std=settings.input_noise_std
        )
        self._std = settings.measurement_std
        self._lock = threading.Lock()
        self._commands: deque[tuple[int, int, float]] = deque()  # (send index, k, u) of the move
        self._measurements: deque[tuple[int, np.ndarray, float]] = deque()  # (arrival index, y, applied)
        self._sent = 0
        self._measured = 0
        self._pending: tuple[int, np.ndarray] | None = None  # (first sample, start state) of a move from idle
        self._low = 0  # measurements before this index came before the move
        self._offset: int | None = None
        self._est: Estimate | None = None
        self._at = -1  # send index of the command the estimate comes before
        self._measured_to = -1  # the sample after the last measurement used
        #: Why the filter stopped (a measurement that did not pair with its command), "" while fine.
        self.fault = ""

    def restart(self, first_sample: int, x0) -> None:
        """A move from idle: when its first command (global sample ``first_sample``) is sent, the state is ``x0``."""
        with self._lock:
            self._pending = (int(first_sample), np.array(x0, float))
            self._low = self._measured

    def command(self, k: int, u: float) -> None:
        """Command ``u`` sent at global sample ``k`` (the stream thread)."""
        with self._lock:
            j = self._sent
            self._sent += 1
            if self._pending is not None and k >= self._pending[0]:
                self._est = Estimate(x=self._pending[1], P=np.eye(self.km.n_states) * self._std**2)
                self._at = j
                self._measured_to = int(k)
                self._pending = None
                self._offset = None
                self._commands.clear()
                self.fault = ""
            if self._est is not None:
                self._commands.append((j, int(k), float(u)))

    def measurement(self, y, applied: float) -> None:
        """The next measurement in arrival order: the state after a command (``applied``: that command)."""
        with self._lock:
            m = self._measured
            self._measured += 1
            if self._est is not None or self._pending is not None:
                self._measurements.append((m, np.asarray(y, float), float(applied)))

    def _sync(self) -> None:
        """Find the offset: the move's first non-zero command and the first measurement reporting it."""
        meas = self._measurements
        while meas and meas[0][0] < self._low:
            meas.popleft()
        first = next(((j, u) for j, _, u in self._commands if u != 0.0), None)
        if first is None:
            return
        j, u = first
        for m, _, applied in meas:
            if applied == u:
                self._offset = m - j
                break
        if self._offset is not None:
            while meas and meas[0][0] - self._offset < self._at:
                meas.popleft()

    def estimate(self) -> StreamEstimate | None:
        """Filter what has been measured, then predict with the commands sent since; None before a move."""
        with self._lock:
            est = self._est
            if est is None or self.fault:
                return None
            if self._offset is None:
                self._sync()
            cmds, meas = self._commands, self._measurements
            while self._offset is not None and cmds and meas and meas[0][0] - self._offset == cmds[0][0]:
                j, k, u = cmds.popleft()
                _, y, applied = meas.popleft()
                if abs(applied - u) > PAIRING_RTOL * (1.0 + abs(u)):
                    self.fault = (
                        f"the measured state after command {j} reports applying {applied!r}, the stream sent {u!r}: "
                        "measurements and commands do not pair (one measured state per command, in order)"
                    )
                    self._est = None
                    return None
                est, _ = update(self.km, predict(self.km, est, u), y)
                self._at = j + 1
                self._measured_to = k + 1
            self._est = est
            measured_to = self._measured_to
            ahead = [(k, u) for _, k, u in cmds]
        # predict with the commands not yet measured (outside the lock: the stream thread appends meanwhile)
        for _, u in ahead:
            est = predict(self.km, est, u)
        sample = ahead[-1][0] + 1 if ahead else measured_to
        return StreamEstimate(x=est.x, P=est.P, sample=sample, measured_to=measured_to)


__all__ = ["PAIRING_RTOL", "FeedbackSettings", "StreamEstimate", "StreamEstimator", "feedback_settings"]
