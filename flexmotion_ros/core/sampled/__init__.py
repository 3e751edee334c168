"""Zero-order-hold planners at a fixed rate: the exact ZOH optimum, its variants, shared LP tools, the one exact check."""

from .check import verified_samples
from .fixed_time import plan_fixed_time_zoh
from .lp_tools import (
    correct_arrival,
    least_norm_correction,
    lp_state_scale,
    sample_vectors,
)
from .robust import plan_robust_time_optimal_zoh
from .sparse_rows import SparseRows
from .zoh import plan_time_optimal_zoh

__all__ = [
    "SparseRows",
    "correct_arrival",
    "least_norm_correction",
    "lp_state_scale",
    "plan_fixed_time_zoh",
    "plan_robust_time_optimal_zoh",
    "plan_time_optimal_zoh",
    "sample_vectors",
    "verified_samples",
]
