"""Minimum-fuel moves for a given move time (seed eq. 2.38), continuous and sampled, and the fuel/time curve."""

from .curve import FuelCurve, fuel_time_curve, sampled_fuel_curve
from .lp import check_move_time, plan_min_fuel_zoh
from .min_fuel import FuelProfile, plan_min_fuel

__all__ = [
    "FuelCurve",
    "FuelProfile",
    "check_move_time",
    "fuel_time_curve",
    "plan_min_fuel",
    "plan_min_fuel_zoh",
    "sampled_fuel_curve",
]
