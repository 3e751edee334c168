"""Joint references integrated from a ZOH plan, and the acceleration-input builders, against independent expm."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm

from flexmotion_ros.cli.main import main
from flexmotion_ros.core.config import load_config
from flexmotion_ros.core.errors import ConfigError, ModelError
from flexmotion_ros.core.interfaces import (
    CommandInterface,
    check_acceleration_model,
    command_interface,
    hold_setpoint,
    joint_reference,
    reference_for,
    setpoints,
    velocity_limit_option,
)
from flexmotion_ros.core.model.builders import crane, crane_acceleration, two_mass_acceleration
from flexmotion_ros.core.model.modal_model import ModalModel


def rigid_expm(b0: float, c: float, p0: float, v0: float, u, dt: float) -> np.ndarray:
    """``[p, v]`` at every sample by the augmented exponential of the rigid body alone (no shared code)."""
    M = np.zeros((3, 3))
    M[0, 1], M[1, 1], M[1, 2] = 1.0, c, b0
    E = expm(M * dt)
    x = np.array([p0, v0])
    out = [x]
    for uk in u:
        x = E[:2, :2] @ x + E[:2, 2] * uk
        out.append(x)
    return np.array(out)


@pytest.mark.parametrize(("b0", "c"), [(1.0, 0.0), (0.5, 0.0), (0.04, -0.3)])
def test_reference_is_the_exact_rigid_body_propagation(b0, c):
    rng = np.random.default_rng(0)
    u = rng.uniform(-1.0, 1.0, 500)
    dt = 1e-3 * math.pi  # not a round number
    model = ModalModel(b0=b0, c=c, omega=[3.0], zeta=[0.01], b=[0.7])
    ref = joint_reference(model, u, dt, 0.3, -0.2)
    want = rigid_expm(b0, c, 0.3, -0.2, u, dt)
    scale = np.max(np.abs(want), axis=0)
    assert np.max(np.abs(ref.positions - want[:, 0])) < 1e-12 * scale[0]
    assert np.max(np.abs(ref.velocities - want[:, 1])) < 1e-12 * scale[1]
    if c == 0.0:
        np.testing.assert_array_equal(ref.accelerations, b0 * u)
        # inside an interval: the exact quadratic / linear (an expm over a partial step)
        for k, s in [(0, 0.0), (17, 0.3 * dt), (499, 0.999 * dt)]:
            part = rigid_expm(b0, c, ref.positions[k], ref.velocities[k], [u[k]], s)[-1]
            assert ref.position_at(k * dt + s) == pytest.approx(part[0], abs=1e-13)
            assert ref.velocity_at(k * dt + s) == pytest.approx(part[1], abs=1e-13)
        assert ref.position_at(-1.0) == ref.positions[0] and ref.velocity_at(1e9) == ref.velocities[-1]


def test_setpoints_are_the_values_due_at_the_end_of_each_interval():
    model = crane_acceleration(2.0).model
    u = np.array([1.0, 1.0, -1.0, -1.0])
    ref = joint_reference(model, u, 0.1, 2.0)
    np.testing.assert_allclose(ref.velocities, [0.0, 0.1, 0.2, 0.1, 0.0], atol=1e-15)
    np.testing.assert_allclose(ref.positions, [2.0, 2.005, 2.02, 2.035, 2.04], atol=1e-15)
    np.testing.assert_array_equal(setpoints(ref, "effort"), u)
    np.testing.assert_array_equal(setpoints(ref, "velocity"), ref.velocities[1:])
    np.testing.assert_array_equal(setpoints(ref, CommandInterface.POSITION), ref.positions[1:])
    assert hold_setpoint(ref, "effort") == 0.0 and hold_setpoint(ref, "velocity") == 0.0
    assert hold_setpoint(ref, "position") == ref.positions[-1]  # the hold of a position joint is where it ended


def test_command_interface_names_and_refusals():
    assert command_interface("Velocity") is CommandInterface.VELOCITY
    assert not CommandInterface.EFFORT.acceleration_input and CommandInterface.POSITION.acceleration_input
    with pytest.raises(ConfigError, match=r"command_interface: .*did you mean velocity"):
        command_interface("velocty")
    with pytest.raises(ConfigError, match="command_interface"):
        command_interface(3)
    viscous = ModalModel(b0=1.0, c=-0.1)
    check_acceleration_model(viscous, CommandInterface.EFFORT)
    with pytest.raises(ModelError, match=r"model.c: must be 0.0 for command_interface velocity"):
        reference_for(viscous, [1.0], 0.01, viscous.rest_state(), "velocity")
    assert velocity_limit_option(0.5, "position") == {"limits.velocity_max": 0.5}
    for bad in (0.0, -1.0, math.inf, "x"):
        with pytest.raises(ConfigError, match="velocity_limit"):
            velocity_limit_option(bad, "velocity")


def physical_cart_pendulum(L: float, g: float, zeta: float, x0, a, dt: float) -> np.ndarray:
    """Cart position and payload position under a prescribed cart acceleration, from the angle equation.

    State ``[x_c, x_c', theta, theta']``: ``theta'' = -(g/L) theta - 2 zeta w theta' - a / L``.
    """
    w = math.sqrt(g / L)
    A = np.array([[0, 1, 0, 0], [0, 0, 0, 0], [0, 0, 0, 1], [0, 0, -(w**2), -2 * zeta * w]], float)
    B = np.array([0.0, 1.0, 0.0, -1.0 / L])
    M = np.zeros((5, 5))
    M[:4, :4], M[:4, 4] = A, B
    E = expm(M * dt)
    x = np.array(x0, float)
    out = []
    for ak in a:
        x = E[:4, :4] @ x + E[:4, 4] * ak
        out.append([x[0], x[0] + L * x[2]])
    return np.array(out)


def test_crane_with_acceleration_input_is_the_pendulum_on_a_driven_cart():
    L, g, zeta = 2.5, 9.81, 0.02
    built = crane(None, None, L, g, zeta, input="acceleration")
    same = crane_acceleration(L, g, zeta)
    assert built.model == same.model and np.array_equal(built.modal_to_physical, same.modal_to_physical)
    m = built.model
    assert m.b0 == 1.0 and m.c == 0.0 and m.b == (-1.0,) and m.omega[0] == pytest.approx(math.sqrt(g / L))
    rng = np.random.default_rng(4)
    a = rng.uniform(-1, 1, 300)
    dt = 0.01
    E = expm(np.block([[m.A(), m.B()[:, None]], [np.zeros((1, m.n_states + 1))]]) * dt)
    x = m.rest_state(0.0)
    modal = []
    for ak in a:
        x = E[:-1, :-1] @ x + E[:-1, -1] * ak
        modal.append(built.physical_positions(x))
    np.testing.assert_allclose(np.array(modal), physical_cart_pendulum(L, g, zeta, [0, 0, 0, 0], a, dt), atol=1e-12)
    with pytest.raises(ModelError, match="input"):
        crane(20.0, 5.0, L, input="torque")
    with pytest.raises(ModelError, match="cart_mass"):
        crane(None, 5.0, L)


def test_two_mass_with_acceleration_input():
    built = two_mass_acceleration(m2=2.0, k=8.0, d=0.4)
    m = built.model
    assert m.omega[0] == pytest.approx(2.0) and m.zeta[0] == pytest.approx(0.4 / (2 * 4.0)) and m.b == (1.0,)
    # x2'' = (k s + d s') / m2 with s = x1 - x2: the rigid body is mass 1 and x2 = p - s
    x = np.array([0.0, 1.0, 0.1, -0.2])  # p, v, s, s'
    acc = m.A() @ x + m.B() * 0.5
    s, sd = x[2], x[3]
    assert acc[1] == 0.5 and acc[1] - acc[3] == pytest.approx((8.0 * s + 0.4 * sd) / 2.0)
    assert built.physical_positions(x)[1] == pytest.approx(x[0] - s)


def test_model_crane_input_acceleration_writes_a_planable_file(tmp_path, capsys):
    path = tmp_path / "crane_acc.yaml"
    args = ["model", "crane", "--cable-length", "2", "--input", "acceleration", "--u-max", "0.5", "-o", str(path)]
    assert main(args) == 0
    capsys.readouterr()
    text = path.read_text()
    assert "cart acceleration" in text and "u_max is the acceleration bound" in text
    cfg = load_config(path)
    assert cfg.model.b0 == 1.0 and cfg.model.b == (-1.0,) and cfg.u_max == 0.5
    assert cfg.model.omega[0] == pytest.approx(math.sqrt(9.81 / 2.0))
    assert main(["model", "crane", "--cable-length", "2"]) == 2
    assert "cart_mass: --cart-mass is required with --input force" in capsys.readouterr().err
