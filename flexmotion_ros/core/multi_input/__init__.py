"""Several inputs (seed eq. 2.1 with ``m`` inputs): the model, its parameter layout, builders and planners.

Typical use::

    from flexmotion_ros.core.multi_input import gantry, multi_rest_to_rest, plan_multi_move

    g = gantry(10.0, 40.0, 5.0, 2.0, trolley_force=30.0, bridge_force=50.0)
    result = plan_multi_move(multi_rest_to_rest(g.model, g.u_max, [3.0, 2.0]), rate_hz=1000.0)
    result.summary()  # duration, switch_times, levels (rows of m), certified, sync, samples, commands (K x m)
"""

from .builders import MULTI_BUILDERS, MultiBuiltModel, gantry, multi_chain, multi_two_mass
from .exact import VectorPiecewise
from .fixed_time import plan_multi_fixed_time, plan_multi_fixed_time_zoh
from .fuel import plan_multi_min_fuel_zoh
from .methods import MULTI_METHODS, REFUSED, MultiPlanResult, check_multi_method, plan_multi_move
from .model import MultiModel
from .parse import (
    PARAMETER_NAMES,
    SYNC_VALUES,
    MultiSetup,
    is_multi_input,
    multi_model_from_parameters,
    multi_setup_from_parameters,
)
from .parts import decoupled_parts
from .phase import plan_phase
from .problem import MultiMoveProblem, multi_rest_to_rest, multi_state_to_rest
from .results import MultiCertificate, MultiProfile, MultiSampledProfile, PartRole, SyncMode
from .shaped import plan_multi_shaped, sample_profile
from .time_optimal import check_sync, plan_multi_time_optimal
from .zoh import plan_multi_time_optimal_zoh

__all__ = [
    "MULTI_BUILDERS",
    "MULTI_METHODS",
    "PARAMETER_NAMES",
    "REFUSED",
    "SYNC_VALUES",
    "MultiBuiltModel",
    "MultiCertificate",
    "MultiModel",
    "MultiMoveProblem",
    "MultiPlanResult",
    "MultiProfile",
    "MultiSampledProfile",
    "MultiSetup",
    "PartRole",
    "SyncMode",
    "VectorPiecewise",
    "check_multi_method",
    "check_sync",
    "decoupled_parts",
    "gantry",
    "is_multi_input",
    "multi_chain",
    "multi_model_from_parameters",
    "multi_rest_to_rest",
    "multi_setup_from_parameters",
    "multi_state_to_rest",
    "multi_two_mass",
    "plan_multi_fixed_time",
    "plan_multi_fixed_time_zoh",
    "plan_multi_min_fuel_zoh",
    "plan_multi_move",
    "plan_multi_shaped",
    "plan_multi_time_optimal",
    "plan_multi_time_optimal_zoh",
    "plan_phase",
    "sample_profile",
]
