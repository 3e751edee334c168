"""Closed-loop replanning in a node: the state estimator fed by the stream, and its settings (ROS-free).

``feedback.replan_period_s > 0``: during a move the planner estimates the
machine's state with a Kalman filter on its own modal model
(:mod:`flexmotion_ros.core.estimation.kalman`), fed with the commands it sent
and the plant's ``measurements`` (physical coordinates ``y = C x + D u`` with
noise, :mod:`flexmotion_ros.core.model.measurement`; the spec of issue 13),
and every period replans from the estimate (:func:`~.replan.replan`), spliced
ahead of the planning time as a preemption is.  :class:`StreamEstimator`
keeps the filter in step with the stream:

* every command sent, ``(k, u, t)`` in send order, ``t`` the system time
  just before it was published (the stream thread calls
  :meth:`StreamEstimator.command`);
* every reading ``(stamp, y)`` (:meth:`StreamEstimator.measurement`): the
  plant reads sample ``k`` just after command ``k`` is applied, ``y_k = C x_k
  + D u_k``, and a lockstep plant stamps it with the command's DDS send time;
  so a reading belongs to the last command sent at or before its stamp (a
  real-time plant stamps its own ticks: the pairing is then to the sample
  whose command was sent last before the tick, within one sample);
* a move from idle restarts the filter at the plan's start state when its
  first command is sent (:meth:`StreamEstimator.restart`).

:meth:`StreamEstimator.estimate` filters as far as the readings go (update
with ``y_k - D u_k``, then predict with ``u_k``; a sample whose reading never
came -- a later one did -- is predicted only), then predicts with the
commands sent since: the estimate of the state before the next sample, with
its covariance.
"""

from __future__ import annotations

import bisect
import math
import threading
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..core.errors import ConfigError
from ..core.estimation.kalman import Estimate, KalmanModel, kalman_model, predict, update
from ..core.model.modal_model import ModalModel


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
        Standard deviation of the input disturbance per sample (the input's unit, N); the filter
        also assumes as much acting independently on every coordinate (model error).
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


#: An estimate predicted over more than this many replanning periods since its last reading is stale: no
#: replan from it (a model a few per cent off, predicted open loop for 0.8 s while the readings lagged under
#: load, was off by 4 % of the move, and the loop corrected what was not there).
STALE_PERIODS = 2.0


def stale_reason(estimate: StreamEstimate, period_s: float, rate_hz: float) -> str | None:
    """Why ``estimate`` is too stale to replan from (None: fresh enough); see :data:`STALE_PERIODS`."""
    unread = estimate.sample - estimate.measured_to
    limit = max(1, math.ceil(STALE_PERIODS * period_s * rate_hz))
    if unread > limit:
        return f"the estimate is stale: {unread} samples predicted since the last reading (at most {limit})"
    return None


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

    Parameters
    ----------
    model : ModalModel
        The planner's model.
    dt : float
        Sample period (s).
    settings : FeedbackSettings
    C : array_like, shape ``(m, n)``
        The readings from the state (``MeasurementMap.for_model``).
    D : array_like, shape ``(m,)``
        Their feedthrough of the input (acceleration channels; 0 otherwise).

    Raises
    ------
    ModelError
        The readings cannot observe a mode (or the rigid body) at this sample period.
    """

    def __init__(self, model: ModalModel, dt: float, settings: FeedbackSettings, C, D=None) -> None:
        C = np.atleast_2d(np.asarray(C, float))
        km = kalman_model(model, dt, C, settings.measurement_std, input_noise_std=settings.input_noise_std)
        # the input disturbance on the actuator (rank one), and as much again independently on every coordinate:
        # a model error (a frequency off by a few %) moves the state where no input could, and a filter without
        # noise there trusts its model over the readings (measured: 6e-3 of bias for 5 %, 2e-5 with it)
        g = km.Gamma
        self.km: KalmanModel = replace(km, Q=km.Q + settings.input_noise_std**2 * np.diag(g * g))
        self._D = np.zeros(C.shape[0]) if D is None else np.asarray(D, float).ravel()
        self._std = settings.measurement_std
        self._lock = threading.Lock()
        self._commands: deque[tuple[int, int, float, int]] = deque()  # (send index, k, u, send time ns)
        self._readings: dict[int, np.ndarray] = {}  # send index -> reading of the state before that command
        self._unpaired: deque[tuple[int, np.ndarray]] = deque()  # readings whose command is not logged yet
        self._sent = 0
        self._pending: tuple[int, np.ndarray] | None = None  # (first sample, start state) of a move from idle
        self._est: Estimate | None = None
        self._at = -1  # send index of the command the estimate comes before
        self._latest_read = -1  # the latest send index a reading paired with
        self._measured_to = -1  # the sample after the last reading used
        #: Readings used, and readings dropped (before the move, or no command to pair with).
        self.used = 0
        self.dropped = 0

    def restart(self, first_sample: int, x0) -> None:
        """A move from idle: when its first command (global sample ``first_sample``) is sent, the state is ``x0``."""
        with self._lock:
            self._pending = (int(first_sample), np.array(x0, float))

    def command(self, k: int, u: float, t_ns: int) -> None:
        """Command ``u`` sent at global sample ``k``, at system time ``t_ns`` (the stream thread)."""
        with self._lock:
            j = self._sent
            self._sent += 1
            if self._pending is not None and k >= self._pending[0]:
                self._est = Estimate(x=self._pending[1], P=np.eye(self.km.n_states) * self._std**2)
                self._at = j
                self._measured_to = int(k)
                self._pending = None
                self._commands.clear()
                self._readings.clear()
                self._latest_read = j - 1
            if self._est is not None:
                self._commands.append((j, int(k), float(u), int(t_ns)))

    def measurement(self, stamp_ns: int, y) -> None:
        """A reading stamped ``stamp_ns`` (system time ns; the subscription's thread)."""
        with self._lock:
            if self._est is not None:
                self._unpaired.append((int(stamp_ns), np.asarray(y, float)))

    def _pair(self) -> None:
        """Each reading to the last command sent at or before its stamp (readings wait for their command)."""
        cmds = self._commands
        if not cmds:
            self.dropped += len(self._unpaired)
            self._unpaired.clear()
            return
        times = [c[3] for c in cmds]
        while self._unpaired:
            stamp, y = self._unpaired[0]
            i = bisect.bisect_right(times, stamp) - 1
            if i < 0:  # before the move's first command (or a command already filtered): nothing to pair with
                self._unpaired.popleft()
                self.dropped += 1
                continue
            if i == len(cmds) - 1:
                break  # after the last command logged: it may be the reading of one not logged yet
            self._unpaired.popleft()
            j = cmds[i][0]
            self._readings[j] = y
            self._latest_read = max(self._latest_read, j)

    def estimate(self) -> StreamEstimate | None:
        """Filter what has been read, then predict with the commands sent since; None before a move."""
        with self._lock:
            est = self._est
            if est is None:
                return None
            self._pair()
            cmds = self._commands
            while cmds and cmds[0][0] == self._at:
                j, k, u, _ = cmds[0]
                y = self._readings.pop(j, None)
                if y is None and self._latest_read <= j:
                    break  # its reading may still come
                if y is not None:
                    est, _ = update(self.km, est, y - self._D * u)
                    self.used += 1
                est = predict(self.km, est, u)
                cmds.popleft()
                self._at = j + 1
                self._measured_to = k + 1
            self._est = est
            measured_to = self._measured_to
            ahead = [(k, u) for _, k, u, _ in cmds]
        # predict with the commands not yet read (outside the lock: the stream thread appends meanwhile)
        for _, u in ahead:
            est = predict(self.km, est, u)
        sample = ahead[-1][0] + 1 if ahead else measured_to
        return StreamEstimate(x=est.x, P=est.P, sample=sample, measured_to=measured_to)


__all__ = [
    "STALE_PERIODS",
    "FeedbackSettings",
    "StreamEstimate",
    "StreamEstimator",
    "feedback_settings",
    "stale_reason",
]
