"""The nodes read the same parameter file as ``flexmotion plan``, with descriptors on every parameter."""

from __future__ import annotations

from pathlib import Path

from flexmotion_ros.core.config import load_config
from flexmotion_ros.nodes.parameters import planner_specs, plant_specs
from flexmotion_ros.nodes.planner_node import PlannerNode
from flexmotion_ros.nodes.plant_node import PlantNode

from .conftest import NAMESPACE

ROOT = Path(__file__).resolve().parents[2]


def test_planner_reads_the_cli_parameter_file(ros, tmp_path):
    """Nested ``model: {b0: ...}`` keys and method options, as ``flexmotion plan --config`` reads them."""
    text = (ROOT / "config" / "flexible_beam_3mode.yaml").read_text() + "    robust_order: 1\n"
    text += "/**/flexmotion_plant:\n  ros__parameters:\n    plant:\n      omega_scale: [1.1, 1.0, 1.0]\n    lockstep: true\n"
    path = tmp_path / "beam.yaml"
    path.write_text(text)
    args = ["--ros-args", "--params-file", str(path)]
    planner = ros.add(PlannerNode(context=ros.context, namespace=NAMESPACE, cli_args=args))
    assert planner.config == load_config(path)  # exactly what `flexmotion plan --config` uses
    assert planner.config.model.n_modes == 3 and planner.config.options == {"robust_order": 1}
    assert planner.describe_parameter("robust_order").description.startswith("option of the planning method")
    plant = ros.add(PlantNode(context=ros.context, namespace=NAMESPACE, cli_args=args))
    assert plant.cfg.nominal == planner.config.model
    assert plant.cfg.model.omega[0] == 1.1 * planner.config.model.omega[0] and plant.cfg.lockstep


def test_planner_leaves_the_plant_parameters_of_a_shared_file_alone(ros):
    planner = ros.planner(
        **{"plant.omega_scale": [1.1, 1.0], "lockstep": True, "command_timeout": 0.2, "robust_order": 2}
    )
    assert not planner.has_parameter("plant.omega_scale") and not planner.has_parameter("lockstep")
    assert planner.config.options == {"robust_order": 2}


def test_every_parameter_has_a_described_descriptor(ros):
    planner = ros.planner()
    plant = ros.plant()
    for node, specs in ((planner, planner_specs()), (plant, plant_specs())):
        for spec in specs:
            d = node.describe_parameter(spec.name)
            assert d.description == spec.description and len(d.description) > 20, spec.name
            assert d.read_only == spec.read_only
    # units in the descriptions, ranges where they mean something, read-only where a change cannot apply live
    assert "(Hz)" in planner.describe_parameter("rate_hz").description
    assert planner.describe_parameter("rate_hz").read_only and planner.describe_parameter("stream_priority").read_only
    assert not planner.describe_parameter("model.omega").read_only  # applies to the next goal
    assert plant.describe_parameter("model.omega").read_only  # the simulated machine
    assert planner.describe_parameter("replan_lead_s").floating_point_range[0].to_value == 60.0
    assert planner.describe_parameter("max_trajectory_points").integer_range[0].from_value == 2
