"""The Kalman filter against hidden-truth data: an independent expm simulation with known noise.

Consistency is judged with the chi-square bounds of the normalised errors
over independent seeds (NEES: the state error against the filter's
covariance; NIS: the innovations), and a model error must show as a bias.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.stats import chi2

from flexmotion_ros.core.config import PlannerConfig
from flexmotion_ros.core.errors import ConfigError, ModelError
from flexmotion_ros.core.estimation import (
    initial_estimate,
    kalman_model,
    measurement_matrix,
    predict,
    run_filter,
    update,
)
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.model.boundary import rest_to_rest
from flexmotion_ros.core.model.builders import chain, crane

BUILT = crane(20.0, 5.0, 2.0, zeta=0.005)
MODEL = BUILT.model
DT = 0.01
SIGMA_W = 1.0  # N, input disturbance held over each sample
SIGMA_Y = 0.002  # m, position sensors
RUNS, STEPS = 40, 300


@pytest.fixture(scope="module")
def commands() -> np.ndarray:
    cfg = PlannerConfig(model=MODEL, u_max=50.0, rate_hz=1.0 / DT)
    u = np.asarray(plan_move(cfg, rest_to_rest(MODEL, 50.0, 2.0), 1.0 / DT).sampled.commands, float)
    return np.concatenate([u, np.zeros(max(0, STEPS - u.size))])[:STEPS]


def truth(model, x0, commands, rng, C, sigma_w=SIGMA_W, sigma_y=SIGMA_Y):
    """States and measurements of the hidden plant: its own augmented expm, its own noise."""
    n = model.n_states
    M = np.zeros((n + 1, n + 1))
    M[:n, :n], M[:n, n] = model.A(), model.B()
    E = expm(M * DT)
    x = np.array(x0, float)
    xs, ys = [], []
    for u in commands:
        xs.append(x)
        ys.append(C @ x + sigma_y * rng.standard_normal(C.shape[0]))
        x = E[:n, :n] @ x + E[:n, n] * (u + sigma_w * rng.standard_normal())
    return np.array(xs), np.array(ys)


def moving_start(rng) -> np.ndarray:
    return np.array([0.3, 0.2, 0.05, -0.1]) + rng.normal(0.0, [0.05, 0.05, 0.02, 0.05])


def test_measurement_rows_from_the_builders_map():
    C = measurement_matrix(BUILT)
    x = np.array([1.0, 0.5, 0.2, -0.3])
    np.testing.assert_allclose(C @ x, BUILT.physical_positions(x))
    Cv = measurement_matrix(BUILT, ["payload"], velocities=True)
    assert Cv.shape == (2, 4) and Cv[1] @ x == pytest.approx(0.5 + Cv[0, 2] * -0.3)
    with pytest.raises(ConfigError, match="unknown coordinate 'hook'"):
        measurement_matrix(BUILT, ["hook"])


def test_the_swing_no_sensor_measures_is_estimated_from_the_cart_alone(commands):
    """Only the cart position is measured; the filter, started wrong, finds the swing within its own bounds."""
    C = measurement_matrix(BUILT, ["cart"])
    km = kalman_model(MODEL, DT, C, SIGMA_Y, input_noise_std=SIGMA_W)
    rng = np.random.default_rng(11)
    xs, ys = truth(MODEL, moving_start(rng), commands, rng, C)
    run = run_filter(km, initial_estimate(km, np.zeros(4), [1.0, 1.0, 0.5, 0.5]), commands, ys)
    err = run.x - xs
    sd = np.sqrt(np.einsum("kii->ki", run.P))
    assert abs(err[0, 2]) > 0.02  # it starts wrong on the swing ...
    late = slice(STEPS // 2, None)
    assert np.max(np.abs(err[late, 2:]) / sd[late, 2:]) < 4.5  # ... and ends within its own bounds
    assert np.max(np.abs(err[late, 2])) < 0.1 * np.max(np.abs(xs[:, 2]))  # a small fraction of the swing


def test_nees_and_nis_are_chi_square_consistent_over_seeds(commands):
    C = measurement_matrix(BUILT)
    km = kalman_model(MODEL, DT, C, SIGMA_Y, input_noise_std=SIGMA_W)
    n, m = km.n_states, km.n_measurements
    nees = np.empty((RUNS, STEPS))
    nis = np.empty((RUNS, STEPS))
    P0 = np.array([0.05, 0.05, 0.02, 0.05])
    for r in range(RUNS):
        rng = np.random.default_rng(1000 + r)
        x0 = np.array([0.3, 0.2, 0.05, -0.1]) + P0 * rng.standard_normal(4)
        xs, ys = truth(MODEL, x0, commands, rng, C)
        run = run_filter(km, initial_estimate(km, [0.3, 0.2, 0.05, -0.1], P0), commands, ys)
        e = run.x - xs
        nees[r] = np.einsum("ki,kij,kj->k", e, np.linalg.inv(run.P), e)
        nis[r] = run.nis
    lo, hi = chi2.ppf([0.025, 0.975], RUNS * n) / RUNS
    inside = np.mean((nees.mean(axis=0) >= lo) & (nees.mean(axis=0) <= hi))
    assert inside > 0.88, inside  # 95 % expected at each step (independent seeds)
    # innovations are white in time: the total NIS is chi-square with RUNS * STEPS * m degrees of freedom
    dof = RUNS * STEPS * m
    lo, hi = chi2.ppf([0.0005, 0.9995], dof)
    assert lo <= nis.sum() <= hi, (nis.sum() / dof, lo / dof, hi / dof)


def test_a_model_error_shows_as_a_bias(commands):
    """The plant swings 5 % faster than the model: innovations too large, swing estimate biased."""
    C = measurement_matrix(BUILT)
    km = kalman_model(MODEL, DT, C, SIGMA_Y, input_noise_std=0.2)
    plant = MODEL.with_changes(omega=(1.05 * MODEL.omega[0],))
    results = {}
    for name, hidden in (("exact", MODEL), ("5% error", plant)):
        nis, err = [], []
        for r in range(20):
            rng = np.random.default_rng(2000 + r)
            xs, ys = truth(hidden, MODEL.rest_state(0.0), commands, rng, C, sigma_w=0.2)
            run = run_filter(km, initial_estimate(km, MODEL.rest_state(0.0), 1e-6), commands, ys)
            nis.append(run.nis)
            err.append(run.x[:, 2] - xs[:, 2])
        err = np.array(err)
        t_stat = np.abs(err.mean(axis=0)) / (err.std(axis=0, ddof=1) / math.sqrt(err.shape[0]))
        results[name] = (np.mean(nis) / km.n_measurements, float(np.mean(t_stat > 4.0)))
    lo, hi = chi2.ppf([0.0005, 0.9995], 20 * STEPS * km.n_measurements) / (20 * STEPS * km.n_measurements)
    assert lo <= results["exact"][0] <= hi and results["exact"][1] < 0.01, results
    assert results["5% error"][0] > 3.0 * hi and results["5% error"][1] > 0.2, results


def test_steady_state_gain_is_the_limit_of_the_time_varying_filter(commands):
    C = measurement_matrix(BUILT)
    km = kalman_model(MODEL, DT, C, SIGMA_Y, input_noise_std=SIGMA_W)
    ks = kalman_model(MODEL, DT, C, SIGMA_Y, input_noise_std=SIGMA_W, steady_state=True)
    est = initial_estimate(km, np.zeros(4), 1.0)
    for _ in range(3000):
        est, _ = update(km, est, np.zeros(2))
        est = predict(km, est, 0.0)
    np.testing.assert_allclose(est.P, ks.steady_covariance, rtol=1e-6, atol=1e-14)
    # the same data through both filters: started from the limit covariance, the time-varying filter stays there
    rng = np.random.default_rng(5)
    xs, ys = truth(MODEL, moving_start(rng), commands, rng, C)
    from_limit = initial_estimate(km, xs[0], 0.0)
    from_limit = type(from_limit)(x=from_limit.x, P=ks.steady_covariance.copy())
    a = run_filter(km, from_limit, commands, ys)
    b = run_filter(ks, initial_estimate(ks, xs[0], 0.0), commands, ys)
    assert np.max(np.abs(a.x - b.x)) < 1e-6 * np.max(np.sqrt(np.diag(ks.steady_covariance)))
    np.testing.assert_allclose(b.nis, a.nis, rtol=1e-5)
    with pytest.raises(ConfigError, match="input_noise_std"):
        kalman_model(MODEL, DT, C, SIGMA_Y, steady_state=True)


def test_unobservable_parts_are_refused_with_their_name():
    with pytest.raises(ModelError, match="the rigid body cannot be observed"):
        kalman_model(MODEL, DT, [[0.0, 0.0, 1.0, 0.0]], 1e-3)  # the swing alone: where is the crane?
    three = chain([1.0, 1.0, 1.0], [100.0, 100.0])
    middle = measurement_matrix(three, ["x2"])  # a node of the first mode (the ends swing against each other)
    with pytest.raises(ModelError, match="mode mode_1 cannot be observed"):
        kalman_model(three.model, DT, middle, 1e-3)
    kalman_model(three.model, DT, measurement_matrix(three, ["x1"]), 1e-3)
    for bad in ({"measurement_std": None}, {"measurement_std": -1.0}, {"measurement_std": 1e-3, "input_noise_std": -1}):
        with pytest.raises(ConfigError):
            kalman_model(MODEL, DT, measurement_matrix(BUILT), **bad)
    with pytest.raises(ConfigError, match="measurement.rows"):
        kalman_model(MODEL, DT, [[1.0, 0.0]], 1e-3)
