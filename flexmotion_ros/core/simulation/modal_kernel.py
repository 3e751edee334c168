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

    The rigid body's columns join the same product: with the basis extended
    by ``1, e^{c t}, t phi1(c t), t^2 phi2(c t)`` every response of the state
    (rigid and modal, in the response's state order) is one row of ``Q @ P``,
    so an evaluation is one basis and one matrix product, whatever the model.

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
        r, n = self.r, self.n = response.r, response.n
        b0, c = self.b0, self.c = float(response.b0), float(response.c)
        sig, wd, w, bm = response.sig, response.wd, response.w, response.bm
        self.sig, self.wd = sig, wd
        N = self.N = w.size
        self.fastest = float(np.max(wd)) if N else 0.0
        i = np.arange(N)
        # rows of the basis: E sin (N), E cos (N), then the rigid body's 1, e^{ct}, t phi1(ct), t^2 phi2(ct)
        one, ect, tp1, ttp2 = 2 * N, 2 * N + 1, 2 * N + 2, 2 * N + 3
        self._rows = 2 * N + 4
        P = np.zeros((self._rows, 3 * n))  # columns: e^{At}B | A e^{At}B | Gamma(t), state order
        P_eB = np.zeros((2 * N, 2 * N))
        P_eB[i, 2 * i] = bm / wd  # q column: bm E sin / wd
        P_eB[i, 2 * i + 1] = -bm * sig / wd  # q' column: bm E (cos - sig/wd sin)
        P_eB[N + i, 2 * i + 1] = bm
        P_G = np.zeros((2 * N, 2 * N))
        P_G[i, 2 * i] = -bm * sig / (wd * w * w)  # q: bm/w^2 (1 - E (cos + sig/wd sin))
        P_G[N + i, 2 * i] = -bm / (w * w)
        P_G[i, 2 * i + 1] = bm / wd  # q': bm E sin / wd
        P[: 2 * N, r:n] = P_eB
        P[: 2 * N, n + r : 2 * n] = _derivative(P_eB, sig, wd)
        P[: 2 * N, 2 * n + r :] = P_G
        P[one, 2 * n + r :: 2] = bm / (w * w)
        if r == 2:  # e^{At}B = b0 (t phi1, e^{ct}); A e^{At}B = b0 (e^{ct}, c e^{ct}); Gamma = b0 (t^2 phi2, t phi1)
            P[tp1, 0] = P[ect, 1] = P[ect, n] = P[tp1, 2 * n + 1] = P[ttp2, 2 * n] = b0
            P[ect, n + 1] = b0 * c
        else:  # e^{At}B = b0 e^{ct}; A e^{At}B = b0 c e^{ct}; Gamma = b0 t phi1
            P[ect, 0] = P[tp1, 2 * n] = b0
            P[ect, n] = b0 * c
        self.P = P
        self.x0 = None if x0 is None else np.asarray(x0, dtype=float)
        if self.x0 is not None:
            x0 = self.x0
            P_x = np.zeros((self._rows, 2 * n))  # columns: e^{AT} x0 | A e^{AT} x0
            if N:
                q, qd = x0[r::2], x0[r + 1 :: 2]
                Pm = np.zeros((2 * N, 2 * N))
                Pm[i, 2 * i] = (q * sig + qd) / wd  # q(t) = E (q cos + (q sig + qd)/wd sin)
                Pm[N + i, 2 * i] = q
                Pm[i, 2 * i + 1] = -(q * w * w + qd * sig) / wd  # q'(t) = E (qd cos - (q w^2 + qd sig)/wd sin)
                Pm[N + i, 2 * i + 1] = qd
                P_x[: 2 * N, r:n] = Pm
                P_x[: 2 * N, n + r :] = _derivative(Pm, sig, wd)
            v = float(x0[r - 1])
            if r == 2:  # p + v t phi1(cT), v e^{cT}; derivatives v e^{cT}, c v e^{cT}
                P_x[one, 0] = float(x0[0])
                P_x[tp1, 0] = P_x[ect, 1] = P_x[ect, n] = v
                P_x[ect, n + 1] = c * v
            else:
                P_x[ect, 0] = v
                P_x[ect, n] = c * v
            self.P_x = P_x

    def basis(self, t: np.ndarray) -> np.ndarray:
        """``[E sin(wd t), E cos(wd t), 1, e^{ct}, t phi1(ct), t^2 phi2(ct)]``, shape ``(len(t), 2N + 4)``."""
        N = self.N
        Q = np.empty((t.size, self._rows))
        if N:
            E = np.exp(np.multiply.outer(t, -self.sig))
            arg = np.multiply.outer(t, self.wd)
            np.multiply(E, np.sin(arg), out=Q[:, :N])
            np.multiply(E, np.cos(arg), out=Q[:, N : 2 * N])
        Q[:, 2 * N] = 1.0
        if self.c == 0.0:
            Q[:, 2 * N + 1] = 1.0
            Q[:, 2 * N + 2] = t
            Q[:, 2 * N + 3] = 0.5 * t * t
        else:
            ct = self.c * t
            Q[:, 2 * N + 1] = np.exp(ct)
            Q[:, 2 * N + 2] = t * phi1(ct)
            Q[:, 2 * N + 3] = t * t * phi2(ct)
        return Q

    def evaluate(self, t: np.ndarray) -> KernelValues:
        """Responses at the times ``t`` (s, 1-D, ``>= 0``); the initial state's at ``t[-1]``."""
        t = np.asarray(t, dtype=float)
        n = self.n
        Q = self.basis(t)
        M = Q @ self.P
        eAx = AeAx = None
        if self.x0 is not None:
            mx = Q[-1] @ self.P_x
            eAx, AeAx = mx[:n], mx[n:]
        return KernelValues(eB=M[:, :n], AeB=M[:, n : 2 * n], G=M[:, 2 * n :], eAx=eAx, AeAx=AeAx)

    def input_response(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """``(e^{A t} B, e^{A T} x0, A e^{A T} x0)``: :meth:`evaluate`'s ``eB``, ``eAx``, ``AeAx`` alone.

        A third of the product (a smoothed dual step needs ``e^{A t} B`` on
        its grid and the free motion at the end, nothing else).
        """
        t = np.asarray(t, dtype=float)
        Q = self.basis(t)
        eB = Q @ self.P[:, : self.n]
        if self.x0 is None:
            return eB, None, None
        mx = Q[-1] @ self.P_x
        return eB, mx[: self.n], mx[self.n :]
