"""Step matrices of the modal model in closed form: the friction simulator's fast path.

``e^{A h}``, ``int_0^h e^{A s} B ds`` and the rigid-body friction term for one
step length ``h`` from the modal closed forms of
:class:`~flexmotion_ros.core.simulation.modal_response.ModalResponse`, cached
per ``h``.  Used by :class:`~.contact.FrictionSystem` (``closed_form=True``,
the planners' shooting runs) and by the sampled LPs (:mod:`.sampled_lp`); the
independent checks use matrix exponentials.
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

    def steps(self, h: float):
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
        if r.w.size:
            E, C, S = (a[0] for a in r._mode_trig(np.array([h])))
            s_wd = r.sig / r.wd
            i = 2 + 2 * np.arange(r.w.size)
            Phi[i, i] = E * (C + s_wd * S)
            Phi[i, i + 1] = E * S / r.wd
            Phi[i + 1, i] = -E * r.w**2 / r.wd * S
            Phi[i + 1, i + 1] = E * (C - s_wd * S)
        Gam = r.input_integral(np.array([h]))[0]
        Gg = np.zeros(n)
        Gg[:2] = Gam[:2] * (abs(r.b0) / r.b0)  # friction acts on the rigid body only
        if len(self._cache) > 4096:
            self._cache.clear()
        out = (Phi, Gam, Gg)
        self._cache[h] = out
        return out
