"""The plant's ``measurements`` topic: the true model's physical coordinates, read just after each command.

Checked against an exact simulation made here (matrix exponentials of the held commands on the
plant's TRUE model, ``plant.omega_scale`` / ``plant.extra_zeta`` applied), with the noise the seed
gives, stamped with the send time of the command each reading follows.
"""

from __future__ import annotations

import threading

import numpy as np
import pytest
from sensor_msgs.msg import JointState

from flexmotion_ros.core.config import config_from_parameters
from flexmotion_ros.core.errors import ConfigError
from flexmotion_ros.core.model.builders import crane
from flexmotion_ros.core.model.measurement import builder_map
from flexmotion_ros.core.simulation.exact import simulate_samples
from flexmotion_ros.nodes import messages
from flexmotion_ros.nodes.plant_measurements import MEASUREMENT_QOS
from flexmotion_ros.nodes.plant_node import PlantNode

from .conftest import NAMESPACE, overrides, wait_for

BUILT = crane(20.0, 5.0, 0.5)  # swing at 4.95 rad/s; input: force on the cart (N)


def crane_parameters(**extra) -> dict:
    base = builder_map(BUILT)
    m = BUILT.model
    return {
        "model.b0": m.b0,
        "model.omega": list(m.omega),
        "model.zeta": [0.0],
        "model.b": list(m.b),
        "rate_hz": 100.0,
        # cart, payload and rope angle, the payload's velocity and the cart's acceleration (feedthrough)
        "measurement.names": [*base.names, "payload_velocity", "cart_acceleration"],
        "measurement.map": [*base.map.ravel(), *base.map[1], *base.map[0]],
        "measurement.kinds": ["position"] * 3 + ["velocity", "acceleration"],
        **extra,
    }


class Recorder:
    def __init__(self, node) -> None:
        self.lock = threading.Lock()
        self.msgs: list[JointState] = []
        self.sub = node.create_subscription(JointState, "measurements", self._on, MEASUREMENT_QOS)

    def _on(self, msg: JointState) -> None:
        with self.lock:
            self.msgs.append(msg)

    def readings(self) -> tuple[list[str], np.ndarray, np.ndarray]:
        with self.lock:
            msgs = list(self.msgs)
        names = list(msgs[0].name) if msgs else []
        stamps = np.array([m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec for m in msgs])
        return names, np.array([list(m.position) for m in msgs]), stamps


def test_lockstep_measurements_are_the_true_models_readings_with_seeded_noise(ros):
    noise = [0.0, 1e-3, 1e-3, 0.0, 2e-2]
    params = crane_parameters(
        **{"plant.omega_scale": [1.12], "plant.extra_zeta": [0.03], "plant.noise_std": noise, "plant.noise_seed": 11}
    )
    plant = ros.plant(**params)
    rec = Recorder(ros.probe)
    probe = ros.probe
    wait_for(lambda: plant._measure.subscription_count() >= 1, 10.0, "the measurements subscription")
    wait_for(lambda: probe.command_pub.get_subscription_count() >= 2, 10.0, "the plant's commands subscription")
    u = np.random.default_rng(5).uniform(-50.0, 50.0, 300)
    for uk in u:
        probe.command_pub.publish(messages.command(float(uk)))
    wait_for(lambda: len(rec.msgs) >= u.size and len(probe.commands) >= u.size, 20.0, "300 readings")
    names, y, stamps = rec.readings()
    assert names == ["cart", "payload", "rope_angle", "payload_velocity", "cart_acceleration"]
    assert y.shape == (u.size, 5)
    with rec.lock:
        assert all(not m.velocity and not m.effort for m in rec.msgs)
    # the TRUE model: the file's swing 12 % faster, damping 0.03
    true = plant.cfg.model
    assert true.omega[0] == pytest.approx(1.12 * BUILT.model.omega[0]) and true.zeta == (0.03,)
    x = simulate_samples(true, true.rest_state(), u, 0.01)[:-1]  # x_k before command k
    C, D = plant.cfg.measurement.for_model(true)
    rng = np.random.default_rng(11)
    expected = x @ C.T + D * u[:, None] + np.array(noise) * rng.standard_normal((u.size, 5))
    scale = np.max(np.abs(expected), axis=0)
    np.testing.assert_allclose(y / scale, expected / scale, rtol=0, atol=1e-12)
    # y_k read just after u_k is applied: the accelerometer jumps with the command at the same sample
    jumps = np.diff(y[:, 4])  # noisy, but the feedthrough u/M dominates
    assert np.corrcoef(jumps, np.diff(u))[0, 1] > 0.9
    # stamped with the send time of the command each reading follows
    sent = np.array([t for _, _, t in probe.commands[: u.size]])
    np.testing.assert_array_equal(stamps, sent)
    plant.publish_diagnostics()
    assert plant._measure.published == u.size


def test_without_measurement_parameters_the_plant_measures_the_rigid_body(ros):
    plant = ros.plant(**{"plant.noise_std": 0.0})
    rec = Recorder(ros.probe)
    wait_for(lambda: plant._measure.subscription_count() >= 1, 10.0, "the measurements subscription")
    wait_for(lambda: ros.probe.command_pub.get_subscription_count() >= 2, 10.0, "commands")
    for uk in (10.0, -10.0, 0.0):
        ros.probe.command_pub.publish(messages.command(uk))
    wait_for(lambda: len(rec.msgs) >= 3, 10.0, "3 readings")
    names, y, _ = rec.readings()
    assert names == ["rigid_body"]
    x = simulate_samples(plant.cfg.model, plant.cfg.model.rest_state(), [10.0, -10.0, 0.0], plant.cfg.dt)
    np.testing.assert_allclose(y[:, 0], x[:3, 0], rtol=0, atol=1e-14)


@pytest.mark.parametrize(
    ("extra", "name"),
    [
        ({"measurement.map": [1.0, 0.0]}, "measurement.map"),
        (
            {"measurement.kinds": ["position", "positon", "position", "velocity", "acceleration"]},
            "measurement.kinds[1]",
        ),
        ({"plant.noise_std": [0.1, 0.2]}, "plant.noise_std"),
        ({"plant.noise_std": -0.1}, "plant.noise_std"),
    ],
)
def test_a_bad_measurement_set_is_refused_at_start_up_as_the_command_line_refuses_it(ros, extra, name):
    params = crane_parameters(**{"lockstep": True, **extra})
    with pytest.raises(ConfigError) as err:
        PlantNode(context=ros.context, namespace=NAMESPACE, parameter_overrides=overrides(params))
    assert err.value.parameter == name, str(err.value)
    if name.startswith("measurement"):  # flexmotion plan on the same set: the same line
        with pytest.raises(ConfigError) as cli:
            config_from_parameters({k: v for k, v in params.items() if k != "lockstep"})
        assert str(cli.value) == str(err.value)


def test_the_model_commands_file_feeds_planner_and_plant(ros, tmp_path):
    """``flexmotion model crane`` writes measurement.*; the plant's noise is one double or one per channel."""
    import subprocess
    import sys

    path = tmp_path / "crane.yaml"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "flexmotion_ros.cli.main",
            "model",
            "crane",
            "--cart-mass",
            "20",
            "--payload-mass",
            "5",
            "--cable-length",
            "0.5",
            "--u-max",
            "50",
            "--rate",
            "100",
            "-o",
            str(path),
        ],
        check=True,
        capture_output=True,
    )
    for noise, expected in (("0.01", [0.01] * 3), ("[0.01, 0.0, 0.002]", [0.01, 0.0, 0.002])):
        text = path.read_text() + f"    plant:\n      noise_std: {noise}\n      noise_seed: 4\n    lockstep: true\n"
        f = tmp_path / "with_noise.yaml"
        f.write_text(text)
        args = ["--ros-args", "--params-file", str(f)]
        plant = ros.add(PlantNode(context=ros.context, namespace=NAMESPACE, cli_args=args))
        assert plant.cfg.measurement == builder_map(BUILT) and list(plant.cfg.noise_std) == expected
        assert plant.cfg.noise_seed == 4
    planner = ros.planner(**crane_parameters())
    assert planner.get_parameter("measurement.kinds").value[-1] == "acceleration"


def test_a_gantry_from_flexmotion_model_measures_its_physical_coordinates(ros, tmp_path):
    """Several drives: ``flexmotion model gantry`` writes the builder's physical coordinates as measurement.*,
    and the plant reads trolley, bridge and payload positions, checked against our own exact simulation."""
    import subprocess
    import sys

    from scipy.linalg import expm
    from std_msgs.msg import Float64MultiArray

    from flexmotion_ros.core.multi_input.builders import gantry

    path = tmp_path / "gantry.yaml"
    argv = ["model", "gantry", "--trolley-mass", "50", "--bridge-mass", "200", "--payload-mass", "100"]
    argv += ["--rope-length", "3", "--trolley-force", "300", "--bridge-force", "500", "--rate", "100", "-o", str(path)]
    subprocess.run([sys.executable, "-m", "flexmotion_ros.cli.main", *argv], check=True, capture_output=True)
    f = tmp_path / "lockstep.yaml"
    f.write_text(path.read_text() + "    lockstep: true\n")
    plant = ros.add(
        PlantNode(context=ros.context, namespace=NAMESPACE, cli_args=["--ros-args", "--params-file", str(f)])
    )
    built = gantry(50.0, 200.0, 100.0, 3.0, trolley_force=300.0, bridge_force=500.0)
    assert plant.cfg.measurement.names == tuple(built.coordinates)
    rec = Recorder(ros.probe)
    wait_for(lambda: plant._measure.subscription_count() >= 1, 10.0, "the measurements subscription")
    wait_for(lambda: ros.probe.command_pub.get_subscription_count() >= 1, 10.0, "commands")
    u = np.array([[300.0, -500.0], [-300.0, 250.0], [0.0, 0.0]])
    for row in u:
        ros.probe.command_pub.publish(Float64MultiArray(data=[float(v) for v in row]))
    wait_for(lambda: len(rec.msgs) >= 3, 10.0, "3 readings")
    names, y, _ = rec.readings()
    assert names == list(built.coordinates)  # trolley_x, payload_x, bridge_y, payload_y
    A, B = built.model.A(), built.model.B()
    n, m = B.shape
    aug = np.zeros((n + m, n + m))
    aug[:n, :n], aug[:n, n:] = A, B
    E = expm(aug * plant.cfg.dt)  # our own zero-order-hold step: [[Phi, Gamma], [0, I]]
    x = [np.zeros(n)]
    for row in u:
        x.append(E[:n, :n] @ x[-1] + E[:n, n:] @ row)
    x = np.array(x)
    expected = built.physical_positions(x[:3])  # the reading y_k of the state x_k the command u_k meets
    np.testing.assert_allclose(y[:3], expected, rtol=0, atol=1e-12)
    assert np.all(np.abs(expected[1:, [0, 2]]) > 1e-5)  # the readings moved: the check is not of zeros
