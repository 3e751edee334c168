"""State estimation on the planner's modal model: a discrete Kalman filter fed with commands and measurements."""

from .kalman import (
    Estimate,
    FilterRun,
    Innovation,
    KalmanModel,
    check_observable,
    initial_estimate,
    kalman_model,
    measurement_matrix,
    predict,
    run_filter,
    update,
)

__all__ = [
    "Estimate",
    "FilterRun",
    "Innovation",
    "KalmanModel",
    "check_observable",
    "initial_estimate",
    "kalman_model",
    "measurement_matrix",
    "predict",
    "run_filter",
    "update",
]
