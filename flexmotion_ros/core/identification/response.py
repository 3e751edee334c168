"""The exact zero-order-hold response of a modal model at a sensor, and its derivatives.

A sensor reads a physical coordinate ``y = a0 p + sum_i a_i q_i`` (position),
its velocity, or its acceleration, sampled at ``t_k = k dt`` while the input is
held, ``u(t) = u_k`` on ``[t_k, t_{k+1})``, from rest.  The model is linear in
the gains, so the response is a sum of unit responses::

    y_k = offset + a0 b0 R_k(c) + sum_i g_i M_k(omega_i, zeta_i),   g_i = a_i b_i

``R`` is the rigid body's unit response (``p'' = c p' + u``) and ``M`` a mode's
(``q'' + 2 zeta omega q' + omega^2 q = u``), each read as the sensor's kind.

Each unit response is the exact ZOH discretisation of its 1- or 2-state block
(the augmented matrix exponential ``expm([[A, B], [0, 0]] dt)``), written as a
discrete transfer function and run with :func:`scipy.signal.lfilter` (compiled
recursion: 10^4 samples in tens of microseconds).  Derivatives with respect to
``c``, ``omega`` and ``zeta`` are exact too: the filter coefficients'
derivatives come from a complex step through the matrix exponential, and
``dy = (db u - da y) / a`` is two more filters.

Acceleration has direct feedthrough: ``q'' = u - 2 zeta omega q' - omega^2 q``
jumps with the input.  The convention is that sample ``k`` is read *after* the
command ``u_k`` is applied (``y_k = C x_k + D u_k``); a sensor read just before
the update sees ``u_{k-1}``: pass the input delayed by one sample.
"""

from __future__ import annotations

from enum import Enum

import numpy as np
from scipy.linalg import expm
from scipy.signal import lfilter

#: Complex-step size (relative): the derivative is exact to rounding, whatever the step.
_COMPLEX_STEP = 1e-30


class OutputKind(str, Enum):
    """What a sensor measures: a physical coordinate, its velocity or its acceleration."""

    POSITION = "position"
    VELOCITY = "velocity"
    ACCELERATION = "acceleration"

    def __str__(self) -> str:
        return str(self.value)

    def __format__(self, format_spec: str) -> str:
        return format(str(self.value), format_spec)


OUTPUT_UNITS = {
    OutputKind.POSITION: "m",
    OutputKind.VELOCITY: "m/s",
    OutputKind.ACCELERATION: "m/s^2",
}


def _block(kind: OutputKind, rigid: bool, p1, p2=None):
    """Continuous ``(A, B, C, D)`` of one unit block read as ``kind``.

    Rigid (``p1 = c``): ``p'' = c p' + u``; position needs ``[p, v]``, velocity and
    acceleration only ``v``.  Mode (``p1 = omega``, ``p2 = zeta``):
    ``[q, q']`` with ``q'' = -omega^2 q - 2 zeta omega q' + u``.
    """
    dtype = complex if np.iscomplexobj(np.asarray([p1, 0.0 if p2 is None else p2])) else float
    if rigid:
        c = p1
        if kind is OutputKind.POSITION:
            A = np.array([[0.0, 1.0], [0.0, c]], dtype=dtype)
            return A, np.array([0.0, 1.0]), np.array([1.0, 0.0], dtype=dtype), 0.0
        A = np.array([[c]], dtype=dtype)
        if kind is OutputKind.VELOCITY:
            return A, np.array([1.0]), np.array([1.0], dtype=dtype), 0.0
        return A, np.array([1.0]), np.array([c], dtype=dtype), 1.0
    w, z = p1, p2
    A = np.array([[0.0, 1.0], [-w * w, -2.0 * z * w]], dtype=dtype)
    B = np.array([0.0, 1.0])
    if kind is OutputKind.POSITION:
        return A, B, np.array([1.0, 0.0], dtype=dtype), 0.0
    if kind is OutputKind.VELOCITY:
        return A, B, np.array([0.0, 1.0], dtype=dtype), 0.0
    return A, B, np.array([-w * w, -2.0 * z * w], dtype=dtype), 1.0


def zoh_filter(kind: OutputKind, rigid: bool, dt: float, p1, p2=None) -> tuple[np.ndarray, np.ndarray]:
    """Exact ZOH transfer function ``(b, a)`` (powers of ``z^-1``) of one unit block.

    Parameters
    ----------
    kind : OutputKind
    rigid : bool
        ``True``: rigid body with viscous term ``p1 = c`` (1/s).  ``False``: a mode
        with ``p1 = omega`` (rad/s), ``p2 = zeta``.
    dt : float
        Sample time (s).

    Returns
    -------
    b, a : ndarray
        ``y = lfilter(b, a, u)`` is the sampled response from rest, ``y_k = C x_k + D u_k``.
        Complex when a parameter is complex (complex-step derivatives).
    """
    A, B, C, D = _block(kind, rigid, p1, p2)
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1), dtype=A.dtype)
    M[:n, :n] = A
    M[:n, n] = B
    E = expm(M * dt)
    Phi, Gam = E[:n, :n], E[:n, n]
    if n == 1:
        p = Phi[0, 0]
        return np.array([D, C[0] * Gam[0] - D * p]), np.array([1.0, -p])
    tr = Phi[0, 0] + Phi[1, 1]
    det = Phi[0, 0] * Phi[1, 1] - Phi[0, 1] * Phi[1, 0]
    adj = np.array([[-Phi[1, 1], Phi[0, 1]], [Phi[1, 0], -Phi[0, 0]]])  # adj(zI - Phi) = z I + adj
    b = np.array([D, C @ Gam - D * tr, C @ adj @ Gam + D * det])
    return b, np.array([1.0, -tr, det])


def unit_response(kind: OutputKind, rigid: bool, dt: float, u: np.ndarray, p1: float, p2: float | None = None):
    """Sampled unit response ``y_k`` of one block to the held input ``u`` from rest."""
    b, a = zoh_filter(kind, rigid, dt, p1, p2)
    return lfilter(b, a, u)


def unit_response_and_derivatives(
    kind: OutputKind, rigid: bool, dt: float, u: np.ndarray, params: tuple[float, ...]
) -> tuple[np.ndarray, list[np.ndarray]]:
    """A unit response and its exact derivatives with respect to each block parameter.

    ``params`` is ``(c,)`` for the rigid body, ``(omega, zeta)`` for a mode.
    """
    b, a = zoh_filter(kind, rigid, dt, *params)
    y = lfilter(b, a, u)
    derivs = []
    for j in range(len(params)):
        h = _COMPLEX_STEP * max(1.0, abs(params[j]))
        pert = [complex(p) for p in params]
        pert[j] += 1j * h
        bc, ac = zoh_filter(kind, rigid, dt, *pert)
        db, da = bc.imag / h, ac.imag / h
        # a y = b u  =>  a dy = db u - da y  (filters commute)
        derivs.append(lfilter(db, a, u) - lfilter(da, a, y))
    return y, derivs
