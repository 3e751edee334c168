"""Identification of the modal model from measured moves, with standard errors and 95 % intervals.

Entry points: :func:`identify` (data -> :class:`IdentificationResult`, whose
``to_model()`` is a :class:`~flexmotion_ros.core.model.modal_model.ModalModel`
and ``to_dict()`` plain values for JSON), :func:`design_excitation` (a
bounded rest-to-rest excitation for a frequency band) and the data checks.
"""

from .data import IdentificationData, SensorOutput, check_data
from .identify import identify
from .response import OutputKind
from .result import Estimate, IdentificationResult, ModeEstimate, ModeSelection, OutputFit

__all__ = [
    "Estimate",
    "IdentificationData",
    "IdentificationResult",
    "ModeEstimate",
    "ModeSelection",
    "OutputFit",
    "OutputKind",
    "SensorOutput",
    "check_data",
    "identify",
]
