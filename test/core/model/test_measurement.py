"""The measurement map ``y = C x + D u`` against an independent simulation of the PHYSICAL crane.

The crane's cart position ``x``, rope angle ``theta`` (small angles, force ``f`` on the cart)::

    M x'' = f + m g theta,      L theta'' = -g theta - x''

simulated here by the matrix exponential of these equations (not the modal model), read as a cart
encoder, a payload position, a rope angle, a payload velocity and a cart accelerometer.
"""

import math

import numpy as np
import pytest
from scipy.linalg import expm

from flexmotion_ros.core.config import config_from_parameters
from flexmotion_ros.core.errors import ConfigError
from flexmotion_ros.core.model.builders import crane, two_mass
from flexmotion_ros.core.model.measurement import (
    MeasurementKind,
    builder_map,
    default_map,
    measurement_map,
    noise_levels,
)
from flexmotion_ros.core.simulation.exact import simulate_samples

M, MP, L, G = 20.0, 5.0, 2.0, 9.81


def physical_crane(u: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """States ``[x, x', theta, theta']`` before each held sample, and the cart's acceleration just after it."""
    A = np.array(
        [
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, MP * G / M, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            [0.0, 0.0, -G / L - MP * G / (M * L), 0.0],
        ]
    )
    B = np.array([0.0, 1.0 / M, 0.0, -1.0 / (M * L)])
    E = expm(np.block([[A, B[:, None]], [np.zeros((1, 5))]]) * dt)
    x = np.zeros(4)
    states, acc = [], []
    for uk in u:
        states.append(x.copy())
        acc.append((uk + MP * G * x[2]) / M)
        x = E[:4, :4] @ x + E[:4, 4] * uk
    return np.array(states), np.array(acc)


def test_crane_readings_match_the_physical_equations():
    built = crane(M, MP, L)
    base = builder_map(built)
    assert base.names == ("cart", "payload", "rope_angle")
    params = {
        "measurement.names": ["cart", "payload", "rope_angle", "payload_velocity", "cart_acceleration"],
        "measurement.map": [*base.map.ravel(), *base.map[1], *base.map[0]],
        "measurement.kinds": ["position", "position", "position", "velocity", "acceleration"],
    }
    mm = measurement_map(params, built.model.n_modes)
    C, D = mm.for_model(built.model)
    assert np.count_nonzero(D) == 1 and D[4] == pytest.approx(1.0 / M, rel=1e-14)  # feedthrough: 1/M
    rng = np.random.default_rng(3)
    dt = 0.01
    u = rng.uniform(-50.0, 50.0, 400)
    x_modal = simulate_samples(built.model, built.model.rest_state(), u, dt)[:-1]
    y = x_modal @ C.T + D[None, :] * u[:, None]
    phys, acc = physical_crane(u, dt)
    expected = np.column_stack([phys[:, 0], phys[:, 0] + L * phys[:, 2], phys[:, 2], phys[:, 1] + L * phys[:, 3], acc])
    scale = np.max(np.abs(expected), axis=0)
    np.testing.assert_allclose(y / scale, expected / scale, rtol=0, atol=1e-10)


def test_default_map_is_the_rigid_body_position():
    mm = measurement_map({}, 2)
    assert mm == default_map(2) and mm.names == ("rigid_body",) and np.array_equal(mm.map, [[1.0, 0.0, 0.0]])
    model = two_mass(1.0, 1.0, 1.0).model
    C, D = measurement_map({}, 1).for_model(model)
    np.testing.assert_array_equal(C, [[1.0, 0.0, 0.0, 0.0]])
    assert not D.any() and mm.kinds == (MeasurementKind.POSITION,)


@pytest.mark.parametrize(
    ("params", "name", "text"),
    [
        ({"measurement.names": ["a"], "measurement.map": [1.0]}, "measurement.map", "1 x 2 = 2 values"),
        ({"measurement.map": [1.0, 0.0]}, "measurement.names", "must name the channels"),
        ({"measurement.names": ["a", "a"], "measurement.map": [1.0] * 4}, "measurement.names", "unique"),
        ({"measurement.names": ["a"], "measurement.map": [0.0, 0.0]}, "measurement.map", "all zero"),
        ({"measurement.names": ["a"], "measurement.map": [1.0, math.nan]}, "measurement.map[1]", "finite"),
        (
            {"measurement.names": ["a"], "measurement.map": [1.0, 0.0], "measurement.kinds": ["positon"]},
            "measurement.kinds[0]",
            "(closest: 'position')",
        ),
        (
            {"measurement.names": ["a"], "measurement.map": [1.0, 0.0], "measurement.kinds": ["position"] * 2},
            "measurement.kinds",
            "one kind per name (1)",
        ),
    ],
)
def test_bad_maps_are_refused_naming_the_parameter(params, name, text):
    with pytest.raises(ConfigError) as err:
        measurement_map(params, 1)
    assert err.value.parameter == name and text in str(err.value), str(err.value)
    # the configuration (flexmotion plan, the planner node) gives the same verdict
    model = {"model.omega": [2.0], "model.zeta": [0.0], "model.b": [1.0]}
    with pytest.raises(ConfigError) as err2:
        config_from_parameters({**model, **params})
    assert str(err2.value) == str(err.value)


def test_noise_levels():
    np.testing.assert_array_equal(noise_levels(0.1, 3), [0.1] * 3)
    np.testing.assert_array_equal(noise_levels([0.1, 0.0, 2.0], 3), [0.1, 0.0, 2.0])
    for bad in ([0.1, 0.2], -1.0, math.inf):
        with pytest.raises(ConfigError, match="plant.noise_std"):
            noise_levels(bad, 3)
