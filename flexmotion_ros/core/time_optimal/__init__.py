"""Certified time-optimal bang-bang moves (seed section 2.3, eqs. 2.30-2.37), robust and fixed-time variants."""

from .certificate import certify
from .fixed_time import check_arrival_time, plan_fixed_time
from .rigid_body import rigid_profile, rigid_time
from .robust import RobustModalResponse, check_order, plan_robust_time_optimal
from .solver import plan_time_optimal, solve_bang_bang
from .switching import find_roots, isolate_roots

__all__ = [
    "RobustModalResponse",
    "certify",
    "check_arrival_time",
    "check_order",
    "find_roots",
    "isolate_roots",
    "plan_fixed_time",
    "plan_robust_time_optimal",
    "plan_time_optimal",
    "rigid_profile",
    "rigid_time",
    "solve_bang_bang",
]
