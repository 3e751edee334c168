"""``flexmotion plan`` / ``flexmotion model``: JSON fields, checked by our own simulation;
bad input gives one line on stderr, exit status 2 and nothing on stdout."""

import itertools
import json
import math
import subprocess
import sys
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


# ----------------------------------------------------- installed console script
def test_installed_console_script():
    exe = Path(sys.executable).parent / "flexmotion"
    assert exe.exists(), f"{exe} not installed"
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
