"""Velocity, deflection and slew-rate limits: their checks and the fewest-samples limited planner."""

from .limits import Limits, check_limits
from .planner import LimitedProfile, plan_limited_zoh

__all__ = ["LimitedProfile", "Limits", "check_limits", "plan_limited_zoh"]
