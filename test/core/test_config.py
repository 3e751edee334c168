"""Parameter files: round trip, doubles written as doubles, wildcard vs node sections, errors."""

import math
import re
from pathlib import Path

import pytest
import yaml

from flexmotion_ros.core import (
    FlexmotionError,
    GoalError,
    ModalModel,
    ModelError,
    chain,
    crane,
)
from flexmotion_ros.core.config import (
    PlannerConfig,
    config_from_parameters,
    dump_parameters,
    flatten,
    load_config,
    read_parameter_file,
    unflatten,
    write_config,
)
from flexmotion_ros.core.errors import ConfigError

CONFIG_DIR = Path(__file__).resolve().parents[2] / "config"
MODEL = ModalModel(b0=0.5, c=-0.125, omega=(1.4142135623730951, 7.0), zeta=(0.0, 0.03), b=(1.0, -2.0))


def write(tmp_path, text: str, name: str = "p.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# ---------------------------------------------------------------- round trip
def test_write_and_load_round_trip(tmp_path):
    cfg = PlannerConfig(model=MODEL, u_max=2.0, rate_hz=500.0, position_min=-1.5, position_max=3.0)
    path = tmp_path / "cfg.yaml"
    write_config(path, cfg, header="# a header\n")
    assert path.read_text().startswith("# a header\n/**:\n  ros__parameters:\n")
    back = load_config(path)
    assert back.model == cfg.model
    assert (back.u_max, back.rate_hz, back.method) == (2.0, 500.0, "time_optimal")
    assert (back.position_min, back.position_max) == (-1.5, 3.0)
    assert back.options == {}


def test_dump_read_config_from_parameters_round_trip_is_exact(tmp_path):
    params = PlannerConfig(model=MODEL, u_max=0.1, rate_hz=1000.0).to_parameters()
    del params["limits.position_min"], params["limits.position_max"]
    path = write(tmp_path, dump_parameters(params))
    flat = read_parameter_file(path)
    assert flat == params  # every double exactly (repr round trip), lists as lists
    assert config_from_parameters(flat).model == MODEL


def test_infinite_limits_are_not_written(tmp_path):
    path = tmp_path / "cfg.yaml"
    write_config(path, PlannerConfig(model=MODEL))
    text = path.read_text()
    assert "limits" not in text and "inf" not in text
    back = load_config(path)
    assert back.position_min == -math.inf and back.position_max == math.inf


# ------------------------------------------------------ doubles look like doubles
@pytest.mark.parametrize(
    "value",
    [
        2,
        2.0,
        1,
        0,
        -3,
        1e-20,
        1e20,
        0.1,
        1.4142135623730951,
        1e16,
        123456789.0,
        -0.0,
        5e-324,
    ],
)
def test_doubles_are_written_as_doubles(value):
    text = dump_parameters({"u_max": value, "model.omega": [value, 3]})
    body = yaml.safe_load(text)["/**"]["ros__parameters"]
    # a YAML (and so ROS 2) parser reads a double, not an integer or a string
    assert type(body["u_max"]) is float and body["u_max"] == float(value)
    assert all(type(v) is float for v in body["model"]["omega"])
    assert body["model"]["omega"] == [float(value), 3.0]
    line = next(ln for ln in text.splitlines() if ln.strip().startswith("u_max:"))
    literal = line.split(":", 1)[1].strip()
    assert "." in literal, f"{literal!r} does not look like a double"


def test_specific_spellings():
    text = dump_parameters({"u_max": 2, "rate_hz": 1000, "model.b0": 1e-20, "model.c": 0})
    assert "u_max: 2.0\n" in text
    assert "rate_hz: 1000.0\n" in text
    assert re.search(r"\bb0: 1\.0e-20[,}\n]", text)
    assert re.search(r"\bc: 0\.0[,}\n]", text)


def test_integer_and_string_parameters_keep_their_type():
    text = dump_parameters({"robust_order": 2, "method": "time_optimal", "flag": True})
    body = yaml.safe_load(text)["/**"]["ros__parameters"]
    assert body == {"robust_order": 2, "method": "time_optimal", "flag": True}
    assert type(body["robust_order"]) is int


def test_flatten_unflatten():
    tree = {
        "model": {"b0": 1.0, "omega": [1.0]},
        "u_max": 2.0,
        "limits": {"position_min": -1.0},
    }
    flat = flatten(tree)
    assert flat == {
        "model.b0": 1.0,
        "model.omega": [1.0],
        "u_max": 2.0,
        "limits.position_min": -1.0,
    }
    assert unflatten(flat) == tree


# ------------------------------------------------- wildcard vs node sections
TWO_SECTIONS = """
/**:
  ros__parameters:
    model: {b0: 0.5, omega: [2.0], zeta: [0.0], b: [1.0]}
    u_max: 1.0
    rate_hz: 100.0
flexmotion_planner:
  ros__parameters:
    u_max: 3.0
other_node:
  ros__parameters:
    u_max: 9.0
"""


def test_node_section_overrides_the_wildcard(tmp_path):
    path = write(tmp_path, TWO_SECTIONS)
    assert read_parameter_file(path)["u_max"] == 1.0
    assert read_parameter_file(path, "flexmotion_planner")["u_max"] == 3.0
    assert read_parameter_file(path, "other_node")["u_max"] == 9.0
    merged = read_parameter_file(path, "flexmotion_planner")
    assert merged["rate_hz"] == 100.0 and merged["model.omega"] == [2.0]
    assert load_config(path).u_max == 3.0  # default node name: flexmotion_planner
    assert load_config(path, node_name=None).u_max == 1.0


def test_fully_qualified_node_name_matches_a_plain_section(tmp_path):
    """ROS 2 matches '/node' and 'node' sections alike for a node in the root namespace."""
    path = write(tmp_path, TWO_SECTIONS)
    assert read_parameter_file(path, "/other_node")["u_max"] == 9.0


def test_slash_prefixed_node_section(tmp_path):
    path = write(tmp_path, TWO_SECTIONS.replace("flexmotion_planner:", "/flexmotion_planner:"))
    assert load_config(path).u_max == 3.0


def test_node_section_alone(tmp_path):
    path = write(tmp_path, "flexmotion_planner:\n  ros__parameters:\n    u_max: 4.0\n")
    cfg = load_config(path)
    assert cfg.u_max == 4.0 and cfg.model.n_modes == 0  # defaults fill the rest
    with pytest.raises(ConfigError) as exc:
        read_parameter_file(path)
    assert exc.value.parameter == "config" and "ros__parameters" in exc.value.reason


def test_method_options_go_to_options_and_node_names_are_known(tmp_path):
    path = write(
        tmp_path,
        "/**:\n  ros__parameters:\n    robust_order: 2\n    shaper: {multimode: direct}\n    lockstep: true\n"
        "    plant: {omega_scale: [1.1]}\n    design: {builder: two_mass}\n    use_sim_time: false\n"
        "    qos_overrides: {/commands: {publisher: {depth: 10}}}\n    joint_name: cart\n",
    )
    cfg = load_config(path)
    assert cfg.options == {"robust_order": 2, "shaper.multimode": "direct"}


# ------------------------------------------------------------ strict names and types (issue 11)
@pytest.mark.parametrize(
    "body, name, closest",
    [
        ("u_mx: 5.0", "u_mx", "u_max"),
        ("shaper: {tolerence: 0.2}", "shaper.tolerence", "shaper.tolerance"),
        ("colomb_force: 0.1", "colomb_force", "coulomb_force"),
        ("limits: {velocity: 1.0}", "limits.velocity", "limits.velocity_max"),
        ("model: {omgea: [1.0]}", "model.omgea", "model.omega"),
        ("lockstepp: true", "lockstepp", "lockstep"),
    ],
)
def test_unknown_names_are_refused_with_the_closest_known_name(tmp_path, body, name, closest):
    """Old main: ``u_mx: 5.0`` went to ``options`` and the move was planned with u_max 1.0."""
    path = write(tmp_path, "/**:\n  ros__parameters:\n    " + body + "\n")
    with pytest.raises(ConfigError) as exc:
        load_config(path)
    assert exc.value.parameter == name
    assert f"did you mean {closest}?" in exc.value.reason


@pytest.mark.parametrize(
    "body, name, fragment",
    [
        ("u_max: 1", "u_max", "write 1.0"),
        ("rate_hz: 1000", "rate_hz", "write 1000.0"),
        ("model: {b0: 1, omega: [1.0], zeta: [0.0], b: [1.0]}", "model.b0", "write 1.0"),
        ("model: {omega: [1, 2], zeta: [0.0, 0.0], b: [1.0, 1.0]}", "model.omega", "must be a double array"),
        ("model: {omega: [1, 2], zeta: [0.0, 0.0], b: [1.0, 1.0]}", "model.omega", "write [1.0, 2.0]"),
        ("coulomb_force: 0", "coulomb_force", "write 0.0"),
        ("robust_order: 1.0", "robust_order", "must be an integer"),
        ("method: 1", "method", "must be a string"),
        ("u_max: abc", "u_max", "must be a double"),
        ("u_max: null", "u_max", "the string 'null'"),  # rcl types null as a string
        ("limits: {report_each: maybe}", "limits.report_each", "must be a bool"),
    ],
)
def test_values_must_have_their_ros_type(tmp_path, body, name, fragment):
    """One verdict with the node: an integer where a double is declared is refused (rclpy refuses it too)."""
    path = write(tmp_path, "/**:\n  ros__parameters:\n    " + body + "\n")
    with pytest.raises(ConfigError) as exc:
        load_config(path)
    assert exc.value.parameter == name
    assert fragment in exc.value.reason, exc.value.reason


@pytest.mark.parametrize(
    "body, fragment",
    [
        ("u_max: [1, 2.0]", "list items must all have one type"),
        ("u_max:", "no value at line 3"),
        ("u_max: [1.0\n", "not valid YAML at line 5, column 1"),
    ],
)
def test_what_rcl_refuses_is_refused(tmp_path, body, fragment):
    path = write(tmp_path, "/**:\n  ros__parameters:\n    " + body + "\n")
    with pytest.raises(ConfigError) as exc:
        load_config(path)
    assert fragment in exc.value.reason, exc.value.reason
    assert "\n" not in str(exc.value)


# What rcl_yaml_param_parser made of each plain scalar (measured with rclpy.init(--params-file) on Jazzy;
# test/ros/test_parameters.py compares the two live).
RCL_SCALARS = [
    ("1", 1),
    ("-3", -3),
    ("+5", 5),
    ("0x10", 16),
    ("010", 8),
    ("1.0", 1.0),
    ("1.", 1.0),
    (".5", 0.5),
    ("1e3", 1000.0),
    ("1E3", 1000.0),
    ("-5.03e-05", -5.03e-05),
    ("123456789012345678901234567890", 1.2345678901234568e29),
    (".inf", math.inf),
    ("-.inf", -math.inf),
    ("Infinity", math.inf),
    ("true", True),
    ("Yes", True),
    ("y", True),
    ("off", False),
    ("abc", "abc"),
    ("null", "null"),
    ("~", "~"),
    ("1_000", "1_000"),
    ("1e400", "1e400"),
    ("0o10", "0o10"),
    ("2001-01-01", "2001-01-01"),
]


@pytest.mark.parametrize("text, value", RCL_SCALARS)
def test_scalars_are_typed_as_rcl_types_them(text, value):
    from flexmotion_ros.core.ros_types import rcl_scalar

    got = rcl_scalar(text)
    assert type(got) is type(value) and got == value
    assert rcl_scalar(text, quoted=True) == text  # a quoted scalar is a string


def test_nan_and_quoted_values(tmp_path):
    flat = read_parameter_file(write(tmp_path, "/**:\n  ros__parameters:\n    a: .nan\n    b: '1.0'\n    c: []\n"))
    assert math.isnan(flat["a"]) and flat["b"] == "1.0" and flat["c"] == []


def test_a_method_without_its_required_option_is_refused_by_the_configuration():
    """Old main built the configuration and refused every goal later (``ros2 param set method ...`` succeeded)."""
    base = {"model.b0": 0.5, "model.omega": [1.0], "model.zeta": [0.0], "model.b": [1.0]}
    with pytest.raises(ConfigError) as exc:
        config_from_parameters({**base, "method": "time_optimal_friction"})
    assert exc.value.parameter == "coulomb_force" and "required by method time_optimal_friction" in exc.value.reason
    with pytest.raises(ConfigError) as exc:
        config_from_parameters({**base, "method": "fixed_time"})
    assert exc.value.parameter == "arrival_time"
    cfg = config_from_parameters({**base, "method": "time_optimal_friction", "coulomb_force": 0.1})
    with pytest.raises(ConfigError):
        cfg.with_changes(method="fixed_time")


def test_a_directory_is_not_a_parameter_file(tmp_path):
    with pytest.raises(ConfigError) as exc:
        load_config(tmp_path)
    assert exc.value.parameter == "config" and "is a directory" in exc.value.reason


def test_a_goal_beyond_the_move_budget_is_refused_before_planning():
    """Old main: ``--goal 1e300`` ended in numpy's ValueError (Maximum allowed size exceeded)."""
    from flexmotion_ros.core.methods.table import plan_move
    from flexmotion_ros.core.model.boundary import motion_to_rest, rest_to_rest

    cfg = load_config(CONFIG_DIR / "wie_bernstein.yaml")
    assert cfg.max_move_duration_s == 3600.0
    for problem in (rest_to_rest(cfg.model, cfg.u_max, 1e300), motion_to_rest(cfg.model, cfg.u_max, 1e200)):
        with pytest.raises(GoalError) as exc:
            plan_move(cfg, problem)
        assert exc.value.parameter == "goal" and "max_move_duration_s = 3600 s" in exc.value.reason
    small = cfg.with_changes(max_move_duration_s=2.0)  # the unit move needs at least 2.83 s (rigid body)
    with pytest.raises(GoalError, match="2.828 s"):
        plan_move(small, rest_to_rest(cfg.model, cfg.u_max, 1.0))
    assert plan_move(cfg.with_changes(max_move_duration_s=5.0), rest_to_rest(cfg.model, cfg.u_max, 1.0)).continuous
    for bad in (0.0, -1.0, math.inf, math.nan):
        with pytest.raises(ConfigError) as exc:
            cfg.with_changes(max_move_duration_s=bad)
        assert exc.value.parameter == "max_move_duration_s"


def test_the_sample_budget_refuses_with_a_lower_bound_and_is_validated():
    """Issue 16: a goal of 1e6 was a 47-minute move planned in 8.6 s; the budget refuses it up front."""
    from flexmotion_ros.core.config import check_move_samples
    from flexmotion_ros.core.model.boundary import rest_to_rest

    cfg = load_config(CONFIG_DIR / "wie_bernstein.yaml")
    assert cfg.max_move_samples == 100_000
    unit = rest_to_rest(cfg.model, cfg.u_max, 1.0)  # rigid body: 2 sqrt(2) s = 2828.4 samples at 1 kHz
    assert check_move_samples(cfg, unit) == 2829
    with pytest.raises(GoalError) as exc:
        check_move_samples(cfg.with_changes(max_move_samples=2828), unit)
    assert exc.value.parameter == "goal" and "max_move_samples = 2828" in exc.value.reason
    assert check_move_samples(cfg, unit, rate_hz=10.0) == 29  # a given rate counts, not config.rate_hz
    with pytest.raises(GoalError, match="5.657e"):
        check_move_samples(cfg, rest_to_rest(cfg.model, cfg.u_max, 1e6), rate_hz=200.0)
    for bad in (0, -3, 1.5, True, "7"):
        with pytest.raises(ConfigError) as exc:
            cfg.with_changes(max_move_samples=bad)
        assert exc.value.parameter == "max_move_samples"


def test_a_mode_at_or_above_the_nyquist_frequency_is_refused_from_parameters():
    """Issue 16: omega 1e5 rad/s at 1 kHz was accepted, and planned for 36.9 s."""
    base = {"model.omega": [5.0, 3141.0], "model.zeta": [0.0, 0.0], "model.b": [1.0, 1.0], "rate_hz": 1000.0}
    assert config_from_parameters(base).model.omega[1] == 3141.0  # just below pi x 1000
    with pytest.raises(ConfigError) as exc:
        config_from_parameters({**base, "model.omega": [5.0, 3142.0]})
    assert exc.value.parameter == "model.omega[1]" and "Nyquist frequency pi x rate_hz = 3141.59 rad/s" in str(
        exc.value
    )


def test_every_method_option_is_registered_with_its_methods():
    from flexmotion_ros.core.methods import METHODS
    from flexmotion_ros.core.parameters import METHOD_OPTIONS, required_options

    assert {o.name for m in METHODS.values() for o in m.options} == {o.name for o in METHOD_OPTIONS}
    assert [o.name for o in required_options("time_optimal_friction")] == ["coulomb_force"]
    assert [o.name for o in required_options("fixed_time")] == ["arrival_time"]
    for o in METHOD_OPTIONS:
        assert set(o.methods) <= set(METHODS) and set(o.required_by) <= set(o.methods), o.name


# ------------------------------------------------------------------ errors
def test_missing_file(tmp_path):
    with pytest.raises(ConfigError) as exc:
        load_config(tmp_path / "nope.yaml")
    assert exc.value.parameter == "config"
    assert "not found" in exc.value.reason and "nope.yaml" in exc.value.reason


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("/**:\n  ros__parameters:\n    u_max: [1.0\n", "not valid YAML"),
        ("- 1\n- 2\n", "expected a mapping"),
        ("", "expected a mapping"),
        ("/**:\n  params:\n    u_max: 1.0\n", "ros__parameters"),
        ("/**:\n  ros__parameters: 3\n", "ros__parameters"),
    ],
)
def test_bad_files(tmp_path, text, fragment):
    with pytest.raises(ConfigError) as exc:
        load_config(write(tmp_path, text))
    assert exc.value.parameter == "config"
    assert fragment in exc.value.reason
    assert "\n" not in str(exc.value), "one line: nodes and the CLI report it verbatim"


@pytest.mark.parametrize(
    "params, parameter, fragment",
    [
        ("u_max: -1.0", "u_max", "> 0"),
        ("u_max: .nan", "u_max", "finite"),
        ("u_max: abc", "u_max", "must be a double"),
        ("rate_hz: 0.0", "rate_hz", "> 0"),
        ("rate_hz: 2.0e+6", "rate_hz", "1e6"),
        ("method: warp_drive", "method", "time_optimal"),
        (
            "limits: {position_min: 1.0, position_max: -1.0}",
            "limits.position_min/position_max",
            "position_min < position_max",
        ),
        ("model: {b0: 0.0}", "model.b0", "non-zero"),
        ("model: {c: 0.5}", "model.c", "<= 0"),
        ("model: {omega: [1.0], zeta: [1.5], b: [1.0]}", "model.zeta[0]", "[0, 1)"),
        (
            "model: {omega: [1.0], zeta: [0.0], b: [0.0]}",
            "model.b[0]",
            "uncontrollable",
        ),
        ("model: {omega: [-1.0], zeta: [0.0], b: [1.0]}", "model.omega[0]", "> 0"),
        (
            "model: {omega: [1.0, 1.0], zeta: [0.0, 0.0], b: [1.0, 1.0]}",
            "model.omega[1]",
            "not controllable",
        ),
        (
            "model: {omega: [1.0, 2.0], zeta: [0.0], b: [1.0]}",
            "model.omega/zeta/b",
            "same length",
        ),
        ("model: {omega: [.inf], zeta: [0.0], b: [1.0]}", "model.omega[0]", "finite"),
    ],
)
def test_bad_values_name_the_parameter(tmp_path, params, parameter, fragment):
    path = write(tmp_path, "/**:\n  ros__parameters:\n    " + params + "\n")
    with pytest.raises(FlexmotionError) as exc:
        load_config(path)
    assert exc.value.parameter == parameter
    assert fragment in exc.value.reason
    assert isinstance(exc.value, (ConfigError, ModelError))


def test_check_goal():
    cfg = PlannerConfig(model=MODEL, position_min=-1.0, position_max=2.0)
    assert cfg.check_goal(2.0) == 2.0 and cfg.check_goal(-1.0) == -1.0
    for bad, fragment in (
        (2.5, "outside the position limits"),
        (math.nan, "finite"),
        (math.inf, "finite"),
        ("x", "finite"),
    ):
        with pytest.raises(GoalError) as exc:
            cfg.check_goal(bad)
        assert exc.value.parameter == "goal" and fragment in exc.value.reason


def test_with_changes_revalidates():
    cfg = PlannerConfig(model=MODEL)
    with pytest.raises(FlexmotionError) as exc:
        cfg.with_changes(u_max=0.0)
    assert exc.value.parameter == "u_max"
    assert cfg.with_changes(rate_hz=50.0).rate_hz == 50.0


# ------------------------------------------------------- shipped examples
def test_shipped_examples_load_and_match_their_builders():
    wb = load_config(CONFIG_DIR / "wie_bernstein.yaml")
    assert wb.model == ModalModel(b0=0.5, omega=(math.sqrt(2.0),), zeta=(0.0,), b=(1.0,))
    assert (wb.u_max, wb.rate_hz) == (1.0, 1000.0)
    cr = load_config(CONFIG_DIR / "crane.yaml")
    built = crane(20.0, 5.0, 2.0, 9.81, 0.005).model
    assert cr.model.omega == pytest.approx(built.omega, rel=1e-15) and cr.model.b == built.b
    assert cr.u_max == 50.0
    beam = load_config(CONFIG_DIR / "flexible_beam_3mode.yaml")
    built = chain([0.5] * 4, [400.0] * 3, [0.4] * 3).model
    assert beam.model.omega == pytest.approx(built.omega, rel=1e-12)
    assert beam.model.zeta == pytest.approx(built.zeta, rel=1e-12)
    assert beam.model.b == pytest.approx(built.b, rel=1e-12)
