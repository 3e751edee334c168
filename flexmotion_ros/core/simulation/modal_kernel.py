"""Every closed-form response of a modal model at a few times, from one trigonometric evaluation.

:class:`~flexmotion_ros.core.simulation.modal_response.ModalResponse` answers
one question per call (``e^{A tau} B``, ``Gamma(tau)``, the switching
function, ...), each recomputing ``e^{-sigma tau}``, ``cos`` and ``sin``.  The
planners' inner loops (a switch-time Newton step, a smoothed dual step) ask
four or five of them at the same times, with arrays of a few to a few hundred
entries where the cost is the number of numpy calls, not the arithmetic.

Every modal column of these responses is ``E (a sin(wd tau) + b cos(wd tau))``
(plus a constant for ``Gamma``), ``E = e^{-sigma tau}``, with coefficients
fixed by the model (and the initial state).  So with the basis
``Q = [E sin, E cos]`` (one row per time) each response is ``Q @ P`` for a
constant matrix ``P`` built once, and ``d/dtau`` maps a column's ``(a, b)`` to
``(-(sigma a + wd b), wd a - sigma b)``: :class:`ModalKernel` evaluates
``e^{A tau} B``, ``A e^{A tau} B`` and ``Gamma(tau)`` at every time, and
``e^{A T} x0``, ``A e^{A T} x0`` at the last, in about fifteen numpy calls.

The formulas are those of :class:`ModalResponse` (tested against it); like
it, nothing computed here is trusted: every plan is checked by the matrix
exponentials of :mod:`flexmotion_ros.core.simulation.exact`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .modal_response import ModalResponse, phi1, phi2


@dataclass(frozen=True, kw_only=True)
class KernelValues:
    """Responses at times ``t`` (rows) in the response's state order (columns).

    Attributes
    ----------
    eB : ndarray
        ``e^{A t} B``, shape ``(len(t), n)``.
    AeB : ndarray
        ``A e^{A t} B`` (its time derivative).
    G : ndarray
        ``Gamma(t) = int_0^t e^{A s} B ds`` (the state a unit input held for
        ``t`` reaches from rest).
    eAx : ndarray or None
        ``e^{A t_last} x0`` (shape ``(n,)``) when an initial state was given.
    AeAx : ndarray or None
        ``A e^{A t_last} x0``.
    """

    eB: np.ndarray
    AeB: np.ndarray
    G: np.ndarray
    eAx: np.ndarray | None = None
    AeAx: np.ndarray | None = None


def _derivative(P: np.ndarray, sig: np.ndarray, wd: np.ndarray) -> np.ndarray:
    """Coefficients of ``d/dtau`` of modal columns ``E (a sin + b cos)`` (rows ``[a; b]`` per mode)."""
    N = sig.size
    a, b = P[:N], P[N:]
    return np.concatenate([-(a * sig[:, None] + b * wd[:, None]), a * wd[:, None] - b * sig[:, None]])


class ModalKernel:
    """Fused closed-form responses of one :class:`ModalResponse` (see the module docstring).

    Parameters
    ----------
    response : ModalResponse
        The model's responses (with or without the rigid-body position).
    x0 : ndarray, optional
        An initial state (the response's state): :meth:`evaluate` then also
        gives ``e^{A T} x0`` and ``A e^{A T} x0`` at its last time.
    """

    def __init__(self, response: ModalResponse, x0: np.ndarray | None = None) -> None:
        self.response = response
        self.r, self.n = response.r, response.n
        self.b0, self.c = float(response.b0), float(response.c)
        sig, wd, w, bm = response.sig, response.wd, response.w, response.bm
        self.sig, self.wd = sig, wd
        N = self.N = w.size
        self.fastest = float(np.max(wd)) if N else 0.0
        i = np.arange(N)
        P_eB = np.zeros((2 * N, 2 * N))
        P_eB[i, 2 * i] = bm / wd  # q column: bm E sin / wd
        P_eB[i, 2 * i + 1] = -bm * sig / wd  # q' column: bm E (cos - sig/wd sin)
        P_eB[N + i, 2 * i + 1] = bm
        P_G = np.zeros((2 * N, 2 * N))
        P_G[i, 2 * i] = -bm * sig / (wd * w * w)  # q: bm/w^2 (1 - E (cos + sig/wd sin))
        P_G[N + i, 2 * i] = -bm / (w * w)
        P_G[i, 2 * i + 1] = bm / wd  # q': bm E sin / wd
        self.G_const = np.zeros(2 * N)
        self.G_const[2 * i] = bm / (w * w)
        self.P = np.concatenate([P_eB, _derivative(P_eB, sig, wd), P_G], axis=1)
        self.x0 = None if x0 is None else np.asarray(x0, dtype=float)
        if self.x0 is not None and N:
            q, qd = self.x0[self.r :: 2], self.x0[self.r + 1 :: 2]
            P_x = np.zeros((2 * N, 2 * N))
            P_x[i, 2 * i] = (q * sig + qd) / wd  # q(t) = E (q cos + (q sig + qd)/wd sin)
            P_x[N + i, 2 * i] = q
            P_x[i, 2 * i + 1] = -(q * w * w + qd * sig) / wd  # q'(t) = E (qd cos - (q w^2 + qd sig)/wd sin)
            P_x[N + i, 2 * i + 1] = qd
            self.P_x = np.concatenate([P_x, _derivative(P_x, sig, wd)], axis=1)

    def basis(self, t: np.ndarray) -> np.ndarray:
        """``[E sin(wd t), E cos(wd t)]`` per mode, shape ``(len(t), 2N)``."""
        E = np.exp(np.multiply.outer(t, -self.sig))
        arg = np.multiply.outer(t, self.wd)
        return np.concatenate([E * np.sin(arg), E * np.cos(arg)], axis=1)

    def evaluate(self, t: np.ndarray) -> KernelValues:
        """Responses at the times ``t`` (s, 1-D, ``>= 0``); the initial state's at ``t[-1]``."""
        t = np.asarray(t, dtype=float)
        m, n, r, N = t.size, self.n, self.r, self.N
        eB = np.empty((m, n))
        AeB = np.empty((m, n))
        G = np.empty((m, n))
        eAx = AeAx = None
        if N:
            Q = self.basis(t)
            M = Q @ self.P
            eB[:, r:] = M[:, : 2 * N]
            AeB[:, r:] = M[:, 2 * N : 4 * N]
            G[:, r:] = M[:, 4 * N :] + self.G_const
        b0, c = self.b0, self.c
        x0 = self.x0
        if x0 is not None:
            eAx = np.empty(n)
            AeAx = np.empty(n)
            if N:
                mx = Q[-1] @ self.P_x
                eAx[r:] = mx[: 2 * N]
                AeAx[r:] = mx[2 * N :]
        T = float(t[-1]) if m else 0.0
        if c == 0.0:
            if r == 2:
                eB[:, 0] = b0 * t
                eB[:, 1] = b0
                AeB[:, 0] = b0
                AeB[:, 1] = 0.0
                G[:, 0] = 0.5 * b0 * t * t
                G[:, 1] = b0 * t
                if x0 is not None:
                    eAx[0], eAx[1] = x0[0] + x0[1] * T, x0[1]
                    AeAx[0], AeAx[1] = x0[1], 0.0
            else:
                eB[:, 0] = b0
                AeB[:, 0] = 0.0
                G[:, 0] = b0 * t
                if x0 is not None:
                    eAx[0], AeAx[0] = x0[0], 0.0
        else:
            ect = np.exp(c * t)
            ph1 = phi1(c * t)
            if r == 2:
                eB[:, 0] = b0 * t * ph1
                eB[:, 1] = b0 * ect
                AeB[:, 0] = b0 * ect
                AeB[:, 1] = b0 * c * ect
                G[:, 0] = b0 * t * t * phi2(c * t)
                G[:, 1] = b0 * t * ph1
            else:
                eB[:, 0] = b0 * ect
                AeB[:, 0] = b0 * c * ect
                G[:, 0] = b0 * t * ph1
            if x0 is not None:
                e = math.exp(c * T)
                v = x0[r - 1]
                if r == 2:
                    eAx[0] = x0[0] + v * T * float(ph1[-1])
                    AeAx[0] = v * e
                eAx[r - 1] = v * e
                AeAx[r - 1] = c * v * e
        return KernelValues(eB=eB, AeB=AeB, G=G, eAx=eAx, AeAx=AeAx)
