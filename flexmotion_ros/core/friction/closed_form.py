"""The friction fast path's step matrices in closed form (modal blocks, one step length at a time).

:class:`ClosedForm` gives ``e^{A h}``, ``int_0^h e^{A s} B ds`` and the rigid-body friction term of a
:class:`~flexmotion_ros.core.model.modal_model.ModalModel` for one ``h``: the numbers of
:class:`~flexmotion_ros.core.simulation.modal_response.ModalResponse` to the bit, without its array set-up.
The event-located simulator (:mod:`.contact`) steps with it where ``closed_form=True``, and so do the
sampled LPs (:mod:`.sampled_lp`).
"""

from __future__ import annotations

import math

import numpy as np

from ..model.modal_model import ModalModel
from ..simulation.modal_response import ModalResponse


class ClosedForm:
    """``e^{A h}``, ``int_0^h e^{A s} B ds`` and the friction term in closed form (modal blocks)."""

    def __init__(self, model: ModalModel) -> None:
        self.model = model
        self.resp = ModalResponse(model, True)
        self.n = model.n_states
        self._cache: dict[float, tuple] = {}
        r = self.resp
        # constants of :meth:`steps`, each formed as ``ModalResponse`` forms it (the same numbers to the bit)
        self._neg_sig = -r.sig
        self._s_wd = r.sig / r.wd
        self._half_wd = 0.5 * r.wd
        self._w2 = r.w**2
        self._diag = 2 + 2 * np.arange(r.w.size)
        i, n = self._diag, self.n
        # flat indices of the modal 2 x 2 blocks of Phi, in the order :meth:`steps` forms their entries
        self._blocks = np.concatenate([i * n + i, i * n + i + 1, (i + 1) * n + i, (i + 1) * n + i + 1])

    def steps(self, h: float):
        """``(Phi, Gam, Gg)`` for a step of ``h`` seconds: ``e^{A h}``, ``int_0^h e^{A s} B ds`` and the
        friction term (cached per ``h``).

        The numbers of :meth:`ModalResponse.input_integral` and ``_mode_trig`` at ``[h]``, operation for
        operation, on one time instead of an array of times: the planners' exact runs ask for a new ``h``
        at almost every segment (a Newton residual: about 26), and the array versions' set-up (2-D
        broadcasting, boolean masks of ``phi1`` / ``phi2``) was most of their cost.
        """
        hit = self._cache.get(h)
        if hit is not None:
            return hit
        r = self.resp
        n = self.n
        Phi = np.zeros((n, n))
        ch = r.c * h
        Phi[0, 0] = 1.0
        Phi[0, 1] = h * (math.expm1(ch) / ch if ch != 0.0 else 1.0)
        Phi[1, 1] = math.exp(ch)
        Gam = np.empty(n)
        if r.c == 0.0:  # as input_integral: phi1(0) = 1, phi2(0) = 1/2 exactly
            Gam[0] = r.b0 * h * h * 0.5
            Gam[1] = r.b0 * h
        else:
            Gam[0] = r.b0 * h * h * _phi2(ch)
            Gam[1] = r.b0 * h * _phi1(ch)
        if r.w.size:
            E = np.exp(self._neg_sig * h)
            arg = r.wd * h
            C, S = np.cos(arg), np.sin(arg)
            s_wd = self._s_wd
            sS = s_wd * S
            ES_wd = E * S / r.wd
            # the four entries of every block in one assignment (the same operations as one assignment
            # each: (-E * w2) / wd * S as -E * w2 / wd * S)
            Phi.flat[self._blocks] = np.concatenate([E * (C + sS), ES_wd, -E * self._w2 / r.wd * S, E * (C - sS)])
            half = np.sin(self._half_wd * h)
            one_minus = -np.expm1(self._neg_sig * h) + 2.0 * E * half * half - E * s_wd * S
            Gam[2::2] = r.bm * one_minus / self._w2
            Gam[3::2] = r.bm * E * S / r.wd
        Gg = np.zeros(n)
        Gg[:2] = Gam[:2] * (abs(r.b0) / r.b0)  # friction acts on the rigid body only
        if len(self._cache) > 4096:
            self._cache.clear()
        out = (Phi, Gam, Gg)
        self._cache[h] = out
        return out


def _phi1(z: float) -> float:
    """``modal_response.phi1`` of one number: the same operations (``numpy``'s ``expm1``), no array set-up."""
    if abs(z) >= 1e-12:
        return float(np.expm1(np.array([z]))[0]) / z
    return 1.0 + 0.5 * z


#: ``|z|`` below which ``phi2`` sums its Taylor series (``modal_response``'s threshold; the test of
#: :meth:`ClosedForm.steps` against ``ModalResponse`` holds them equal).
PHI2_SERIES_Z = 0.1
#: The Taylor coefficients ``1 / (k + 2)!`` of ``phi2``, highest first (Horner), as ``modal_response`` adds them.
_PHI2_SERIES = tuple(1.0 / math.factorial(k + 2) for k in range(8, -1, -1))


def _phi2(z: float) -> float:
    """``modal_response.phi2`` of one number: the same operations in the same order, no array set-up."""
    if abs(z) >= PHI2_SERIES_Z:
        return (float(np.expm1(np.array([z]))[0]) - z) / (z * z)
    acc = 0.0
    for coefficient in _PHI2_SERIES:
        acc = acc * z + coefficient
    return acc
