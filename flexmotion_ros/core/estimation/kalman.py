"""A discrete Kalman filter on the planner's modal model: the modal state no sensor measures directly.

The plant between two samples, with the command sent ``u_k`` and an unknown
input disturbance ``w_k`` held over the sample (the same exact ZOH as every
planner, :func:`~flexmotion_ros.core.simulation.exact.step_matrices`)::

    x_{k+1} = Phi x_k + Gamma (u_k + w_k),   w_k ~ N(0, sigma_w^2)   ->   Q = sigma_w^2 Gamma Gamma^T
    y_k     = C x_k + e_k,                    e_k ~ N(0, R)

``y`` are physical coordinates (a cart and a payload position, a link tip):
rows of ``C`` come from a builder's map to physical coordinates
(:func:`measurement_matrix`) or are given as they are.  Per sample: update
with ``y_k`` (:func:`update`: ``x_{k|k}``, the innovation and its NIS), then
predict with ``u_k`` (:func:`predict`: ``x_{k+1|k}``).  With
``steady_state=True`` the gain is the limit one, from the discrete algebraic
Riccati equation, and the covariance stays at its limit.

Every result is a frozen dataclass; the functions are pure, so a node keeps
one :class:`Estimate` and replaces it each sample.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_discrete_are

from ..errors import ConfigError, ModelError
from ..model.builders import BuiltModel
from ..model.modal_model import ModalModel
from ..simulation.exact import step_matrices

#: Relative singular-value threshold of the observability (PBH) test.
OBSERVABILITY_RTOL = 1e-9


@dataclass(frozen=True, kw_only=True)
class KalmanModel:
    """The filter's matrices.

    Attributes
    ----------
    dt : float
        Sample period (s).
    Phi, Gamma : ndarray
        Exact ZOH transition ``(n, n)`` and input ``(n,)`` over ``dt``.
    C : ndarray, shape ``(m, n)``
        Measurement matrix (physical coordinates from the modal state).
    Q : ndarray, shape ``(n, n)``
        Process noise ``sigma_w^2 Gamma Gamma^T`` (state units squared).
    R : ndarray, shape ``(m, m)``
        Measurement noise covariance (measurement units squared).
    steady_gain : ndarray or None, shape ``(n, m)``
        The limit gain (None: the filter propagates its covariance).
    steady_covariance : ndarray or None
        The limit predicted covariance ``P_{k+1|k}`` (with ``steady_gain``).
    """

    dt: float
    Phi: np.ndarray
    Gamma: np.ndarray
    C: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    steady_gain: np.ndarray | None = None
    steady_covariance: np.ndarray | None = None

    @property
    def n_states(self) -> int:
        """State dimension ``n``."""
        return int(self.Phi.shape[0])

    @property
    def n_measurements(self) -> int:
        """Measurement dimension ``m``."""
        return int(self.C.shape[0])


@dataclass(frozen=True, kw_only=True)
class Estimate:
    """The state estimate and its covariance.

    Attributes
    ----------
    x : ndarray, shape ``(n,)``
        ``[p, v, q_1, q_1', ...]`` (m, m/s, modal coordinates).
    P : ndarray, shape ``(n, n)``
        Error covariance.
    """

    x: np.ndarray
    P: np.ndarray


@dataclass(frozen=True, kw_only=True)
class Innovation:
    """What a measurement said against the prediction.

    Attributes
    ----------
    residual : ndarray, shape ``(m,)``
        ``y - C x_{k|k-1}`` (measurement units).
    S : ndarray, shape ``(m, m)``
        Its predicted covariance ``C P C^T + R``.
    nis : float
        Normalised innovation squared ``r^T S^-1 r`` (chi-square with ``m`` degrees of freedom when consistent).
    """

    residual: np.ndarray
    S: np.ndarray
    nis: float


def measurement_matrix(
    built: BuiltModel, coordinates: Sequence[str] | None = None, velocities: bool = False
) -> np.ndarray:
    """Rows of ``C`` for physical coordinates of a built model (positions, optionally velocities too).

    Parameters
    ----------
    built : BuiltModel
        ``y = modal_to_physical @ [p, q_1, ..., q_N]``.
    coordinates : sequence of str, optional
        Which of ``built.coordinates`` are measured (default: all).
    velocities : bool
        Also measure their velocities (rows after the positions).

    Raises
    ------
    ConfigError
        An unknown coordinate name.
    """
    names = list(built.coordinates)
    chosen = names if coordinates is None else list(coordinates)
    n = built.model.n_states
    cols = [0, *range(2, n, 2)]  # p, q_1, ..., q_N in the state
    rows = []
    for name in chosen:
        if name not in names:
            raise ConfigError("measurement.coordinates", f"unknown coordinate {name!r}; known: {names}")
        row = np.zeros(n)
        row[cols] = built.modal_to_physical[names.index(name)]
        rows.append(row)
    if velocities:
        rows += [np.roll(r, 1) for r in list(rows)]  # the same combination of the velocity states
    return np.array(rows)


def kalman_model(
    model: ModalModel,
    dt: float,
    C,
    measurement_std=None,
    *,
    R=None,
    input_noise_std: float = 0.0,
    steady_state: bool = False,
) -> KalmanModel:
    """Build the filter for ``model`` sampled at ``dt`` (s).

    Parameters
    ----------
    model : ModalModel
        The planner's model.
    dt : float
        Sample period (s).
    C : array_like, shape ``(m, n)``
        Measurement rows (:func:`measurement_matrix`, or a list of rows over the state).
    measurement_std : float or sequence of float, optional
        Standard deviation of each measurement (its unit); or give ``R``.
    R : array_like, optional
        Measurement covariance ``(m, m)``.
    input_noise_std : float
        Standard deviation of the input disturbance held over each sample (the input's unit, N).
    steady_state : bool
        Use the limit gain (discrete Riccati equation).

    Raises
    ------
    ConfigError
        Shapes or noise levels that cannot be used.
    ModelError
        A mode (or the rigid body) that the measurements cannot observe at this sample period.
    """
    if not (math.isfinite(dt) and dt > 0.0):
        raise ConfigError("estimator.dt", f"must be finite and > 0 s, got {dt}")
    n = model.n_states
    C = np.atleast_2d(np.asarray(C, dtype=float))
    if C.shape[1] != n or not np.all(np.isfinite(C)):
        raise ConfigError("measurement.rows", f"each row needs {n} finite entries (one per state), got shape {C.shape}")
    m = C.shape[0]
    if R is None:
        if measurement_std is None:
            raise ConfigError("measurement.std", "give the measurement noise (std per row, or R)")
        std = np.broadcast_to(np.asarray(measurement_std, dtype=float), (m,))
        if not np.all(np.isfinite(std)) or np.any(std <= 0.0):
            raise ConfigError("measurement.std", f"must be finite and > 0, got {measurement_std!r}")
        R = np.diag(std**2)
    R = np.atleast_2d(np.asarray(R, dtype=float))
    if R.shape != (m, m) or not np.allclose(R, R.T) or np.min(np.linalg.eigvalsh(R)) <= 0.0:
        raise ConfigError("measurement.R", f"must be a symmetric positive definite ({m}, {m}) matrix")
    sw = float(input_noise_std)
    if not (math.isfinite(sw) and sw >= 0.0):
        raise ConfigError("estimator.input_noise_std", f"must be finite and >= 0, got {input_noise_std!r}")
    Phi, Gamma = step_matrices(model.A(), model.B(), dt)
    check_observable(Phi, C, model, dt)
    Q = sw * sw * np.outer(Gamma, Gamma)
    gain = cov = None
    if steady_state:
        if sw == 0.0:
            raise ConfigError(
                "estimator.input_noise_std", "must be > 0 for a steady-state gain (else the gain tends to 0)"
            )
        cov = solve_discrete_are(Phi.T, C.T, Q, R)
        gain = cov @ C.T @ np.linalg.inv(C @ cov @ C.T + R)
    return KalmanModel(dt=float(dt), Phi=Phi, Gamma=Gamma, C=C, Q=Q, R=R, steady_gain=gain, steady_covariance=cov)


def check_observable(Phi: np.ndarray, C: np.ndarray, model: ModalModel, dt: float) -> None:
    """PBH test of the sampled pair ``(Phi, C)``: every eigenvalue must show in the measurements.

    Raises
    ------
    ModelError
        Naming the first unobservable part (rigid body or mode), with the reason.
    """
    n = Phi.shape[0]
    names = ["the rigid body", "the rigid body", *(f"mode {name}" for name in model.names for _ in (0, 1))]
    lam, vecs = np.linalg.eig(Phi)
    for j, lj in enumerate(lam):
        s = np.linalg.svd(np.vstack([lj * np.eye(n) - Phi, C]), compute_uv=False)
        if s[-1] <= OBSERVABILITY_RTOL * max(s[0], 1.0):
            part = names[int(np.argmax(np.abs(vecs[:, j])))]
            raise ModelError(
                "measurement.rows",
                f"{part} cannot be observed from these measurements at dt = {dt:g} s "
                "(measure a coordinate it moves, or change the sample period)",
            )


def initial_estimate(km: KalmanModel, x0, std) -> Estimate:
    """An initial estimate ``x0`` with independent errors of standard deviation ``std`` (scalar or per state)."""
    x = np.asarray(x0, dtype=float).ravel()
    s = np.broadcast_to(np.asarray(std, dtype=float), (km.n_states,))
    if x.size != km.n_states or not np.all(np.isfinite(x)) or not np.all(np.isfinite(s)) or np.any(s < 0.0):
        raise ConfigError("estimator.initial", f"needs {km.n_states} finite states and std >= 0")
    P = km.steady_covariance.copy() if km.steady_gain is not None else np.diag(s * s)
    return Estimate(x=x, P=P)


def update(km: KalmanModel, est: Estimate, y) -> tuple[Estimate, Innovation]:
    """Measurement update with ``y_k``: ``x_{k|k}`` and the innovation (Joseph form for the covariance)."""
    y = np.asarray(y, dtype=float).ravel()
    C, R = km.C, km.R
    r = y - C @ est.x
    S = C @ est.P @ C.T + R
    nis = float(r @ np.linalg.solve(S, r))
    if km.steady_gain is not None:
        return Estimate(x=est.x + km.steady_gain @ r, P=est.P), Innovation(residual=r, S=S, nis=nis)
    K = np.linalg.solve(S, C @ est.P).T  # P C^T S^-1 (S and P symmetric)
    IKC = np.eye(km.n_states) - K @ C
    P = IKC @ est.P @ IKC.T + K @ R @ K.T
    return Estimate(x=est.x + K @ r, P=0.5 * (P + P.T)), Innovation(residual=r, S=S, nis=nis)


def predict(km: KalmanModel, est: Estimate, u: float) -> Estimate:
    """Time update with the command sent ``u_k`` (N), held for one sample: ``x_{k+1|k}``."""
    x = km.Phi @ est.x + km.Gamma * float(u)
    if km.steady_gain is not None:
        return Estimate(x=x, P=est.P)
    P = km.Phi @ est.P @ km.Phi.T + km.Q
    return Estimate(x=x, P=0.5 * (P + P.T))


@dataclass(frozen=True, kw_only=True)
class FilterRun:
    """A filter run over a record (rows: samples).

    Attributes
    ----------
    x : ndarray, shape ``(K, n)``
        ``x_{k|k}`` after each measurement.
    P : ndarray, shape ``(K, n, n)``
        Its covariance.
    nis : ndarray, shape ``(K,)``
    residuals : ndarray, shape ``(K, m)``
    predicted : Estimate
        ``x_{K|K-1}``: the estimate one sample after the last measurement, with the last command.
    """

    x: np.ndarray
    P: np.ndarray
    nis: np.ndarray
    residuals: np.ndarray
    predicted: Estimate


def run_filter(km: KalmanModel, est: Estimate, commands, measurements) -> FilterRun:
    """Update with ``measurements[k]`` then predict with ``commands[k]``, for every sample ``k``."""
    u = np.asarray(commands, dtype=float).ravel()
    Y = np.atleast_2d(np.asarray(measurements, dtype=float))
    if Y.shape != (u.size, km.n_measurements):
        raise ConfigError("measurements", f"need one row of {km.n_measurements} per command ({u.size}), got {Y.shape}")
    n = km.n_states
    xs, Ps = np.empty((u.size, n)), np.empty((u.size, n, n))
    nis, res = np.empty(u.size), np.empty((u.size, km.n_measurements))
    for k in range(u.size):
        est, inn = update(km, est, Y[k])
        xs[k], Ps[k], nis[k], res[k] = est.x, est.P, inn.nis, inn.residual
        est = predict(km, est, u[k])
    return FilterRun(x=xs, P=Ps, nis=nis, residuals=res, predicted=est)


__all__ = [
    "OBSERVABILITY_RTOL",
    "Estimate",
    "FilterRun",
    "Innovation",
    "KalmanModel",
    "check_observable",
    "initial_estimate",
    "kalman_model",
    "measurement_matrix",
    "predict",
    "run_filter",
    "update",
]
