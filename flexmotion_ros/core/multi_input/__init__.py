"""Several inputs: the multi-input model (seed eq. 2.1 with ``m`` inputs) and its planners."""

from .model import MultiModel, decoupled_parts
from .parse import multi_model_from_parameters, multi_setup_from_parameters
from .problem import MultiMoveProblem, multi_rest_to_rest, multi_state_to_rest
from .results import MultiCertificate, MultiProfile, MultiSampledProfile, SyncMode
from .time_optimal import plan_multi_time_optimal

__all__ = [
    "MultiCertificate",
    "MultiModel",
    "MultiMoveProblem",
    "MultiProfile",
    "MultiSampledProfile",
    "SyncMode",
    "decoupled_parts",
    "multi_model_from_parameters",
    "multi_rest_to_rest",
    "multi_setup_from_parameters",
    "multi_state_to_rest",
    "plan_multi_time_optimal",
]
