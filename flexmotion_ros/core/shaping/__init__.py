"""Input shapers (seed section 2.1.3), shaped profiles and their sensitivity to model error."""

from .sampled_shaped import sample_command
from .sensitivity import (
    Insensitivity,
    command_insensitivity,
    command_vibration,
    residual_amplitudes,
    shaper_insensitivity,
)
from .shaped_profile import ShapedProfile, plan_shaped, shape
from .shapers import SHAPER_TABLE, SHAPERS, Shaper, ShaperKind, design, multi_mode_direct

__all__ = [
    "Insensitivity",
    "SHAPERS",
    "SHAPER_TABLE",
    "ShapedProfile",
    "Shaper",
    "ShaperKind",
    "command_insensitivity",
    "command_vibration",
    "design",
    "multi_mode_direct",
    "plan_shaped",
    "residual_amplitudes",
    "sample_command",
    "shape",
    "shaper_insensitivity",
]
