"""One Coulomb friction contact: where it acts and on which velocity (the model of :mod:`.contact`).

``g`` is the state derivative per newton of friction force and ``y = C x`` the
sliding velocity (``C g > 0``); see :mod:`.contact` for the dynamics and the
exact simulation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..model.modal_model import ModalModel


@dataclass(frozen=True)
class Contact:
    """One Coulomb friction contact.

    Attributes
    ----------
    g : ndarray, shape ``(n,)``
        ``x'`` per newton of friction force (e.g. ``|b0| e_v`` for the rigid body).
    C : ndarray, shape ``(n,)``
        Sliding velocity ``y = C x`` (m/s).
    force : float
        Coulomb force ``F >= 0`` (N, the input's unit).
    """

    g: np.ndarray
    C: np.ndarray
    force: float

    def __post_init__(self) -> None:
        g = np.asarray(self.g, float).ravel()
        C = np.asarray(self.C, float).ravel()
        F = float(self.force)
        if not (math.isfinite(F) and F >= 0.0):
            raise InputError("coulomb_force", f"must be finite and >= 0 N, got {self.force}")
        if g.shape != C.shape or not float(C @ g) > 0.0:
            raise InputError("friction contact", "needs C g > 0 (friction must oppose the sliding velocity)")
        object.__setattr__(self, "g", g)
        object.__setattr__(self, "C", C)
        object.__setattr__(self, "force", F)


def rigid_contact(model: ModalModel, coulomb_force: float) -> Contact:
    """Friction ``F sgn(v)`` on the rigid-body coordinate of ``model`` (see module notes)."""
    g = np.zeros(model.n_states)
    g[1] = abs(model.b0)
    C = np.zeros(model.n_states)
    C[1] = 1.0
    return Contact(g, C, coulomb_force)


def contact_at_coordinate(built, index: int, coulomb_force: float) -> Contact:
    """Friction at physical coordinate ``index`` of a :class:`~.builders.BuiltModel` (inside the structure).

    With ``Phi = modal_to_physical`` and the physical mass matrix ``M`` the
    generalised effect of a force on coordinate ``j`` is ``Phi^{-1} M^{-1} e_j``
    (mass-orthogonal modes); the sliding velocity is row ``j`` of ``Phi`` on
    the velocity states.  Needs the builder's masses (``two_mass``, ``crane``,
    ``chain``).
    """
    p = built.parameters
    if "masses" in p:
        masses = np.asarray(p["masses"], float)
    elif "m1" in p:
        masses = np.array([p["m1"], p["m2"]], float)
    elif "cart_mass" in p:
        masses = np.array([p["cart_mass"], p["payload_mass"]], float)
    else:
        raise InputError("friction contact", f"no masses known for a {built.kind!r} model")
    Phi = np.asarray(built.modal_to_physical, float)
    if not 0 <= index < Phi.shape[0]:
        raise InputError("friction contact", f"coordinate index must be in [0, {Phi.shape[0] - 1}], got {index}")
    eff = np.linalg.solve(Phi, np.eye(Phi.shape[0])[index] / masses)  # modal accelerations per N
    n = built.model.n_states
    g = np.zeros(n)
    C = np.zeros(n)
    g[1::2] = eff
    C[1::2] = Phi[index]
    return Contact(g, C, coulomb_force)
