"""The stream's state estimator (issue 14): readings paired with commands by stamp, against the hidden truth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flexmotion_ros.core.errors import ConfigError, ModelError
from flexmotion_ros.core.model.modal_model import ModalModel
from flexmotion_ros.core.simulation.exact import step_matrices
from flexmotion_ros.execution.feedback import (
    STALE_PERIODS,
    FeedbackSettings,
    StreamEstimate,
    StreamEstimator,
    feedback_settings,
    stale_reason,
)

WB = ModalModel(b0=0.5, omega=[2**0.5], zeta=[0.0], b=[1.0])
DT = 0.01
#: Both masses of the two-mass machine: x1 = p + q / 2, x2 = p - q / 2 (positions; no feedthrough).
C = np.array([[1.0, 0.0, 0.5, 0.0], [1.0, 0.0, -0.5, 0.0]])


def drive(est: StreamEstimator, truth_model: ModalModel, u, *, holds: int, lose=(), noise=0.0, seed=3):
    """Send holds then ``u`` (one per 10 ms of system time); the plant reads y_k before applying u_k."""
    Phi, Gam = step_matrices(truth_model.A(), truth_model.B(), DT)
    rng = np.random.default_rng(seed)
    x = truth_model.rest_state(0.0)
    t = 10**12
    sent = np.concatenate([np.zeros(holds), u])
    est.restart(holds, x)
    for k, uk in enumerate(sent):
        est.command(k, float(uk), t)
        if k not in lose:
            est.measurement(t + 30_000, C @ x + noise * rng.standard_normal(2))  # stamped with the send time (DDS)
        x = Phi @ x + Gam * uk
        t += 10_000_000
    return x, holds + len(u)


def test_with_an_exact_model_the_estimate_is_the_truth_and_lost_readings_are_predicted():
    est = StreamEstimator(WB, DT, FeedbackSettings(replan_period_s=0.1), C)
    u = np.sign(np.sin(np.arange(80) / 7.0))
    x, n = drive(est, WB, u, holds=12, lose={30, 31, 55})
    e = est.estimate()
    # the last reading is of the state before the last command: one predicted step, exact with an exact model
    assert e.sample == n and e.measured_to == n - 1
    np.testing.assert_allclose(e.x, x, rtol=0, atol=1e-9)
    assert est.used == 80 - 3 - 1  # every reading of the move but the lost ones and the last (its pair is pending)


def test_with_a_wrong_model_the_filter_follows_the_readings():
    """5 % frequency error: the model alone ends 7e-2 off; the filter's error is its last two steps' prediction."""
    est = StreamEstimator(WB, DT, FeedbackSettings(replan_period_s=0.1, measurement_std=1e-6), C)
    truth = WB.with_changes(omega=(1.05 * 2**0.5,))
    u = np.sign(np.sin(np.arange(300) / 23.0))
    x, _ = drive(est, truth, u, holds=0, noise=1e-6)
    e = est.estimate()
    Phi, Gam = step_matrices(WB.A(), WB.B(), DT)
    alone = WB.rest_state(0.0)
    for uk in u:
        alone = Phi @ alone + Gam * uk
    err = np.abs(e.x - x)
    assert np.max(np.abs(alone - x)) > 0.05
    assert err[0] < 1e-4 and err[2] < 1e-4 and np.max(err) < 0.005, err  # positions read; velocities inferred


def test_unobservable_readings_and_bad_settings_are_refused():
    with pytest.raises(ModelError, match="mode"):
        StreamEstimator(WB, DT, FeedbackSettings(replan_period_s=0.1), [[1.0, 0.0, 0.0, 0.0]])  # the rigid body only
    with pytest.raises(ConfigError, match="feedback.replan_period_s"):
        feedback_settings({"feedback.replan_period_s": -0.1})
    with pytest.raises(ConfigError, match="feedback.min_deviation"):
        feedback_settings({"feedback.min_deviation": 0.0})


def test_an_estimate_predicted_long_without_readings_is_stale():
    limit = math.ceil(STALE_PERIODS * 0.1 * 100.0)  # samples: two 0.1 s periods at 100 Hz
    fresh = StreamEstimate(x=np.zeros(4), P=np.eye(4), sample=500, measured_to=500 - limit)
    late = StreamEstimate(x=np.zeros(4), P=np.eye(4), sample=500, measured_to=500 - limit - 1)
    assert stale_reason(fresh, 0.1, 100.0) is None
    reason = stale_reason(late, 0.1, 100.0)
    assert reason is not None and f"{limit + 1} samples predicted" in reason
