"""Closed-form responses of the multi-input modal model, vectorised over time.

``A`` is block diagonal (a 2x2 or, with a free final position, 1x1 block
per rigid body; a 2x2 block per mode), so ``e^{A tau} x``,
``e^{A tau} B``, ``int_0^tau e^{A s} B ds`` and the switching functions
``S_i(tau) = nu^T e^{A tau} B_i`` have closed forms.  Each mode contributes
``Re(alpha e^{lambda tau})`` to ``S_i`` (``lambda = -sigma + i omega_d``), so
every derivative is as cheap as ``S_i`` itself.

This is the planners' fast path; every result is checked against
:mod:`.exact` (matrix exponentials of the full augmented matrix, no shared
formulas).  :class:`InputSwitching` presents one input's switching function
with the interface of :class:`~flexmotion_ros.core.simulation.modal_response.ModalResponse`,
so that the proved root isolation of
:func:`~flexmotion_ros.core.time_optimal.switching.isolate_roots` applies unchanged.
"""

from __future__ import annotations

import math

import numpy as np


def phi1(z: np.ndarray) -> np.ndarray:
    """``(e^z - 1) / z`` (1 at 0)."""
    z = np.asarray(z, dtype=float)
    if not z.any():  # c = 0: the common case, no division
        return np.ones_like(z)
    big = np.abs(z) >= 1e-8
    safe = np.where(big, z, 1.0)
    return np.where(big, np.expm1(z) / safe, 1.0 + 0.5 * z + z * z / 6.0)


def phi2(z: np.ndarray) -> np.ndarray:
    """``(e^z - 1 - z) / z^2`` (1/2 at 0; Taylor series below ``|z| = 0.1``)."""
    z = np.asarray(z, dtype=float)
    if not z.any():
        return np.full_like(z, 0.5)
    big = np.abs(z) >= 0.1
    safe = np.where(big, z, 1.0)
    acc = np.zeros_like(z)
    for k in range(9, -1, -1):
        acc = acc * z + 1.0 / math.factorial(k + 2)
    return np.where(big, (np.expm1(safe) - safe) / (safe * safe), acc)


class MultiResponse:
    """Closed-form responses of a move's (shifted, reduced) multi-input system.

    Parameters
    ----------
    problem : :class:`~flexmotion_ros.core.multi_input.problem.MultiMoveProblem`
        Rigid bodies with a free final position lose their position state.
    """

    def __init__(self, problem) -> None:  # a MultiMoveProblem (not imported: this module is a leaf)
        model = problem.model
        self.model = model
        self.m = model.m
        has_pos = np.array(problem.has_position, dtype=bool)
        # reduced state layout
        p_idx, v_idx = [], []
        i = 0
        for j in range(model.k):
            if has_pos[j]:
                p_idx.append(i)
                i += 1
            else:
                p_idx.append(-1)
            v_idx.append(i)
            i += 1
        self.r = i
        self.has_pos = has_pos
        self.p_idx = np.array(p_idx, dtype=int)
        self.v_idx = np.array(v_idx, dtype=int)
        self.q_idx = self.r + 2 * np.arange(model.n_modes)
        self.qd_idx = self.q_idx + 1
        self.n = self.r + 2 * model.n_modes
        self.c = np.asarray(model.c, dtype=float)
        self.B0 = model.B0  # (k, m)
        self.Bm = model.Bm  # (N, m)
        self.w = np.asarray(model.omega, dtype=float)
        self.sig = np.asarray(model.zeta, dtype=float) * self.w
        self.wd = model.omega_d
        self.lam = -self.sig + 1j * self.wd
        self._coef_key: bytes | None = None
        self._coef_val: tuple = ()

    # -------------------------------------------------------------- matrices
    def A(self) -> np.ndarray:
        """State matrix of the reduced state."""
        A = np.zeros((self.n, self.n))
        for j in range(self.c.size):
            if self.has_pos[j]:
                A[self.p_idx[j], self.v_idx[j]] = 1.0
            A[self.v_idx[j], self.v_idx[j]] = self.c[j]
        A[self.q_idx, self.qd_idx] = 1.0
        A[self.qd_idx, self.q_idx] = -(self.w**2)
        A[self.qd_idx, self.qd_idx] = -2.0 * self.sig
        return A

    def B(self) -> np.ndarray:
        """Input matrix of the reduced state, ``(n, m)``."""
        B = np.zeros((self.n, self.m))
        B[self.v_idx] = self.B0
        B[self.qd_idx] = self.Bm
        return B

    # ------------------------------------------------------------- responses
    def _trig(self, tau: np.ndarray):
        t = tau[:, None]
        E = np.exp(-self.sig * t)
        return E, np.cos(self.wd * t), np.sin(self.wd * t)

    def expm_B(self, tau) -> np.ndarray:
        """``e^{A tau} B`` for each ``tau``: shape ``(len(tau), n, m)``."""
        tau = np.atleast_1d(np.asarray(tau, dtype=float))
        out = np.zeros((tau.size, self.n, self.m))
        ct = tau[:, None] * self.c
        hp = self.has_pos
        if hp.any():
            out[:, self.p_idx[hp], :] = (tau[:, None] * phi1(ct))[:, hp, None] * self.B0[hp]
        out[:, self.v_idx, :] = np.exp(ct)[:, :, None] * self.B0
        if self.w.size:
            E, C, S = self._trig(tau)
            out[:, self.q_idx, :] = (E * S / self.wd)[:, :, None] * self.Bm
            out[:, self.qd_idx, :] = (E * (C - self.sig / self.wd * S))[:, :, None] * self.Bm
        return out

    def input_integral(self, tau) -> np.ndarray:
        """``Gamma(tau) = int_0^tau e^{A s} B ds``: shape ``(len(tau), n, m)``."""
        tau = np.atleast_1d(np.asarray(tau, dtype=float))
        out = np.zeros((tau.size, self.n, self.m))
        ct = tau[:, None] * self.c
        hp = self.has_pos
        if hp.any():
            out[:, self.p_idx[hp], :] = ((tau * tau)[:, None] * phi2(ct))[:, hp, None] * self.B0[hp]
        out[:, self.v_idx, :] = (tau[:, None] * phi1(ct))[:, :, None] * self.B0
        if self.w.size:
            E, C, S = self._trig(tau)
            t = tau[:, None]
            half = np.sin(0.5 * self.wd * t)
            one_minus = -np.expm1(-self.sig * t) + 2.0 * E * half * half - E * (self.sig / self.wd) * S
            out[:, self.q_idx, :] = (one_minus / self.w**2)[:, :, None] * self.Bm
            out[:, self.qd_idx, :] = (E * S / self.wd)[:, :, None] * self.Bm
        return out

    def expm_B_cols(self, tau, cols) -> np.ndarray:
        """``e^{A tau_j} B_{cols[j]}``: one input column per time, shape ``(len(tau), n)``."""
        tau = np.atleast_1d(np.asarray(tau, dtype=float))
        cols = np.asarray(cols, dtype=int)
        out = np.zeros((tau.size, self.n))
        ct = tau[:, None] * self.c
        b0 = self.B0[:, cols].T  # (L, k)
        hp = self.has_pos
        if hp.any():
            out[:, self.p_idx[hp]] = (tau[:, None] * phi1(ct))[:, hp] * b0[:, hp]
        out[:, self.v_idx] = np.exp(ct) * b0
        if self.w.size:
            E, C, S = self._trig(tau)
            bm = self.Bm[:, cols].T  # (L, N)
            out[:, self.q_idx] = E * S / self.wd * bm
            out[:, self.qd_idx] = E * (C - self.sig / self.wd * S) * bm
        return out

    def input_integral_cols(self, tau, cols) -> np.ndarray:
        """``Gamma_{cols[j]}(tau_j)``: one input column per time, shape ``(len(tau), n)``."""
        tau = np.atleast_1d(np.asarray(tau, dtype=float))
        cols = np.asarray(cols, dtype=int)
        out = np.zeros((tau.size, self.n))
        ct = tau[:, None] * self.c
        b0 = self.B0[:, cols].T
        hp = self.has_pos
        if hp.any():
            out[:, self.p_idx[hp]] = ((tau * tau)[:, None] * phi2(ct))[:, hp] * b0[:, hp]
        out[:, self.v_idx] = tau[:, None] * phi1(ct) * b0
        if self.w.size:
            E, C, S = self._trig(tau)
            t = tau[:, None]
            half = np.sin(0.5 * self.wd * t)
            one_minus = -np.expm1(-self.sig * t) + 2.0 * E * half * half - E * (self.sig / self.wd) * S
            bm = self.Bm[:, cols].T
            out[:, self.q_idx] = one_minus / self.w**2 * bm
            out[:, self.qd_idx] = E * S / self.wd * bm
        return out

    def expm_x_many(self, tau, x: np.ndarray) -> np.ndarray:
        """``e^{A tau} x`` for many ``tau``: shape ``(len(tau), n)``."""
        tau = np.atleast_1d(np.asarray(tau, dtype=float))
        x = np.asarray(x, dtype=float)
        out = np.empty((tau.size, self.n))
        ct = tau[:, None] * self.c
        v = x[self.v_idx]
        hp = self.has_pos
        if hp.any():
            out[:, self.p_idx[hp]] = x[self.p_idx[hp]] + (v * tau[:, None] * phi1(ct))[:, hp]
        out[:, self.v_idx] = v * np.exp(ct)
        if self.w.size:
            E, C, S = self._trig(tau)
            q, qd = x[self.q_idx], x[self.qd_idx]
            s_wd = self.sig / self.wd
            out[:, self.q_idx] = E * (q * (C + s_wd * S) + qd * S / self.wd)
            out[:, self.qd_idx] = E * (-q * self.w**2 / self.wd * S + qd * (C - s_wd * S))
        return out

    def expm_x(self, tau: float, x: np.ndarray) -> np.ndarray:
        """``e^{A tau} x`` for one ``tau`` (s)."""
        return self.expm_x_many(np.array([float(tau)]), x)[0]

    def A_x(self, x: np.ndarray) -> np.ndarray:
        """``A x`` without forming ``A``."""
        x = np.asarray(x, dtype=float)
        out = np.empty(self.n)
        hp = self.has_pos
        out[self.p_idx[hp]] = x[self.v_idx[hp]]
        out[self.v_idx] = self.c * x[self.v_idx]
        out[self.q_idx] = x[self.qd_idx]
        out[self.qd_idx] = -(self.w**2) * x[self.q_idx] - 2.0 * self.sig * x[self.qd_idx]
        return out

    # ---------------------------------------------------- switching functions
    def coefficients(self, nu: np.ndarray):
        """Per input: rigid coefficients and modal complex amplitudes of ``S_i = nu^T e^{A tau} B_i``.

        Returns ``(rp, rv, alpha)``: ``S_i(tau) = sum_j rp[j, i] tau phi1(c_j tau)
        + rv[j, i] e^{c_j tau} + sum_l Re(alpha[l, i] e^{lambda_l tau})``.
        """
        nu = np.asarray(nu, dtype=float)
        key = nu.tobytes()
        if key == self._coef_key:  # root isolation evaluates one co-state many times
            return self._coef_val
        npos = np.where(self.has_pos, nu[np.maximum(self.p_idx, 0)], 0.0)
        rp = npos[:, None] * self.B0
        rv = nu[self.v_idx][:, None] * self.B0
        nq, nqd = nu[self.q_idx], nu[self.qd_idx]
        alpha = (
            (nqd - 1j * (nq - self.sig * nqd) / self.wd)[:, None] * self.Bm if self.w.size else np.zeros((0, self.m))
        )
        self._coef_key, self._coef_val = key, (rp, rv, alpha)
        return rp, rv, alpha

    def switching_all(self, nu: np.ndarray, tau, order: int = 0) -> np.ndarray:
        """``S_i^{(d)}(tau)`` for ``d = 0..order``: shape ``(order + 1, m, len(tau))``."""
        tau = np.atleast_1d(np.asarray(tau, dtype=float))
        rp, rv, alpha = self.coefficients(nu)
        out = np.zeros((order + 1, self.m, tau.size))
        if self.c.size and not self.c.any():  # no viscous term: the rigid part is linear in tau
            slope = rp.sum(axis=0)
            out[0] += slope[:, None] * tau[None, :] + rv.sum(axis=0)[:, None]
            if order >= 1:
                out[1] += slope[:, None]
        elif self.c.size:
            ect = np.exp(np.outer(self.c, tau))  # (k, L)
            lin = tau[None, :] * phi1(np.outer(self.c, tau))
            out[0] += rp.T @ lin + rv.T @ ect
            d1 = rp + self.c[:, None] * rv  # (k, m)
            for d in range(1, order + 1):
                out[d] += (d1 * (self.c[:, None] ** (d - 1))).T @ ect
        if self.w.size:
            el = np.exp(np.outer(self.lam, tau))  # (N, L)
            a = alpha
            for d in range(order + 1):
                out[d] += (a.T @ el).real
                a = a * self.lam[:, None]
        return out

    def magnitude(self, nu: np.ndarray, T: float) -> np.ndarray:
        """Per input: sum of the magnitudes of the terms of ``S_i`` on ``[0, T]`` (rounding scale)."""
        rp, rv, alpha = self.coefficients(nu)
        m0 = np.abs(rp).sum(axis=0) * T + np.abs(rv).sum(axis=0) + np.abs(alpha).sum(axis=0)
        return np.asarray(m0, dtype=float)

    def derivative_bound_from(self, nu: np.ndarray, order: int, tau: np.ndarray, i: int) -> np.ndarray:
        """Upper bound on ``|S_i^{(order)}|`` over ``[tau, inf)`` for each ``tau`` (``order >= 1``)."""
        rp, rv, alpha = self.coefficients(nu)
        tau = np.asarray(tau, dtype=float)
        out = np.zeros(tau.shape)
        if self.c.size:
            d1 = np.abs(rp[:, i] + self.c * rv[:, i]) * np.abs(self.c) ** (order - 1)
            out = out + np.exp(np.outer(tau, self.c)) @ d1
        if self.w.size:
            amp = np.abs(alpha[:, i]) * np.abs(self.lam) ** order
            out = out + np.exp(-np.outer(tau, self.sig)) @ amp
        return out

    def for_input(self, i: int) -> InputSwitching:
        """Input ``i``'s switching function with the single-input interface."""
        return InputSwitching(self, i)


class InputSwitching:
    """One input's switching function, with the interface root isolation needs.

    ``switching(nu, tau, derivative=..., order=...)``, ``switching_magnitude``,
    ``switching_derivative_bound(_from)`` and ``wd`` as
    :class:`~flexmotion_ros.core.simulation.modal_response.ModalResponse` has them.
    """

    def __init__(self, response: MultiResponse, i: int) -> None:
        self.response = response
        self.i = i
        self.wd = response.wd
        self.n = response.n

    def switching(self, nu, tau, derivative: bool = False, order: int | None = None):
        k = 0 if order is None else order
        if derivative and order is None:
            k = 1
        D = self.response.switching_all(nu, tau, k)[:, self.i, :]
        return D[0] if k == 0 else tuple(D)

    def switching_magnitude(self, nu, tau_max: float) -> tuple[float, float]:
        m0 = float(self.response.magnitude(nu, tau_max)[self.i])
        return m0, m0 * float(np.max(np.abs(self.response.lam), initial=1.0))

    def switching_derivative_bound_from(self, nu, order: int, tau) -> np.ndarray:
        return self.response.derivative_bound_from(nu, order, tau, self.i)

    def switching_derivative_bound(self, nu, order: int) -> float:
        return float(self.response.derivative_bound_from(nu, order, np.zeros(1), self.i)[0])
