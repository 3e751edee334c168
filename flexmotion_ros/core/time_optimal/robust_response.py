"""The model augmented with frequency derivatives of its modes, in closed form (robust time-optimal moves).

The residual state of mode ``i`` depends on its frequency ``omega_i``.
Requiring it *and* its derivatives ``d^j/domega_i^j`` (``j <= k``, damping
ratio fixed) to vanish at the end flattens the residual vibration around the
nominal frequency, as ZVD does for shapers (Liu & Wie 1992; Singh & Vadali
1993).  The derivatives obey a linear system too: with ``z_j = d^j x_i /
domega^j``::

    z_j' = A_i z_j + j A_i' z_{j-1} + C(j, 2) A_i'' z_{j-2} + [j = 0] B_i u

(``A_i' = dA_i/domega = [[0, 0], [-2 omega, -2 zeta]]``,
``A_i'' = [[0, 0], [-2, 0]]``): each mode becomes a Jordan-type block of size
``2 (k + 1)`` with its eigenvalues repeated ``k + 1`` times.  The robust move
is the time-optimal move of this augmented system to its origin: bang-bang,
more switches, longer, far less sensitive.  It is solved by the core's
:func:`~flexmotion_ros.core.time_optimal.solve_bang_bang`, checked by the
matrix-exponential simulation of the augmented system and certified by
Pontryagin's conditions (:func:`~flexmotion_ros.core.certificate.certify`).

Closed forms
------------
With ``zeta`` fixed, a mode's eigenvalue is ``lambda = mu omega``,
``mu = -zeta + i sqrt(1 - zeta^2)``, so every entry of the mode's closed forms
in :mod:`.modal_response` is ``Re(c omega^q e^{mu omega tau})`` and
``d^j/domega^j (omega^q e^{mu omega tau}) = e^{mu omega tau} sum_l C(j,l)
q^(l) omega^(q-l) (mu tau)^(j-l)`` (``q^(l)`` the falling factorial): the
derivative blocks are exponentials times polynomials in ``tau``.

The planner is :mod:`.robust`.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError, SolverError
from ..model.modal_model import ModalModel
from ..simulation.modal_response import ModalResponse

#: Largest derivative order accepted.
MAX_ORDER = 4


def _ff(q: float, l: int) -> float:
    """Falling factorial ``q (q-1) ... (q-l+1)``."""
    out = 1.0
    for i in range(l):
        out *= q - i
    return out


def check_order(value) -> int:
    """Validate ``robust_order`` (integer ``0..MAX_ORDER``)."""
    msg = f"must be an integer in [0, {MAX_ORDER}], got {value!r}"
    if isinstance(value, bool):
        raise InputError("robust_order", msg)
    try:
        f = float(value)
    except (TypeError, ValueError):
        raise InputError("robust_order", msg) from None
    if not (math.isfinite(f) and f.is_integer() and 0 <= f <= MAX_ORDER):
        raise InputError("robust_order", msg)
    return int(f)


class RobustModalResponse:
    """Closed-form responses of the model augmented with frequency derivatives (``ModalResponse`` interface).

    State: ``[rigid (p, v) or (v) | mode 1: z_0, ..., z_k | mode 2: ...]``,
    ``z_j = (d^j q / domega^j, d^j q' / domega^j)``.

    Parameters
    ----------
    model : ModalModel
    order : int
        Highest derivative ``k`` (0: the plain model).
    include_position : bool
        As for :class:`ModalResponse`.
    horizon : float, optional
        Longest time-to-go (s) at which derivative bounds must hold (the
        polynomial factors grow with ``tau``); set before solving/certifying.
    """

    def __init__(
        self, model: ModalModel, order: int = 1, include_position: bool = True, horizon: float | None = None
    ) -> None:
        self.model = model
        self.order = check_order(order)
        self.include_position = include_position
        self.rigid = ModalResponse(model.with_changes(omega=(), zeta=(), b=(), names=()), include_position)
        self.r = self.rigid.n
        self.N = model.n_modes
        self.block = 2 * (self.order + 1)
        self.n = self.r + self.N * self.block
        self.w = np.asarray(model.omega, dtype=float)
        self.z = np.asarray(model.zeta, dtype=float)
        self.s = np.sqrt(1.0 - self.z**2)
        self.mu = -self.z + 1j * self.s
        self.bm = np.asarray(model.b, dtype=float)
        self.cq = -1j * self.bm / self.s  # q(tau) of e^{A tau}B = Re(cq omega^-1 e^{mu omega tau})
        self.wd = model.omega_d
        self.horizon = horizon
        self._A, self._B = self._matrices()
        self._maps: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        #: Switching-function work spent (points x orders x modes) and the bound on it (None: none).
        self.work = 0
        self.work_budget: float | None = None
        self._last_coeffs: dict[tuple[int, bytes], np.ndarray] = {}

    # ------------------------------------------------------------ structure
    def q_index(self, mode: int, j: int) -> int:
        """Index of ``d^j q_mode / domega^j`` in the state (``+1``: its velocity)."""
        return self.r + mode * self.block + 2 * j

    def _matrices(self) -> tuple[np.ndarray, np.ndarray]:
        A = np.zeros((self.n, self.n))
        B = np.zeros(self.n)
        A[: self.r, : self.r] = self.rigid.A()
        B[: self.r] = self.rigid.B()
        for i, (w, z) in enumerate(zip(self.w, self.z)):
            A0 = np.array([[0.0, 1.0], [-w * w, -2.0 * z * w]])
            A1 = np.array([[0.0, 0.0], [-2.0 * w, -2.0 * z]])
            A2 = np.array([[0.0, 0.0], [-2.0, 0.0]])
            for j in range(self.order + 1):
                a = self.q_index(i, j)
                A[a : a + 2, a : a + 2] = A0
                if j >= 1:
                    A[a : a + 2, a - 2 : a] = j * A1
                if j >= 2:
                    A[a : a + 2, a - 4 : a - 2] = math.comb(j, 2) * A2
            B[self.q_index(i, 0) + 1] = self.bm[i]
        return A, B

    def A(self) -> np.ndarray:
        """Augmented state matrix."""
        return self._A.copy()

    def B(self) -> np.ndarray:
        """Augmented input vector."""
        return self._B.copy()

    def augment(self, x: np.ndarray) -> np.ndarray:
        """A model state (as :class:`ModalResponse` orders it) -> augmented state (derivatives 0)."""
        x = np.asarray(x, dtype=float)
        out = np.zeros(self.n)
        out[: self.r] = x[: self.r]
        for i in range(self.N):
            a = self.q_index(i, 0)
            out[a : a + 2] = x[self.r + 2 * i : self.r + 2 * i + 2]
        return out

    def nominal_part(self, xa: np.ndarray) -> np.ndarray:
        """Augmented state(s) -> the model's state(s) (drop the derivatives)."""
        xa = np.asarray(xa, dtype=float)
        idx = list(range(self.r))
        for i in range(self.N):
            a = self.q_index(i, 0)
            idx += [a, a + 1]
        return xa[..., idx]

    # --------------------------------------------------------- closed forms
    def _D(self, q: float, tau: np.ndarray, E: np.ndarray) -> list[np.ndarray]:
        """``d^j/domega^j (omega^q e^{mu omega tau})``, ``j = 0..order``; each ``(len(tau), N)``."""
        mt = self.mu * tau[:, None]
        out = []
        for j in range(self.order + 1):
            acc = np.zeros_like(E)
            for l in range(j + 1):
                acc = acc + math.comb(j, l) * _ff(q, l) * self.w ** (q - l) * mt ** (j - l)
            out.append(E * acc)
        return out

    def _E(self, tau: np.ndarray) -> np.ndarray:
        return np.exp(self.mu * self.w * tau[:, None])

    def _fill(self, out: np.ndarray, qpart: list, qdpart: list) -> None:
        for j in range(self.order + 1):
            cols = self.r + np.arange(self.N) * self.block + 2 * j
            out[:, cols] = qpart[j].real
            out[:, cols + 1] = qdpart[j].real

    def expm_B(self, tau) -> np.ndarray:
        """``e^{A tau} B``, shape ``(len(tau), n)``."""
        tau = np.atleast_1d(np.asarray(tau, dtype=float))
        out = np.empty((tau.size, self.n))
        out[:, : self.r] = self.rigid.expm_B(tau)
        if self.N:
            E = self._E(tau)
            self._fill(
                out, [self.cq * d for d in self._D(-1, tau, E)], [self.cq * self.mu * d for d in self._D(0, tau, E)]
            )
        return out

    def A_expm_B(self, tau) -> np.ndarray:
        """``A e^{A tau} B``."""
        tau = np.atleast_1d(np.asarray(tau, dtype=float))
        out = np.empty((tau.size, self.n))
        out[:, : self.r] = self.rigid.A_expm_B(tau)
        if self.N:
            E = self._E(tau)
            c1, c2 = self.cq * self.mu, self.cq * self.mu**2
            self._fill(out, [c1 * d for d in self._D(0, tau, E)], [c2 * d for d in self._D(1, tau, E)])
        return out

    def input_integral(self, tau) -> np.ndarray:
        """``int_0^tau e^{A s} B ds``, shape ``(len(tau), n)``."""
        tau = np.atleast_1d(np.asarray(tau, dtype=float))
        out = np.empty((tau.size, self.n))
        out[:, : self.r] = self.rigid.input_integral(tau)
        if self.N:
            E = self._E(tau)
            mt = self.mu * tau[:, None]
            H = [np.expm1(mt * self.w)] + [mt**i * E for i in range(1, self.order + 1)]
            qpart = []
            for j in range(self.order + 1):
                acc = np.zeros_like(E)
                for l in range(j + 1):  # d^j (omega^-2 (e^{mu omega tau} - 1))
                    acc = acc + math.comb(j, l) * _ff(-2.0, l) * self.w ** (-2.0 - l) * H[j - l]
                qpart.append(self.cq / self.mu * acc)
            qd = [self.cq * d for d in self._D(-1, tau, E)]
            self._fill(out, qpart, qd)
        return out

    def expm_x_many(self, tau, x) -> np.ndarray:
        """``e^{A tau} x`` for many ``tau``, shape ``(len(tau), n)``."""
        tau = np.atleast_1d(np.asarray(tau, dtype=float))
        x = np.asarray(x, dtype=float)
        out = np.empty((tau.size, self.n))
        out[:, : self.r] = self.rigid.expm_x_many(tau, x[: self.r])
        if self.N:
            E = self._E(tau)
            Dm, D0, D1 = self._D(-1, tau, E), self._D(0, tau, E), self._D(1, tau, E)
            k = self.order
            qs = [np.zeros((tau.size, self.N), dtype=complex) for _ in range(k + 1)]
            qds = [np.zeros((tau.size, self.N), dtype=complex) for _ in range(k + 1)]
            zr = self.z / self.s
            for l in range(k + 1):
                cols = self.r + np.arange(self.N) * self.block + 2 * l
                c1 = x[cols] * (1.0 - 1j * zr)  # q(tau) = Re(c1 e + c2 omega^-1 e)
                c2 = -1j * x[cols + 1] / self.s
                for j in range(l, k + 1):  # z_j(tau) = sum_l C(j,l) d^{j-l}E z_l(0)
                    d = j - l
                    cj = math.comb(j, l)
                    qs[j] += cj * (c1 * D0[d] + c2 * Dm[d])
                    qds[j] += cj * self.mu * (c1 * D1[d] + c2 * D0[d])
            self._fill(out, qs, qds)
        return out

    def expm_x(self, tau: float, x) -> np.ndarray:
        """``e^{A tau} x`` for one ``tau`` (s)."""
        return self.expm_x_many(np.array([float(tau)]), x)[0]

    def A_x(self, x) -> np.ndarray:
        """``A x``."""
        return self._A @ np.asarray(x, dtype=float)

    # --------------------------------------------------- switching function
    def _coeff_maps(self, m: int) -> tuple[np.ndarray, np.ndarray]:
        """``(Cq, Cqd)``, each ``(order+1, order+1, N)``: ``c_p = sum_j Cq[p, j] nu_q[j] + Cqd[p, j] nu_qd[j]``.

        ``nu_q[j]`` / ``nu_qd[j]``: the co-state entries of ``d^j q / domega^j`` and its rate.
        Built once per derivative order ``m`` (the maps do not depend on ``nu``; the switching
        function is evaluated thousands of times per solve with the same maps).
        """
        cached = self._maps.get(m)
        if cached is not None:
            return cached
        k = self.order
        Cq = np.zeros((k + 1, k + 1, self.N), dtype=complex)
        Cqd = np.zeros((k + 1, k + 1, self.N), dtype=complex)
        aq = self.cq * self.mu**m  # times d^j(omega^(m-1) e)
        aqd = self.cq * self.mu ** (m + 1)  # times d^j(omega^m e)
        for j in range(k + 1):
            for l in range(j + 1):
                p = j - l
                c = math.comb(j, l) * self.mu**p
                Cq[p, j] += c * aq * _ff(m - 1, l) * self.w ** (m - 1 - l)
                Cqd[p, j] += c * aqd * _ff(m, l) * self.w ** (m - l)
        self._maps[m] = (Cq, Cqd)
        return Cq, Cqd

    def _coeffs(self, nu: np.ndarray, m: int) -> np.ndarray:
        """Coefficients ``c_p`` (shape ``(order+1, N)``) with ``S_modes^(m)(tau) = Re(sum_i e^{mu w tau} sum_p c_p tau^p)``."""
        key = (m, nu.tobytes())
        hit = self._last_coeffs.get(key)
        if hit is not None:  # root isolation asks for the same co-state block after block
            return hit
        Cq, Cqd = self._coeff_maps(m)
        blocks = nu[self.r :].reshape(self.N, self.order + 1, 2)
        coef = np.einsum("pji,ji->pi", Cq, blocks[:, :, 0].T) + np.einsum("pji,ji->pi", Cqd, blocks[:, :, 1].T)
        if len(self._last_coeffs) >= 8:
            self._last_coeffs.clear()
        self._last_coeffs[key] = coef
        return coef

    def _spend(self, units: int) -> None:
        """Count switching-function work (points x orders x modes); past ``work_budget``, refuse."""
        self.work += units
        if self.work_budget is not None and self.work > self.work_budget:
            raise SolverError(
                f"robust time-optimal planner: no robust move within its work budget ({self.work_budget:.3g} "
                f"switching-function evaluations x modes over {self.N} modes); nothing is returned"
            )

    #: :meth:`switching` takes ``rows=`` (root isolation then shares one grid's exponentials).
    SWITCHING_TAKES_ROWS = True

    def _grid_exp(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``Re``, ``Im`` of ``e^{mu omega tau}``, shape ``(len(tau), N)`` each.

        Cached by identity for read-only arrays of 32 or more points (a
        planner's grid, as ``ModalResponse``'s trigonometric basis), the last
        two: root isolation evaluates ``S`` on one grid for every co-state at
        a duration; recomputing the exponentials each time was half of a long
        8-mode robust plan (fuzz seed 15 case 325: 18 of 39 s CPU).
        """
        cache = self.__dict__.setdefault("_exp_cache", [])
        for key, val in cache:
            if key is tau:
                return val
        E = self._E(tau)
        val = (np.ascontiguousarray(E.real), np.ascontiguousarray(E.imag))
        if tau.size >= 32 and not tau.flags.writeable:
            cache.insert(0, (tau, val))
            del cache[2:]
        return val

    def switching(self, nu, tau, derivative: bool = False, order: int | None = None, rows=None):
        """``S(tau) = nu^T e^{A tau} B`` and its ``tau``-derivatives (as :meth:`ModalResponse.switching`).

        ``rows``: evaluate at ``tau[rows]`` only, from the exponentials of the
        whole of ``tau`` (cached for a read-only grid).
        """
        K = 0 if order is None else order
        if derivative and order is None:
            K = 1
        tau = tau if isinstance(tau, np.ndarray) and tau.ndim == 1 else np.atleast_1d(np.asarray(tau, dtype=float))
        tau = tau.astype(float, copy=False)
        grid_exp = None
        if rows is not None:
            grid_exp = self._grid_exp(tau) if self.N else None
            tau = tau[rows]
        nu = np.asarray(nu, dtype=float)
        self._spend(tau.size * (K + 1) * max(self.N, 1))
        rig = self.rigid.switching(nu[: self.r], tau, order=K)
        rig = [rig] if K == 0 else list(rig)
        if self.N:
            # Re(sum_i E_i sum_p c_pi tau^p) = sum_p tau^p (Re E @ Re c_p - Im E @ Im c_p): one matrix
            # product per derivative instead of complex element-wise polynomials over (tau, modes),
            # which were most of a long robust plan (fuzz case 73: 16 ms per call)
            if grid_exp is not None:
                Er, Ei = grid_exp[0][rows], grid_exp[1][rows]
            else:
                Er, Ei = self._grid_exp(tau)
            for m in range(K + 1):
                c = self._coeffs(nu, m)  # (order+1, N)
                acc = Er @ np.ascontiguousarray(c.real.T) - Ei @ np.ascontiguousarray(c.imag.T)  # (len(tau), order+1)
                val = acc[:, self.order].copy()
                for p in range(self.order - 1, -1, -1):
                    val = val * tau + acc[:, p]
                rig[m] = rig[m] + val
        return rig[0] if K == 0 else tuple(rig)

    def _poly_bound(self, nu: np.ndarray, m: int, H: float) -> float:
        if not self.N:
            return 0.0
        c = np.abs(self._coeffs(nu, m))
        return float(np.sum(c * (H ** np.arange(self.order + 1))[:, None]))

    def _horizon(self) -> float:
        if self.horizon is None:
            raise SolverError("RobustModalResponse.horizon must be set before bounds are asked for")
        return float(self.horizon)

    def switching_magnitude(self, nu, tau_max: float) -> tuple[float, float]:
        """Sums of the magnitudes of the terms of ``S`` and ``S'`` on ``[0, tau_max]``."""
        nu = np.asarray(nu, dtype=float)
        m0, m1 = self.rigid.switching_magnitude(nu[: self.r], tau_max)
        return m0 + self._poly_bound(nu, 0, tau_max), m1 + self._poly_bound(nu, 1, tau_max)

    def switching_derivative_bound(self, nu, order: int) -> float:
        """Upper bound on ``|S^(order)|`` over ``[0, horizon]`` (``|e^{mu w tau}| <= 1``)."""
        nu = np.asarray(nu, dtype=float)
        return self.rigid.switching_derivative_bound(nu[: self.r], order) + self._poly_bound(nu, order, self._horizon())

    def switching_derivative_bounds(self, nu, tau_max: float) -> tuple[float, float]:
        """Upper bounds on ``|S'|`` and ``|S''|`` over ``[0, tau_max]``."""
        nu = np.asarray(nu, dtype=float)
        d1, d2 = self.rigid.switching_derivative_bounds(nu[: self.r], tau_max)
        return d1 + self._poly_bound(nu, 1, tau_max), d2 + self._poly_bound(nu, 2, tau_max)
