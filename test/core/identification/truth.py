"""Hidden-truth data for the identification tests, computed independently of the estimator.

The estimator runs each block as a discrete transfer function (``lfilter``);
here the *whole* model is propagated state by state with one matrix
exponential of the full augmented matrix, and the sensor is read from the
state (acceleration from ``A x + B u``).  The Cramer-Rao bound comes from
central finite differences of this simulator, not from the estimator's
Jacobian.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from flexmotion_ros.core.model.builders import chain, crane, two_mass
from flexmotion_ros.core.model.modal_model import ModalModel


def simulate_output(model: ModalModel, a0: float, a, u, dt: float, kind: str = "position") -> np.ndarray:
    """Sensor ``a0 p + sum a_i q_i`` (or its velocity / acceleration) at ``t_k``, after ``u_k`` is applied."""
    A, B = model.A(), model.B()
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n] = A
    M[:n, n] = B
    E = expm(M * dt)
    Phi, Gam = E[:n, :n], E[:n, n]
    u = np.asarray(u, dtype=float)
    X = np.empty((u.size, n))
    x = np.zeros(n)
    for k, uk in enumerate(u):
        X[k] = x
        x = Phi @ x + Gam * uk
    cp = np.zeros(n)
    cp[0] = a0
    cp[2::2] = a
    cv = np.zeros(n)
    cv[1] = a0
    cv[3::2] = a
    if kind == "position":
        return X @ cp
    if kind == "velocity":
        return X @ cv
    return (X @ A.T + np.outer(u, B)) @ cv


def theta_of(model: ModalModel, a0: float, a, offset: float = 0.0) -> np.ndarray:
    """The identifiable parameters ``(c, omega_i, zeta_i, b0, a_i b_i, offset)``."""
    nl = [model.c]
    for w, z in zip(model.omega, model.zeta):
        nl += [w, z]
    return np.array([*nl, model.b0, *(np.asarray(a) * np.asarray(model.b)), offset])


def output_of_theta(theta, a0: float, u, dt: float, kind: str) -> np.ndarray:
    """Sensor output for identifiable parameters (``b_i = a_i b_i``, weights 1)."""
    n = (len(theta) - 3) // 3
    c = theta[0]
    omega = theta[1 : 1 + 2 * n : 2]
    zeta = theta[2 : 2 + 2 * n : 2]
    b0 = theta[1 + 2 * n]
    g = theta[2 + 2 * n : 2 + 3 * n]
    # any valid ModalModel: zeta may leave [0, 1) by a finite-difference step, so build A, B directly
    m = ModalModel(b0=b0, c=min(c, 0.0), omega=tuple(omega), zeta=tuple(np.clip(zeta, 0.0, 0.99)), b=tuple(g))
    A = m.A()
    A[1, 1] = c
    for i, (w, z) in enumerate(zip(omega, zeta)):
        A[3 + 2 * i, 3 + 2 * i] = -2.0 * z * w
    model = _Raw(A, m.B())
    return simulate_output(model, a0, np.ones(n), u, dt, kind) + theta[-1]


class _Raw:
    """``A, B`` without ModalModel's checks (finite-difference steps may leave its ranges)."""

    def __init__(self, A, B):
        self._A, self._B = A, B

    def A(self):
        return self._A

    def B(self):
        return self._B


def crb(theta, a0: float, u, dt: float, kind: str, sigma: float) -> np.ndarray:
    """Cramer-Rao bound (covariance) of ``theta`` under white noise ``sigma``, by central differences."""
    theta = np.asarray(theta, dtype=float)
    cols = []
    for j in range(theta.size):
        h = 1e-6 * max(abs(theta[j]), 1e-3)
        tp, tm = theta.copy(), theta.copy()
        tp[j] += h
        tm[j] -= h
        cols.append((output_of_theta(tp, a0, u, dt, kind) - output_of_theta(tm, a0, u, dt, kind)) / (2 * h))
    J = np.column_stack(cols)
    return sigma**2 * np.linalg.inv(J.T @ J)


def prbs(n: int, hold: int, seed: int) -> np.ndarray:
    """A +-1 pseudo-random binary sequence held for ``hold`` samples."""
    rng = np.random.default_rng(seed)
    return np.repeat(rng.choice([-1.0, 1.0], int(np.ceil(n / hold))), hold)[:n]


def noise_for_snr(y: np.ndarray, snr_db: float) -> float:
    """Noise standard deviation for a signal-to-noise ratio (rms of the signal's variation over the noise)."""
    return float(np.std(y)) / 10 ** (snr_db / 20.0)


# ---------------------------------------------------------------- the three machines of the issue
def two_mass_case(n: int = 1500, dt: float = 0.02):
    """Two masses (m1 = m2 = 1 kg, k = 1 N/m, d = 0.05 N s/m); encoder on mass 2 (non-collocated);
    a 1 N move out and back, then its ringdown."""
    built = two_mass(1.0, 1.0, 1.0, 0.05)
    u = np.zeros(n)
    q = n // 8
    u[:q], u[q : 2 * q] = 1.0, -1.0
    return built.model, 1.0, built.modal_to_physical[1, 1:], u, dt, "position"


def crane_case(n: int = 2000, dt: float = 0.02):
    """Crane (20 kg cart, 5 kg payload, 2 m cable, swing damping 0.01) with viscous drag on the
    rigid body (c = -0.05 1/s); encoder on the cart; two moves and their ringdown."""
    built = crane(20.0, 5.0, 2.0, zeta=0.01)
    model = built.model.with_changes(c=-0.05)
    u = np.zeros(n)
    s = int(0.6 / dt)
    u[:s], u[s : 2 * s] = 50.0, -50.0
    u[5 * s : 5 * s + s // 2], u[5 * s + s // 2 : 6 * s] = -50.0, 50.0
    return model, 1.0, built.modal_to_physical[0, 1:], u, dt, "position"


def beam_case(n: int = 3000, dt: float = 0.001, seed: int = 7):
    """Lumped beam (4 x 0.5 kg, 400 N/m, 0.4 N s/m; modes 21.6, 40.0, 52.3 rad/s), force on the first
    mass, accelerometer at the tip; a 10 N PRBS (20 ms hold) then ringdown."""
    built = chain([0.5] * 4, [400.0] * 3, [0.4] * 3, 0)
    u = 10.0 * prbs(n, 20, seed)
    u[n // 2 :] = 0.0
    return built.model, 1.0, built.modal_to_physical[3, 1:], u, dt, "acceleration"
