"""The modal model (seed eqs. 2.1-2.7), boundary conditions of a move (2.12-2.16), physical builders."""

from .boundary import MoveProblem, motion_to_rest, rest_to_rest, state_to_rest
from .builders import BUILDERS, BuiltModel, chain, crane, two_mass
from .modal_model import ModalModel, check_positive

__all__ = [
    "BUILDERS",
    "BuiltModel",
    "ModalModel",
    "MoveProblem",
    "chain",
    "check_positive",
    "crane",
    "motion_to_rest",
    "rest_to_rest",
    "state_to_rest",
    "two_mass",
]
