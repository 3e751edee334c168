"""Closed-form responses of the block-diagonal modal model, vectorised over time.

The planners evaluate ``e^{A tau} x``, ``e^{A tau} B``, ``int_0^tau e^{A s} B ds``
and the switching function ``nu^T e^{A tau} B`` at many times per iteration.
Each block of ``A`` is 1x1 or 2x2, so these have closed forms: evaluating them
is a handful of numpy operations instead of a matrix exponential per time.

This module is the planners' *fast* path.  Results are always checked against
:mod:`flexmotion_ros.core.simulation`, which uses matrix exponentials of the
full augmented matrix and shares no code with this module.

``tau`` is time-to-go in the planners (seconds before the final time); here it
is simply a non-negative time argument.
"""

from __future__ import annotations

import math

import numpy as np

from ..model.modal_model import ModalModel
from . import switching_bounds
from .phi_functions import phi1, phi2

__all__ = ["COEFFICIENT_MEMO", "ModalResponse", "phi1", "phi2"]

#: Switching-function coefficient sets kept per response (:meth:`ModalResponse._switching_coefficients`).
COEFFICIENT_MEMO = 8


class ModalResponse:
    """Closed-form time responses of a :class:`ModalModel`.

    Parameters
    ----------
    model : ModalModel
        The model.
    include_position : bool
        ``True``: state ``[p, v, q_1, q_1', ...]``.  ``False``: the rigid-body
        position is dropped (``[v, q_1, q_1', ...]``), for moves whose final
        position is free (bring a moving machine to rest, seed eq. 2.13).
    """

    #: :meth:`switching` takes ``rows=`` (a subset of a grid, from the grid's cached basis).
    SWITCHING_TAKES_ROWS = True

    def __init__(self, model: ModalModel, include_position: bool = True) -> None:
        self.model = model
        self.include_position = include_position
        self.r = 2 if include_position else 1  # rigid-block size
        self.n = self.r + 2 * model.n_modes
        self.b0 = model.b0
        self.c = model.c
        self.w = np.asarray(model.omega, dtype=float)
        self.sig = np.asarray(model.zeta, dtype=float) * self.w  # decay rate zeta*omega (1/s)
        self.wd = model.omega_d
        self.bm = np.asarray(model.b, dtype=float)
        self._rate = -self.sig + 1j * self.wd  # d/dtau of a mode's complex amplitude

    # -------------------------------------------------------------- matrices
    def A(self) -> np.ndarray:
        """State matrix of this (possibly reduced) state."""
        A = self.model.A()
        return A if self.include_position else A[1:, 1:]

    def B(self) -> np.ndarray:
        """Input vector of this (possibly reduced) state."""
        B = self.model.B()
        return B if self.include_position else B[1:]

    def reduce(self, x: np.ndarray) -> np.ndarray:
        """Full state -> this response's state."""
        x = np.asarray(x, dtype=float)
        return x if self.include_position else x[1:]

    # ------------------------------------------------------------- responses
    def _mode_trig(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = tau[:, None]
        E = np.exp(-self.sig * t)
        arg = self.wd * t
        return E, np.cos(arg), np.sin(arg)

    def expm_B(self, tau: np.ndarray) -> np.ndarray:
        """``e^{A tau} B`` for each ``tau``, shape ``(len(tau), n)``."""
        tau = np.atleast_1d(np.asarray(tau, dtype=float))
        out = np.empty((tau.size, self.n))
        ect = np.exp(self.c * tau)
        if self.include_position:
            out[:, 0] = self.b0 * tau * phi1(self.c * tau)
        out[:, self.r - 1] = self.b0 * ect
        if self.w.size:
            E, C, S = self._mode_trig(tau)
            s_wd = self.sig / self.wd
            out[:, self.r :: 2] = self.bm * E * S / self.wd
            out[:, self.r + 1 :: 2] = self.bm * E * (C - s_wd * S)
        return out

    def A_expm_B(self, tau: np.ndarray) -> np.ndarray:
        """``A e^{A tau} B`` (the time derivative of :meth:`expm_B`)."""
        tau = np.atleast_1d(np.asarray(tau, dtype=float))
        out = np.empty((tau.size, self.n))
        ect = np.exp(self.c * tau)
        if self.include_position:
            out[:, 0] = self.b0 * ect
        out[:, self.r - 1] = self.b0 * self.c * ect
        if self.w.size:
            E, C, S = self._mode_trig(tau)
            s_wd = self.sig / self.wd
            out[:, self.r :: 2] = self.bm * E * (C - s_wd * S)
            out[:, self.r + 1 :: 2] = self.bm * E * (-2.0 * self.sig * C + (self.sig**2 - self.wd**2) / self.wd * S)
        return out

    def input_integral(self, tau: np.ndarray) -> np.ndarray:
        """``Gamma(tau) = int_0^tau e^{A s} B ds``, shape ``(len(tau), n)``.

        The state reached from rest after a unit input held for ``tau``.
        """
        tau = np.atleast_1d(np.asarray(tau, dtype=float))
        out = np.empty((tau.size, self.n))
        if self.c == 0.0:  # phi1(0) = 1, phi2(0) = 1/2 exactly: the same numbers without the series
            if self.include_position:
                out[:, 0] = self.b0 * tau * tau * 0.5
            out[:, self.r - 1] = self.b0 * tau
        else:
            ct = self.c * tau
            if self.include_position:
                out[:, 0] = self.b0 * tau * tau * phi2(ct)
            out[:, self.r - 1] = self.b0 * tau * phi1(ct)
        if self.w.size:
            E, C, S = self._mode_trig(tau)
            t = tau[:, None]
            # 1 - E (C + sig/wd S), arranged to avoid cancellation at small tau
            half = np.sin(0.5 * self.wd * t)
            one_minus = -np.expm1(-self.sig * t) + 2.0 * E * half * half - E * (self.sig / self.wd) * S
            out[:, self.r :: 2] = self.bm * one_minus / self.w**2
            out[:, self.r + 1 :: 2] = self.bm * E * S / self.wd
        return out

    def expm_x(self, tau: float, x: np.ndarray) -> np.ndarray:
        """``e^{A tau} x`` for one time ``tau`` (s) and a state ``x``."""
        x = np.asarray(x, dtype=float)
        out = np.empty(self.n)
        ct = self.c * tau
        ect = math.exp(ct)
        if self.include_position:
            out[0] = x[0] + x[1] * tau * float(phi1(np.array([ct]))[0])
        out[self.r - 1] = x[self.r - 1] * ect
        if self.w.size:
            E, C, S = (a[0] for a in self._mode_trig(np.array([tau], dtype=float)))
            q = x[self.r :: 2]
            qd = x[self.r + 1 :: 2]
            s_wd = self.sig / self.wd
            out[self.r :: 2] = E * (q * (C + s_wd * S) + qd * S / self.wd)
            out[self.r + 1 :: 2] = E * (-q * self.w**2 / self.wd * S + qd * (C - s_wd * S))
        return out

    def expm_x_many(self, tau: np.ndarray, x: np.ndarray) -> np.ndarray:
        """``e^{A tau} x`` for many times ``tau`` (s), shape ``(len(tau), n)``."""
        tau = np.atleast_1d(np.asarray(tau, dtype=float))
        x = np.asarray(x, dtype=float)
        out = np.empty((tau.size, self.n))
        ct = self.c * tau
        if self.include_position:
            out[:, 0] = x[0] + x[1] * tau * phi1(ct)
        out[:, self.r - 1] = x[self.r - 1] * np.exp(ct)
        if self.w.size:
            E, C, S = self._mode_trig(tau)
            q = x[self.r :: 2]
            qd = x[self.r + 1 :: 2]
            s_wd = self.sig / self.wd
            out[:, self.r :: 2] = E * (q * (C + s_wd * S) + qd * S / self.wd)
            out[:, self.r + 1 :: 2] = E * (-q * self.w**2 / self.wd * S + qd * (C - s_wd * S))
        return out

    def A_x(self, x: np.ndarray) -> np.ndarray:
        """``A x`` without forming ``A``."""
        x = np.asarray(x, dtype=float)
        out = np.empty(self.n)
        if self.include_position:
            out[0] = x[1]
        out[self.r - 1] = self.c * x[self.r - 1]
        q = x[self.r :: 2]
        qd = x[self.r + 1 :: 2]
        out[self.r :: 2] = qd
        out[self.r + 1 :: 2] = -(self.w**2) * q - 2.0 * self.sig * qd
        return out

    # ---------------------------------------------------- switching function
    def _trig_basis(self, tau: np.ndarray) -> np.ndarray:
        """``[e^{-sig tau} sin(wd tau), e^{-sig tau} cos(wd tau)]`` per mode, shape ``(len, 2N)``.

        Cached by identity for read-only arrays (the planners' grids,
        :func:`~flexmotion_ros.core.time_optimal.switching.sample_grid`), the
        last two: the planners evaluate the switching function on one grid
        many times while ``T`` is fixed.  Other arrays (subsets, bisection
        midpoints) are not cached, so they cannot evict a grid's basis.
        """
        cache = self.__dict__.setdefault("_basis_cache", [])
        for key, val in cache:
            if key is tau:
                return val
        E, C, Sn = self._mode_trig(tau)
        N = self.w.size
        val = np.empty((tau.size, 2 * N))
        np.multiply(E, Sn, out=val[:, :N])
        np.multiply(E, C, out=val[:, N:])
        if tau.size >= 32 and not tau.flags.writeable:
            cache.insert(0, (tau, val))
            del cache[2:]
        return val

    def switching(
        self,
        nu: np.ndarray,
        tau: np.ndarray,
        derivative: bool = False,
        order: int | None = None,
        rows: np.ndarray | None = None,
    ):
        """``S(tau) = nu^T e^{A tau} B`` and its derivatives in ``tau``.

        ``derivative=True`` returns ``(S, S')``; ``order=k`` returns
        ``(S, S', ..., S^(k))``.  Cheaper than ``expm_B(tau) @ nu``: one
        matrix product over the modes for all orders, the rigid part's
        orders in one outer product.  ``rows``: evaluate at ``tau[rows]``
        only, from the basis of the whole of ``tau`` (cached for a planner's
        grid: many subsets of one grid share one ``exp``, ``sin``, ``cos``
        evaluation).
        """
        k = 0 if order is None else order
        if derivative and order is None:
            k = 1
        tau = tau if isinstance(tau, np.ndarray) and tau.ndim == 1 else np.atleast_1d(np.asarray(tau, dtype=float))
        basis = None
        if rows is not None:
            basis = self._trig_basis(tau)[rows] if self.w.size else None
            tau = tau[rows]
        nu = np.asarray(nu, dtype=float)
        c = self.c
        nv = nu[self.r - 1]
        out = np.empty((k + 1, tau.size))
        if c != 0.0:
            ect = np.exp(c * tau)
            lin = tau * phi1(c * tau)
        else:
            ect = None
            lin = tau
        if self.include_position:
            np_ = nu[0]
            out[0] = self.b0 * (np_ * lin + (nv * ect if ect is not None else nv))
            d1c = self.b0 * (np_ + nv * c)
        else:
            out[0] = self.b0 * nv * (ect if ect is not None else 1.0)
            d1c = self.b0 * c * nv
        if k:  # rigid part: S^(j) = c^(j-1) S'(0) e^{c tau}
            if ect is None:
                out[1] = d1c
                out[2:] = 0.0
            else:
                np.multiply.outer(d1c * c ** np.arange(k, dtype=float), ect, out=out[1:])
        if self.w.size:
            trig = basis if basis is not None else self._trig_basis(tau)
            out += (trig @ self._switching_coefficients(nu, k)).T
        return out[0] if k == 0 else tuple(out)

    def _switching_coefficients(self, nu: np.ndarray, k: int) -> np.ndarray:
        """The modes' coefficients of ``S, S', ..., S^(k)`` on the basis ``[E sin, E cos]``, shape ``(2N, k + 1)``.

        ``S_i = E (a_i sin + b_i cos)``; ``d/dtau`` maps ``(a, b) -> (-(a sig + b wd), a wd - b sig)``,
        i.e. ``a + i b`` times ``lambda = -sig + i wd``: the orders are one running complex product
        (the same multiplications, in the same order, as the real recursion).  Up to
        :data:`COEFFICIENT_MEMO` are kept by the bytes of ``nu`` (a certificate evaluates one
        co-state's ``S`` about ten times).
        """
        memo = self.__dict__.setdefault("_coef_memo", {})
        key = (nu.tobytes(), k)
        coef = memo.get(key)
        if coef is not None:
            return coef
        a = nu[self.r :: 2] * self.bm / self.wd - nu[self.r + 1 :: 2] * self.bm * self.sig / self.wd
        bb = nu[self.r + 1 :: 2] * self.bm
        if k:
            z = np.empty((self.w.size, k + 1), dtype=complex)
            z[:, 0] = a + 1j * bb
            z[:, 1:] = self._rate[:, None]
            z = np.multiply.accumulate(z, axis=1)
            coef = np.concatenate([z.real, z.imag])
        else:
            coef = np.concatenate([a, bb])[:, None]
        coef.flags.writeable = False
        if len(memo) >= COEFFICIENT_MEMO:
            memo.clear()  # atomic: no iteration over a dict another thread may be filling
        memo[key] = coef
        return coef

    def switching_terms(self, nu: np.ndarray, k: int) -> tuple:
        """The switching function's closed form as the compiled kernels take it (:mod:`...kernels.roots`).

        ``(b0, c, nu_p, nu_v, has_position, sig, wd, coef)``: the rigid part
        ``b0 (nu_p tau phi1(c tau) + nu_v e^{c tau})`` (``nu_p = 0`` and
        ``has_position`` False for a free final position), the modes' decay
        rates (1/s) and damped frequencies (rad/s), and the coefficients of
        ``S, ..., S^(k)`` on ``[e^{-sig tau} sin, e^{-sig tau} cos]``, shape ``(2N, k + 1)``.
        """
        nu = np.asarray(nu, dtype=float)
        if self.w.size:
            coef = self._switching_coefficients(nu, k)  # read-only, C-ordered (memoised)
        else:
            coef = np.zeros((0, k + 1))
            coef.flags.writeable = False  # one type for the compiled kernels: read-only, as the memoised ones
        return (
            float(self.b0),
            float(self.c),
            float(nu[0]) if self.include_position else 0.0,
            float(nu[self.r - 1]),
            bool(self.include_position),
            np.ascontiguousarray(self.sig, dtype=float),
            np.ascontiguousarray(self.wd, dtype=float),
            coef,
        )

    def switching_derivative_bound_terms(self, nu: np.ndarray, order: int) -> tuple[float, np.ndarray]:
        """The terms of :meth:`switching_derivative_bound_from` (:func:`.switching_bounds.derivative_bound_terms`)."""
        return switching_bounds.derivative_bound_terms(self, nu, order)

    # ------------------------------------------- proved bounds on the switching function
    def switching_magnitude(self, nu: np.ndarray, tau_max: float) -> tuple[float, float]:
        """Sums of the magnitudes of the terms of ``S`` and ``S'`` on ``[0, tau_max]`` (its rounding unit).

        :func:`.switching_bounds.switching_magnitude`.
        """
        return switching_bounds.switching_magnitude(self, nu, tau_max)

    def switching_derivative_bound(self, nu: np.ndarray, order: int) -> float:
        """Upper bound on ``|d^order S / dtau^order|`` over ``tau >= 0`` (``order >= 1``).

        :func:`.switching_bounds.switching_derivative_bound`.
        """
        return switching_bounds.switching_derivative_bound(self, nu, order)

    def switching_derivative_bound_from(self, nu: np.ndarray, order: int, tau: np.ndarray) -> np.ndarray:
        """Upper bound on ``|d^order S / dtau^order|`` over ``[tau, inf)``, for each ``tau``.

        :func:`.switching_bounds.switching_derivative_bound_from`.
        """
        return switching_bounds.switching_derivative_bound_from(self, nu, order, tau)

    def switching_zero_free(self, nu: np.ndarray, a: np.ndarray, b: np.ndarray, margin: float) -> np.ndarray:
        """Which intervals ``[a, b]`` are proved to hold no zero of ``S`` (bool per interval).

        :func:`.switching_bounds.switching_zero_free`.
        """
        return switching_bounds.switching_zero_free(self, nu, a, b, margin)

    def switching_derivative_bounds(self, nu: np.ndarray, tau_max: float) -> tuple[float, float]:
        """Upper bounds on ``|S'|`` and ``|S''|`` over ``[0, tau_max]``.

        :func:`.switching_bounds.switching_derivative_bounds`.
        """
        return switching_bounds.switching_derivative_bounds(self, nu, tau_max)
