"""Boundary conditions of a move (seed section 2.1.2, eqs. 2.12-2.16).

Every move ends at rest.  If the final position is specified, the state is
shifted so that the target is the origin (``x~ = x - x_f``, eq. 2.16; the
target is an equilibrium, so ``A x_f = 0``).  If it is free (bring a moving
machine to rest as fast as possible, eq. 2.13), the position state is dropped
and the remaining states must reach zero.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import GoalError, ModelError
from .modal_model import ModalModel, check_positive


@dataclass(frozen=True)
class MoveProblem:
    """A move to rest.

    Attributes
    ----------
    model : ModalModel
    u_max : float
        Input bound ``|u| <= u_max`` (N, or the model's input unit).
    x0 : ndarray
        Full initial state ``[p, v, q_1, q_1', ...]``.
    target : float or None
        Final rigid-body position (m or rad); ``None``: final position free.
    """

    model: ModalModel
    u_max: float
    x0: np.ndarray
    target: float | None = None

    def __post_init__(self) -> None:
        check_positive("u_max", self.u_max)
        object.__setattr__(self, "u_max", float(self.u_max))
        x0 = np.asarray(self.x0, dtype=float).ravel()
        if x0.size != self.model.n_states:
            raise GoalError("initial_state", f"must have {self.model.n_states} entries, got {x0.size}")
        bad = [i for i, xi in enumerate(x0) if not math.isfinite(xi)]
        if bad:
            names = self.model.state_names()
            raise GoalError("initial_state", f"{names[bad[0]]} must be finite, got {x0[bad[0]]}")
        object.__setattr__(self, "x0", x0)
        if self.target is not None:
            t = self.target
            try:
                t = float(t)
            except (TypeError, ValueError):
                raise GoalError("goal", f"must be a finite position, got {self.target!r}") from None
            if not math.isfinite(t):
                raise GoalError("goal", f"must be a finite position, got {t}")
            object.__setattr__(self, "target", t)

    @property
    def include_position(self) -> bool:
        """Whether the final position is specified (and so part of the state)."""
        return self.target is not None

    def shifted_initial(self) -> np.ndarray:
        """``x~_0 = x_0 - x_f`` (eq. 2.16), without the position if it is free."""
        if self.target is None:
            return self.x0[1:].copy()
        x = self.x0.copy()
        x[0] -= self.target
        return x

    def is_at_rest(self) -> bool:
        """Already at the final state (nothing to do)."""
        return not np.any(self.shifted_initial())


def rest_to_rest(model: ModalModel, u_max: float, gamma: float, start: float = 0.0) -> MoveProblem:
    """Rest-to-rest move by ``gamma`` (eq. 2.12), from rest at ``start``."""
    g = _finite_goal("goal", gamma)
    return MoveProblem(model, u_max, model.rest_state(start), start + g)


def motion_to_rest(model: ModalModel, u_max: float, nu: float) -> MoveProblem:
    """Stop a machine moving at velocity ``nu`` without vibration (eq. 2.13).

    The final position is free.
    """
    v = _finite_goal("initial_velocity", nu)
    x0 = model.rest_state()
    x0[1] = v
    return MoveProblem(model, u_max, x0, None)


def state_to_rest(model: ModalModel, u_max: float, x0, target: float | None = None) -> MoveProblem:
    """From any (moving, vibrating) state to rest at ``target`` (eqs. 2.14-2.16).

    ``target=None`` stops as fast as possible wherever the machine ends up.
    """
    return MoveProblem(model, u_max, np.asarray(x0, dtype=float), target)


def _finite_goal(name: str, value: float) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise GoalError(name, f"must be a finite number, got {value!r}") from None
    if not math.isfinite(x):
        raise GoalError(name, f"must be finite, got {x}")
    return x


__all__ = ["GoalError", "ModelError", "MoveProblem", "motion_to_rest", "rest_to_rest", "state_to_rest"]
