"""The ROS-free numerical core (numpy/scipy only).

Typical use::

    from flexmotion_ros.core import ModalModel, rest_to_rest, plan_time_optimal, plan_zoh

    model = ModalModel(b0=0.5, omega=[2 ** 0.5], zeta=[0.0], b=[1.0])
    profile = plan_time_optimal(rest_to_rest(model, u_max=1.0, gamma=1.0))
    profile.duration, profile.switch_times, profile.certified
"""

from .boundary import MoveProblem, motion_to_rest, rest_to_rest, state_to_rest
from .builders import BuiltModel, chain, crane, two_mass
from .certificate import Certificate
from .config import PlannerConfig, config_from_parameters, load_config, write_config
from .errors import FlexmotionError, GoalError, ModelError, SolverError
from .model import ModalModel
from .profile import BangBangProfile, SampledProfile
from .simulation import (
    PiecewiseConstant,
    final_state,
    modal_amplitudes,
    simulate,
    simulate_samples,
)
from .time_optimal import plan_time_optimal
from .zoh import plan_zoh

__all__ = [
    "BangBangProfile",
    "BuiltModel",
    "Certificate",
    "FlexmotionError",
    "GoalError",
    "ModalModel",
    "ModelError",
    "MoveProblem",
    "PiecewiseConstant",
    "PlannerConfig",
    "SampledProfile",
    "SolverError",
    "chain",
    "config_from_parameters",
    "crane",
    "final_state",
    "load_config",
    "modal_amplitudes",
    "motion_to_rest",
    "plan_time_optimal",
    "plan_zoh",
    "rest_to_rest",
    "simulate",
    "simulate_samples",
    "state_to_rest",
    "two_mass",
    "write_config",
]
