"""The nodes read the same parameter file as ``flexmotion plan``, with descriptors on every parameter."""

from __future__ import annotations

import array
import math
from pathlib import Path

import pytest
import rclpy
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter, parameter_dict_from_yaml_file

from flexmotion_ros.core.config import load_config, read_parameter_file, read_parameter_sections
from flexmotion_ros.core.errors import ConfigError, FlexmotionError
from flexmotion_ros.nodes.parameters import option_specs, parameter_overrides
from flexmotion_ros.nodes.planner_node import PlannerNode
from flexmotion_ros.nodes.planner_parameters import planner_specs
from flexmotion_ros.nodes.plant_node import PlantNode
from flexmotion_ros.nodes.plant_parameters import plant_specs

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


# ------------------------------------------------------------ one reader, rcl's rules (issue 11)
def _typed(value) -> tuple[str, object]:
    """(ROS type name, value) of a plain value, as rclpy names the type."""
    t = Parameter.Type.from_parameter_value(value)
    return t.name, list(value) if isinstance(value, (list, tuple, array.array)) else value


def _same(a, b) -> bool:
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return a == b


#: Files typed alike by rclpy's own reader and rcl: integers where doubles belong, strings, bools, lists.
#: (rclpy's Python reader differs from rcl on quoted numbers, ``1e3``, ``.inf`` and ``[]``: rcl is compared below.)
TYPED_FILES = [
    "    u_max: 1\n    rate_hz: 1000\n    method: zvd\n",
    "    model:\n      b0: 1\n      omega: [1, 2]\n      zeta: [0.0, 0.0]\n      b: [true, false]\n",
    "    method: 1\n    robust_order: 2.0\n    lockstep: yes\n    frame_id: world\n",
    "    limits: {velocity_max: 1.0e+3, report_each: off}\n    state: {mode_joint_names: [a, b]}\n",
]


def test_our_reader_types_like_rclpys_on_every_shipped_config_and_bad_files(tmp_path):
    paths = sorted((ROOT / "config").glob("*.yaml"))
    assert len(paths) >= 5
    for i, body in enumerate(TYPED_FILES):
        path = tmp_path / f"typed_{i}.yaml"
        path.write_text("/**:\n  ros__parameters:\n" + body)
        paths.append(path)
    for path in paths:
        theirs = {
            name: _typed(Parameter.from_parameter_msg(msg).value)
            for name, msg in parameter_dict_from_yaml_file(str(path), use_wildcard=True).items()
        }
        ours = {name: _typed(v) for name, v in read_parameter_file(path).items()}
        assert ours == theirs, path.name


def _rcl_overrides(path: Path) -> dict:
    """What rcl itself (``rclpy.init --params-file``) hands a node: name -> (type, value); raises if rcl refuses."""
    context = Context()
    rclpy.init(context=context, args=["--ros-args", "--params-file", str(path)])
    try:
        node = Node("flexmotion_planner", namespace=NAMESPACE, context=context)
        try:
            return {name: _typed(v) for name, v in parameter_overrides(node).items()}
        finally:
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


#: Scalars whose rcl types surprise (test/core/test_config.py pins the values measured here).
RCL_SCALARS = (
    "1 -3 +5 0x10 010 08 1.0 1. .5 1e3 1E3 -5.03e-05 123456789012345678901234567890 .inf -.inf +.INF .nan "
    "inf Infinity nan true Yes y Y n off ON abc null ~ 1_000 1e400 1e-400 0o10 2001-01-01 10:20 0x1p3"
).split()


def test_our_reader_types_every_scalar_as_rcl_does(tmp_path):
    """rcl's C parser, live: each scalar, plain and quoted, and in a list."""
    lines = [f"    p{i}: {text}\n    q{i}: '{text}'\n" for i, text in enumerate(RCL_SCALARS)]
    lines += [f"    l{i}: [{text}, {text}]\n" for i, text in enumerate(RCL_SCALARS) if ":" not in text]
    path = tmp_path / "scalars.yaml"
    path.write_text("/**:\n  ros__parameters:\n" + "".join(lines))
    rcl = _rcl_overrides(path)
    ours = {name: _typed(v) for name, v in read_parameter_file(path).items()}
    assert set(ours) == set(rcl)
    for name in rcl:
        assert ours[name][0] == rcl[name][0] and _same(ours[name][1], rcl[name][1]), (name, ours[name], rcl[name])


@pytest.mark.parametrize(
    "body",
    [
        "    omega: [1, 2.0]\n",  # rcl: "Sequence should be of same type"
        "    omega: [a, 1]\n",
        "    u_max:\n",  # rcl: "No value at line 3"
        "    u_max: [1.0\n",  # a YAML syntax error
        "    u_max: 1.0\n   rate_hz: 2.0\n",
    ],
)
def test_what_rcl_refuses_our_reader_refuses(tmp_path, body):
    path = tmp_path / "bad.yaml"
    path.write_text("/**:\n  ros__parameters:\n" + body)
    with pytest.raises(RuntimeError):  # rclpy's RCLError
        _rcl_overrides(path)
    with pytest.raises(ConfigError) as exc:
        read_parameter_sections(path)
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize(
    "body",
    [
        "    u_mx: 5.0\n",
        "    u_max: 1\n",
        "    model: {omega: [1, 2], zeta: [0.0, 0.0], b: [1.0, 1.0]}\n",
        "    colomb_force: 0.1\n    method: time_optimal_friction\n",
        "    method: time_optimal_friction\n",
        "    shaper: {tolerence: 0.2}\n",
        "    robust_order: 1.0\n",
        "    limits: {velocity_max: 1}\n",
        "    lockstep: 1\n",
        "    state: {source: bogus}\n",  # old main: flexmotion plan planned, the node refused
        "    trajectory: {early_arrival: optimun}\n",
        "    method: fixed_time\n    arrival_time: 6.0\n",  # valid: accepted by both
        "    joint_name: cart\n    plant: {coulomb_force: 0.1}\n",  # valid
    ],
)
def test_the_cli_and_the_node_give_the_same_verdict_on_the_same_file(ros, tmp_path, body):
    """Old main: the first three planned in `flexmotion plan` (exit 0); the node ignored the typo."""
    text = (ROOT / "config" / "wie_bernstein.yaml").read_text()
    path = tmp_path / "p.yaml"
    path.write_text(text.replace("    u_max: 1.0         # N\n", "") + body)
    args = ["--ros-args", "--params-file", str(path)]
    try:
        cli = ("ok", load_config(path))
    except FlexmotionError as exc:
        cli = ("refused", str(exc))
    try:
        node = ros.add(PlannerNode(context=ros.context, namespace=NAMESPACE, cli_args=args))
        verdict = ("ok", node.config)
    except FlexmotionError as exc:
        verdict = ("refused", str(exc))
    assert verdict == cli


def test_every_node_parameter_is_in_the_core_registry():
    """Where to add a node parameter: its Spec (nodes/parameters.py) and its line in core/parameters.py."""
    from flexmotion_ros.core.parameters import KNOWN

    for spec in planner_specs() + plant_specs() + option_specs():
        assert spec.name in KNOWN, f"{spec.name}: add it to flexmotion_ros/core/parameters.py"
        declared = spec.default if isinstance(spec.default, Parameter.Type) else None
        if declared is None:
            declared = Parameter.Type.from_parameter_value(spec.default)
        assert declared.name == KNOWN[spec.name].type.name, spec.name
