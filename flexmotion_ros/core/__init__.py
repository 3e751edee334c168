"""The ROS-free numerical core (numpy/scipy only).

Typical use::

    from flexmotion_ros.core import ModalModel, rest_to_rest, plan_time_optimal, plan_time_optimal_zoh

    model = ModalModel(b0=0.5, omega=[2 ** 0.5], zeta=[0.0], b=[1.0])
    profile = plan_time_optimal(rest_to_rest(model, u_max=1.0, gamma=1.0))
    profile.duration, profile.switch_times, profile.certified
"""

from .config import PlannerConfig, config_from_parameters, load_config, write_config
from .errors import ConfigError, FlexmotionError, GoalError, InputError, ModelError, SolverError, UnreachableError
from .model.boundary import MoveProblem, motion_to_rest, rest_to_rest, state_to_rest
from .model.builders import BuiltModel, chain, crane, two_mass
from .model.modal_model import ModalModel
from .results import BangBangProfile, Certificate, SampledProfile
from .sampled.zoh import plan_time_optimal_zoh
from .simulation.exact import (
    PiecewiseConstant,
    final_state,
    modal_amplitudes,
    simulate,
    simulate_samples,
)
from .time_optimal.solver import plan_time_optimal

__all__ = [
    "BangBangProfile",
    "BuiltModel",
    "Certificate",
    "ConfigError",
    "FlexmotionError",
    "InputError",
    "GoalError",
    "ModalModel",
    "ModelError",
    "MoveProblem",
    "PiecewiseConstant",
    "PlannerConfig",
    "SampledProfile",
    "SolverError",
    "UnreachableError",
    "chain",
    "config_from_parameters",
    "crane",
    "final_state",
    "load_config",
    "modal_amplitudes",
    "motion_to_rest",
    "plan_time_optimal",
    "plan_time_optimal_zoh",
    "rest_to_rest",
    "simulate",
    "simulate_samples",
    "state_to_rest",
    "two_mass",
    "write_config",
]
