"""What every planner of one move needs, built once per plan: :class:`PreparedMove`.

A plan used to rebuild the closed-form responses (:class:`ModalResponse`) and
the shifted initial state in each planner it called (about four times for a
sampled time-optimal plan, eleven for ``fixed_time``, which also solved the
time-optimal problem twice).  :func:`prepare` builds them once; the planners
accept either a :class:`~flexmotion_ros.core.model.boundary.MoveProblem` or a
:class:`PreparedMove`, so existing call sites keep working.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..model.boundary import MoveProblem
from ..results import BangBangProfile
from .error_scale import state_scale
from .modal_response import ModalResponse


@dataclass(frozen=True, kw_only=True)
class PreparedMove:
    """One move with its closed-form responses, shifted initial state and (once known) time-optimal profile.

    Build it with :meth:`of` or :func:`prepare`; treat the arrays as read-only.

    Attributes
    ----------
    problem : MoveProblem
        The move (model, bound ``u_max`` in N, initial state, target).
    response : ModalResponse
        Closed-form responses of ``problem.model`` in the planners' state
        (without the rigid-body position if the final position is free).
    x0 : ndarray
        Shifted initial state ``x0 - x_f`` (``problem.shifted_initial()``,
        state units: m, m/s, modal coordinates).
    continuous : BangBangProfile or None
        The certified continuous time-optimal profile of ``problem`` at
        ``u_max``, when known (:meth:`with_continuous`).
    """

    problem: MoveProblem
    response: ModalResponse
    x0: np.ndarray
    continuous: BangBangProfile | None = None
    _scales: dict = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def of(cls, problem: MoveProblem) -> PreparedMove:
        """Build the responses and the shifted initial state of ``problem`` (once)."""
        return cls(
            problem=problem,
            response=ModalResponse(problem.model, problem.include_position),
            x0=problem.shifted_initial(),
        )

    @property
    def u_max(self) -> float:
        """Input bound (N)."""
        return self.problem.u_max

    def error_scale(self, T: float) -> np.ndarray:
        """The final-state error scale of a move of length ``T`` (s), in state units.

        :func:`~flexmotion_ros.core.simulation.error_scale.state_scale` of this
        move (computed once per ``T``).
        """
        key = float(T)
        s = self._scales.get(key)
        if s is None:
            s = state_scale(self.response, self.x0, self.problem.u_max, key)
            self._scales[key] = s
        return s.copy()

    def with_continuous(self, profile: BangBangProfile | None) -> PreparedMove:
        """A copy that carries ``profile`` as the certified continuous optimum."""
        return replace(self, continuous=profile, _scales=self._scales)

    def with_bound(self, u_max: float) -> PreparedMove:
        """The same move at another bound ``u_max`` (N): the responses are shared, no optimum attached."""
        problem = MoveProblem(self.problem.model, u_max, self.problem.x0, self.problem.target)
        return PreparedMove(problem=problem, response=self.response, x0=self.x0)


def prepare(move: MoveProblem | PreparedMove) -> PreparedMove:
    """``move`` as a :class:`PreparedMove` (itself if it already is one)."""
    return move if isinstance(move, PreparedMove) else PreparedMove.of(move)
