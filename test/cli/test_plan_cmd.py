"""``flexmotion plan`` / ``flexmotion model``: JSON fields, checked by our own simulation;
bad input gives one line on stderr, exit status 2 and nothing on stdout."""

import itertools
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from flexmotion_ros.cli import main as cli_main
from flexmotion_ros.cli.main import main
from flexmotion_ros.core import (
    ModalModel,
    PiecewiseConstant,
    SolverError,
    final_state,
    load_config,
    motion_to_rest,
    plan_time_optimal,
    simulate_samples,
)

ROOT = Path(__file__).resolve().parents[2]
WB_CONFIG = ROOT / "config" / "wie_bernstein.yaml"
WB = ModalModel(b0=0.5, omega=(math.sqrt(2.0),), zeta=(0.0,), b=(1.0,))
ONE_LINE_PREFIX = "flexmotion: error: "


def run_json(capsys, *argv) -> dict:
    status = main(["plan", *argv, "--json"])
    out, err = capsys.readouterr()
    assert status == 0, err
    assert out.count("\n") == 1  # one JSON object on one line
    return json.loads(out)


def assert_refused(capsys, argv, *fragments) -> str:
    """Exit 2, nothing on stdout, exactly one line on stderr naming the problem."""
    try:
        status = main(argv)
    except SystemExit as exc:  # argparse errors
        status = exc.code
    out, err = capsys.readouterr()
    assert status == 2
    assert out == ""
    assert err.startswith(ONE_LINE_PREFIX) and err.endswith("\n") and err.count("\n") == 1, err
    for f in fragments:
        assert f in err, err
    return err


def check_continuous_fields(out: dict, u_max: float) -> None:
    T = out["duration"]
    sw = out["switch_times"]
    lv = out["levels"]
    assert isinstance(T, float) and T > 0.0
    assert len(lv) == len(sw) + 1
    assert all(0.0 < t < T for t in sw) and all(b > a for a, b in itertools.pairwise(sw))
    assert all(abs(v) == u_max for v in lv)
    assert out["certified"] is True
    assert 0.0 <= out["final_state_error"] < 1e-9
    assert out["solve_time_s"] > 0.0


# ----------------------------------------------------------------- fields
def test_plan_json_wie_bernstein(capsys):
    out = run_json(capsys, "--config", str(WB_CONFIG), "--goal", "1.0")
    check_continuous_fields(out, 1.0)
    assert out["duration"] == pytest.approx(4.2179, abs=5e-5)
    assert out["switch_times"] == pytest.approx([1.0026, 2.1089, 3.2152], abs=2e-4)
    assert out["levels"] == [1.0, -1.0, 1.0, -1.0]
    assert "samples" not in out and "commands" not in out
    # our own simulation of the printed profile reaches rest at the goal
    u = PiecewiseConstant.from_switches(out["switch_times"], out["levels"], out["duration"])
    x = final_state(WB, WB.rest_state(), u)
    np.testing.assert_allclose(x, [1.0, 0.0, 0.0, 0.0], atol=1e-9)


@pytest.mark.parametrize("rate", [50.0, 1000.0])
def test_plan_json_with_rate(capsys, rate):
    out = run_json(capsys, "--config", str(WB_CONFIG), "--goal", "-0.7", "--rate", str(rate))
    check_continuous_fields(out, 1.0)
    cmds = np.asarray(out["commands"], float)
    assert out["samples"] == cmds.size
    assert np.all(np.abs(cmds) <= 1.0)
    assert cmds.size / rate >= out["duration"] * (1.0 - 1e-12)
    X = simulate_samples(WB, WB.rest_state(), cmds, 1.0 / rate)
    np.testing.assert_allclose(X[-1], [-0.7, 0.0, 0.0, 0.0], atol=1e-9)
    assert out["minimal"] is True


def test_initial_velocity_without_goal_stops_asap(capsys):
    out = run_json(capsys, "--config", str(WB_CONFIG), "--initial-velocity", "0.8")
    check_continuous_fields(out, 1.0)
    u = PiecewiseConstant.from_switches(out["switch_times"], out["levels"], out["duration"])
    x = final_state(WB, [0.0, 0.8, 0.0, 0.0], u)
    np.testing.assert_allclose(x[1:], 0.0, atol=1e-9)  # at rest; the position is free
    assert x[0] > 0.0 and out["final_state"][0] == pytest.approx(x[0], rel=1e-9)
    assert out["duration"] == pytest.approx(plan_time_optimal(motion_to_rest(WB, 1.0, 0.8)).duration, rel=1e-12)
    # a rigid body would stop in v / (b0 u_max) = 1.6 s; the mode can only make it longer
    assert out["duration"] >= 1.6


def test_initial_velocity_and_goal(capsys):
    out = run_json(
        capsys,
        "--config",
        str(WB_CONFIG),
        "--initial-velocity",
        "-0.5",
        "--goal",
        "2.0",
    )
    check_continuous_fields(out, 1.0)
    u = PiecewiseConstant.from_switches(out["switch_times"], out["levels"], out["duration"])
    np.testing.assert_allclose(final_state(WB, [0.0, -0.5, 0.0, 0.0], u), [2.0, 0, 0, 0], atol=1e-9)


def test_text_output(capsys):
    assert main(["plan", "--config", str(WB_CONFIG), "--goal", "1.0"]) == 0
    out, err = capsys.readouterr()
    assert "duration          4.2178" in out and "certified         True" in out
    assert err == ""


def test_model_two_mass_writes_a_config_that_plans_to_the_wie_bernstein_optimum(tmp_path, capsys):
    path = tmp_path / "wb.yaml"
    assert main(["model", "two-mass", "--m1", "1", "--m2", "1", "--k", "1", "-o", str(path)]) == 0
    capsys.readouterr()
    cfg = load_config(path)
    assert cfg.model.b0 == pytest.approx(0.5) and cfg.model.omega[0] == pytest.approx(math.sqrt(2.0))
    assert "b0: 0.5" in path.read_text() and "u_max: 1.0" in path.read_text()
    out = run_json(capsys, "--config", str(path), "--goal", "1.0")
    assert out["duration"] == pytest.approx(4.2179, abs=5e-5)
    assert len(out["switch_times"]) == 3 and out["certified"] is True
    reference = run_json(capsys, "--config", str(WB_CONFIG), "--goal", "1.0")
    assert out["duration"] == pytest.approx(reference["duration"], rel=1e-12)


def test_model_to_stdout_is_a_parameter_file(capsys):
    assert (
        main(
            [
                "model",
                "crane",
                "--cart-mass",
                "20",
                "--payload-mass",
                "5",
                "--cable-length",
                "2",
                "--u-max",
                "50",
            ]
        )
        == 0
    )
    out, _ = capsys.readouterr()
    params = yaml.safe_load(out)["/**"]["ros__parameters"]
    assert params["u_max"] == 50.0 and params["model"]["b0"] == pytest.approx(0.04)


# -------------------------------------------------------------- bad input
def write_config(tmp_path, body: str) -> str:
    path = tmp_path / "bad.yaml"
    path.write_text("/**:\n  ros__parameters:\n" + body)
    return str(path)


@pytest.mark.parametrize("goal, name", [("nan", "goal"), ("inf", "goal"), ("-inf", "goal")])
def test_non_finite_goal(capsys, goal, name):
    assert_refused(
        capsys,
        ["plan", "--config", str(WB_CONFIG), f"--goal={goal}", "--json"],
        name,
        "finite",
    )


def test_non_finite_initial_velocity(capsys):
    assert_refused(
        capsys,
        ["plan", "--config", str(WB_CONFIG), "--initial-velocity=nan", "--json"],
        "initial_velocity",
    )


def test_neither_goal_nor_velocity(capsys):
    assert_refused(capsys, ["plan", "--config", str(WB_CONFIG), "--json"], "goal")


def test_missing_file(capsys, tmp_path):
    assert_refused(
        capsys,
        ["plan", "--config", str(tmp_path / "nope.yaml"), "--goal", "1", "--json"],
        "config",
        "not found",
    )


def test_bad_yaml(capsys, tmp_path):
    path = tmp_path / "broken.yaml"
    path.write_text("/**:\n  ros__parameters:\n    model: {b0: [1.0\n")
    assert_refused(
        capsys,
        ["plan", "--config", str(path), "--goal", "1", "--json"],
        "config",
        "not valid YAML",
    )


@pytest.mark.parametrize(
    "body, name",
    [
        ("    model: {b0: 0.0}\n", "model.b0"),
        ("    model: {b0: 1.0, omega: [1.0], zeta: [0.0], b: [0.0]}\n", "model.b[0]"),
        (
            "    model: {b0: 1.0, omega: [2.0, 2.0], zeta: [0.0, 0.0], b: [1.0, 1.0]}\n",
            "model.omega[1]",
        ),
        ("    model: {b0: 1.0, c: 1.0}\n", "model.c"),
        (
            "    model: {b0: 1.0, omega: [1.0], zeta: [1.0], b: [1.0]}\n",
            "model.zeta[0]",
        ),
        ("    model: {b0: .nan}\n", "model.b0"),
        ("    u_max: 0.0\n", "u_max"),
        ("    limits: {position_min: -1.0, position_max: 0.5}\n", "goal"),
    ],
)
def test_bad_model_values(capsys, tmp_path, body, name):
    assert_refused(
        capsys,
        ["plan", "--config", write_config(tmp_path, body), "--goal", "1", "--json"],
        name,
    )


def test_unknown_method(capsys):
    err = assert_refused(
        capsys,
        [
            "plan",
            "--config",
            str(WB_CONFIG),
            "--goal",
            "1",
            "--method",
            "warp",
            "--json",
        ],
        "method",
    )
    assert "time_optimal" in err  # names the allowed values


@pytest.mark.parametrize("rate", ["0", "-5", "nan"])
def test_bad_rate(capsys, rate):
    assert_refused(
        capsys,
        ["plan", "--config", str(WB_CONFIG), "--goal", "1", f"--rate={rate}", "--json"],
        "rate",
    )


def test_unparsable_number(capsys):
    assert_refused(
        capsys,
        ["plan", "--config", str(WB_CONFIG), "--goal", "one", "--json"],
        "--goal",
    )


def test_solver_error_is_one_line_too(capsys, monkeypatch):
    def failing(*args, **kwargs):
        raise SolverError("time-optimal planner missed the target: relative final-state error 1e-3")

    monkeypatch.setattr("flexmotion_ros.cli.plan_cmd.plan_move", failing)
    assert_refused(
        capsys,
        ["plan", "--config", str(WB_CONFIG), "--goal", "1", "--json"],
        "missed the target",
    )


def test_commands_are_registered():
    names = [m.__name__ for m in cli_main.COMMAND_MODULES]
    assert "flexmotion_ros.cli.plan_cmd" in names
    assert "flexmotion_ros.cli.model_cmd" in names


# ------------------------------------------------------ strict configuration (issue 11)
def _with(tmp_path, old: str, new: str, name: str = "p.yaml") -> str:
    text = WB_CONFIG.read_text()
    assert old in text
    path = tmp_path / name
    path.write_text(text.replace(old, new))
    return str(path)


def test_a_typo_in_a_key_is_refused_with_the_closest_name(capsys, tmp_path):
    """Old main: planned with the default u_max 1.0, exit 0."""
    path = _with(tmp_path, "u_max: 1.0 ", "u_mx: 5.0 ")
    assert_refused(capsys, ["plan", "--config", path, "--goal", "1"], "u_mx: unknown parameter; did you mean u_max?")


@pytest.mark.parametrize(
    "line, verdict",
    [
        ("state: {source: bogus}", "state.source: must be one of ['measured', 'assumed'], got 'bogus'"),
        ("trajectory: {early_arrival: optimun}", "got 'optimun' (closest: 'optimum')"),
    ],
)
def test_a_node_parameter_outside_its_choices_is_refused_like_the_node_does(capsys, tmp_path, line, verdict):
    """Old main: `flexmotion plan` planned (exit 0) with state.source: bogus; the node refused it."""
    path = _with(tmp_path, "u_max: 1.0 ", f"{line}\n    u_max: 1.0 ")
    assert_refused(capsys, ["plan", "--config", path, "--goal", "1"], verdict)


@pytest.mark.parametrize(
    "method, option, closest",
    [
        ("time_optimal_friction", "colomb_force=0.1", "coulomb_force"),
        ("zvd", "shaper.tolerence=0.2", "shaper.tolerance"),
    ],
)
def test_a_typo_in_an_option_is_refused_with_the_closest_name(capsys, method, option, closest):
    argv = ["plan", "--config", str(WB_CONFIG), "--goal", "2", "--method", method, "--option", option]
    assert_refused(capsys, argv, f"did you mean {closest}?")


def test_an_option_typed_by_rcl_rules(capsys):
    base = ["plan", "--config", str(WB_CONFIG), "--goal", "2", "--method", "time_optimal_friction", "--json"]
    assert_refused(capsys, [*base, "--option", "coulomb_force=0"], "coulomb_force", "write 0.0")
    assert main([*base, "--option", "coulomb_force=0.1"]) == 0
    assert json.loads(capsys.readouterr().out)["method"] == "time_optimal_friction"


def test_an_integer_where_a_double_belongs_is_refused_as_by_the_node(capsys, tmp_path):
    """Old main: ``u_max: 1`` planned here but the node refused the file."""
    path = _with(tmp_path, "u_max: 1.0 ", "u_max: 1 ")
    assert_refused(capsys, ["plan", "--config", path, "--goal", "1"], "u_max: must be a double", "write 1.0")


def test_a_method_without_its_required_option_is_refused(capsys):
    argv = ["plan", "--config", str(WB_CONFIG), "--goal", "1", "--method", "fixed_time"]
    assert_refused(capsys, argv, "arrival_time: required by method fixed_time")


def test_a_directory_as_config_is_one_line(capsys):
    """Old main: IsADirectoryError traceback, exit 1."""
    assert_refused(capsys, ["plan", "--config", str(ROOT / "config"), "--goal", "1"], "config", "is a directory")


@pytest.mark.parametrize("extra", [[], ["--rate", "1000"]])
def test_a_goal_beyond_the_move_budget_is_one_line(capsys, extra):
    """Old main: numpy's ValueError traceback (Maximum allowed size exceeded), exit 1."""
    argv = ["plan", "--config", str(WB_CONFIG), "--goal", "1e300", *extra]
    assert_refused(capsys, argv, "goal: the move needs at least 2.828e+150 s", "max_move_duration_s = 3600 s")


@pytest.mark.parametrize("goal", ["-5.03e-05", "-1E-3", "-.5", "-2.", "-1e+0"])
def test_a_negative_goal_in_any_float_spelling(capsys, goal):
    """Old main: ``--goal -5.03e-05`` was taken for an option ("expected one argument")."""
    out = run_json(capsys, "--config", str(WB_CONFIG), "--goal", goal)
    assert out["duration"] > 0.0 and out["certified"]


def _subparsers(parser):
    for action in parser._actions:
        if isinstance(action.choices, dict):  # a sub-parsers action: name -> parser
            for sub in action.choices.values():
                yield sub
                yield from _subparsers(sub)


def test_every_parser_takes_negative_numbers_in_e_notation():
    """Every sub-command (and ``model``'s kinds): a negative number in e-notation is a value, not an option."""
    parser = cli_main.build_parser()
    subs = list(_subparsers(parser))
    assert len(subs) >= 8  # plan, model (+3 kinds), design, shaper, compare, demo
    for sub in subs:
        for text in ("-5.03e-05", "-1E+3", "-.5e1", "-inf", "-3"):
            assert sub._negative_number_matcher.match(text), (sub.prog, text)
        assert not sub._negative_number_matcher.match("-x") and not sub._negative_number_matcher.match("--goal")
    args = parser.parse_args(["compare", "--config", "c.yaml", "--goal", "-5.03e-05", "--initial-velocity", "-1e-3"])
    assert (args.goal, args.initial_velocity) == (-5.03e-05, -1e-3)
    args = parser.parse_args(["design", "--config", "c.yaml", "--goal", "-1e-1", "--goal", "2e0", "--xtol", "1e-6"])
    assert args.goal == [-0.1, 2.0]
    args = parser.parse_args(["model", "two-mass", "--m1", "1", "--m2", "1", "--k", "1", "--d", "-1e-3"])
    assert args.d == -1e-3


# ----------------------------------------------------- installed console script
def test_installed_console_script():
    """The installed ``flexmotion``: pip's (beside the interpreter) or colcon's (``<prefix>/lib/flexmotion_ros``)."""
    from flexmotion_ros.cli.shipped import find_executable

    exe = find_executable("flexmotion")
    assert exe is not None, (
        f"flexmotion not installed (not in <prefix>/lib/flexmotion_ros, beside {sys.executable}, on PATH)"
    )
    ok = subprocess.run(
        [str(exe), "plan", "--config", str(WB_CONFIG), "--goal", "1.0", "--json"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert ok.returncode == 0, ok.stderr
    out = json.loads(ok.stdout)
    assert out["duration"] == pytest.approx(4.2179, abs=5e-5) and out["certified"] is True
    bad = subprocess.run(
        [str(exe), "plan", "--config", str(WB_CONFIG), "--goal", "nan", "--json"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert bad.returncode == 2 and bad.stdout == ""
    assert bad.stderr.count("\n") == 1 and "goal" in bad.stderr


def test_a_goal_over_the_sample_budget_is_refused_before_planning(capsys, tmp_path):
    """Issue 16: ``--goal 1e6 --rate 200`` was a 47-minute move planned in 8.6 s; now refused up front."""
    argv = ["plan", "--config", str(WB_CONFIG), "--goal", "1e6", "--rate", "200"]
    t0 = time.perf_counter()
    assert_refused(
        capsys, argv, "goal: the move needs at least 5.657e+05 samples at 200 Hz", "max_move_samples = 100000"
    )
    assert time.perf_counter() - t0 < 1.0
    path = _with(tmp_path, "u_max: 1.0 ", "max_move_samples: 600000\n    u_max: 1.0 ")
    assert_refused(capsys, ["plan", "--config", path, "--goal", "1.5e6", "--rate", "200"], "max_move_samples = 600000")


def test_a_mode_above_the_nyquist_frequency_is_refused_with_the_reason(capsys, tmp_path):
    """Issue 16: omega 1e5 rad/s at 1 kHz planned for 36.9 s; the file is refused as the node refuses it."""
    path = _with(tmp_path, "rate_hz: 1000.0", "rate_hz: 0.2")
    assert_refused(
        capsys,
        ["plan", "--config", path, "--goal", "1"],
        "model.omega[0]: 1.41421 rad/s is at or above the Nyquist frequency pi x rate_hz = 0.628319 rad/s",
        "raise rate_hz above 0.450158 Hz",
    )
