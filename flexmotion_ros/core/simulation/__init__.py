"""Exact propagation of piecewise-constant inputs (matrix exponentials) and closed-form modal responses."""

from .exact import (
    PiecewiseConstant,
    final_state,
    modal_amplitudes,
    simulate,
    simulate_samples,
    step_matrices,
)
from .modal_response import ModalResponse

__all__ = [
    "ModalResponse",
    "PiecewiseConstant",
    "final_state",
    "modal_amplitudes",
    "simulate",
    "simulate_samples",
    "step_matrices",
]
