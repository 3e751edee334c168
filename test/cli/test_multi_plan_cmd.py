"""``flexmotion plan`` / ``flexmotion model`` with several inputs (issue 12).

The JSON for ``m > 1`` (levels: rows of m; commands: K rows of m; sync),
checked by our own matrix-exponential simulation here (scipy's ``expm`` of
the augmented matrix, not the core's propagation); the stop from a moving,
swaying state; the parameter file strict as for one input (names, types,
controllability); bad input is one line, exit 2, nothing on stdout; the
``model`` builders write files ``plan`` accepts, with the physical map.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from flexmotion_ros.cli.main import main

from .test_plan_cmd import assert_refused, run_json

ROOT = Path(__file__).resolve().parents[2]
GANTRY = ROOT / "config" / "gantry.yaml"
CHAIN = ROOT / "config" / "chain_two_drives.yaml"
WB_CONFIG = ROOT / "config" / "wie_bernstein.yaml"


def system(config_path: Path) -> tuple[np.ndarray, np.ndarray, dict]:
    """A, B of a multi-input parameter file, assembled here from the flat row-major layout (no core code)."""
    import yaml

    p = yaml.safe_load(config_path.read_text())["/**"]["ros__parameters"]
    mdl = p["model"]
    m, k, n_modes = len(mdl["inputs"]), len(mdl["rigid_bodies"]), len(mdl["omega"])
    B0 = np.reshape(mdl["b0"], (k, m))
    Bm = np.reshape(mdl["b"], (n_modes, m))
    n = 2 * (k + n_modes)
    A, B = np.zeros((n, n)), np.zeros((n, m))
    for j in range(k):
        A[2 * j, 2 * j + 1] = 1.0
        A[2 * j + 1, 2 * j + 1] = mdl["c"][j]
        B[2 * j + 1] = B0[j]
    for i, (w, z) in enumerate(zip(mdl["omega"], mdl["zeta"])):
        r = 2 * k + 2 * i
        A[r, r + 1], A[r + 1, r], A[r + 1, r + 1] = 1.0, -w * w, -2.0 * z * w
        B[r + 1] = Bm[i]
    return A, B, p


def propagate(A, B, x0, breaks, rows) -> np.ndarray:
    """Exact state after piecewise-constant rows on [breaks[i], breaks[i+1])."""
    n, m = B.shape
    x = np.asarray(x0, float)
    for h, u in zip(np.diff(breaks), rows):
        M = np.zeros((n + m, n + m))
        M[:n, :n], M[:n, n:] = A * h, B * h
        E = expm(M)
        x = E[:n, :n] @ x + E[:n, n:] @ np.asarray(u, float)
    return x


def test_gantry_json_rows_of_m_reach_the_goals_exactly(capsys):
    out = run_json(capsys, "--config", str(GANTRY), "--goal", "3.0,2.0", "--rate", "100")
    A, B, p = system(GANTRY)
    u_max = np.array(p["u_max"])
    T, sw, levels = out["duration"], out["switch_times"], out["levels"]
    assert out["sync"] == "time" and out["certified"] is True and out["inputs"] == ["trolley", "bridge"]
    assert len(levels) == len(sw) + 1 and all(len(r) == 2 for r in levels)
    assert sw == sorted(sw) and 0.0 < sw[0] and sw[-1] < T
    assert np.all(np.abs(levels) <= u_max * (1 + 1e-12))
    target = np.array([3.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    x_T = propagate(A, B, np.zeros(8), [0.0, *sw, T], levels)
    assert np.max(np.abs(x_T - target)) < 1e-9 * 3.0, x_T
    # the sampled plan: K rows of m, exact at the last sample, never above any bound
    K, cmds = out["samples"], np.array(out["commands"])
    assert cmds.shape == (K, 2) and out["minimal"] is True
    assert np.all(np.max(np.abs(cmds), axis=0) <= u_max)
    x_K = propagate(A, B, np.zeros(8), np.arange(K + 1) / 100.0, cmds)
    assert np.max(np.abs(x_K - target)) < 1e-9 * 3.0, x_K
    assert (K - 1) / 100.0 < T <= K / 100.0 + 1e-12  # the fewest samples: not below the continuous optimum
    for key in ("solve_time_s", "sampled_solve_time_s", "plan_time_s", "final_state_error"):
        assert out[key] >= 0.0


def test_stop_from_a_moving_swaying_state_frees_every_position(capsys):
    x0 = [1.0, 0.5, 0.0, 0.1, 0.01, 0.0, 0.0, 0.02]
    out = run_json(capsys, "--config", str(GANTRY), "--initial-state", ",".join(map(str, x0)), "--rate", "100")
    A, B, _ = system(GANTRY)
    x_T = propagate(A, B, x0, [0.0, *out["switch_times"], out["duration"]], out["levels"])
    assert np.max(np.abs(x_T[[1, 3, 4, 5, 6, 7]])) < 1e-9  # at rest, no sway
    np.testing.assert_allclose(out["stop_positions"], x_T[[0, 2]], atol=1e-9)
    K = out["samples"]
    x_K = propagate(A, B, x0, np.arange(K + 1) / 100.0, out["commands"])
    assert np.max(np.abs(x_K[[1, 3, 4, 5, 6, 7]])) < 1e-9
    np.testing.assert_allclose(out["sampled_stop_positions"], x_K[[0, 2]], atol=1e-9)


def test_coupled_two_drive_chain_and_the_text_summary(capsys):
    out = run_json(capsys, "--config", str(CHAIN), "--goal", "1.0")
    assert out["certified"] is True and all(len(r) == 2 for r in out["levels"])
    assert main(["plan", "--config", str(CHAIN), "--goal", "1.0", "--rate", "1000"]) == 0
    text = capsys.readouterr().out
    assert "inputs f0, f3" in text and "peak command      f0" in text and "proved fewest" in text


def test_single_input_output_is_unchanged_flat_lists(capsys):
    out = run_json(capsys, "--config", str(WB_CONFIG), "--goal", "1.0", "--rate", "100")
    assert all(isinstance(v, float) for v in out["levels"]) and all(isinstance(v, float) for v in out["commands"])
    assert "sync" not in out and "inputs" not in out
    # the whole start state works for one input too: [p, v, q, q']
    out = run_json(capsys, "--config", str(WB_CONFIG), "--initial-state", "0,0.8,0,0")
    assert out["certified"] is True and "stop_position" in out


def _file(tmp_path: Path, old: str, new: str, base: Path = GANTRY) -> str:
    text = base.read_text()
    assert old in text, old
    path = tmp_path / "bad.yaml"
    path.write_text(text.replace(old, new))
    return str(path)


#: (old text, new text, fragments of the one-line refusal)
BAD_FILES = [
    ("rigid_bodies:", "rigid_bodys:", ["model.rigid_bodys: unknown parameter; did you mean model.rigid_bodies?"]),
    (
        "u_max: [300.0, 500.0]",
        "u_max: [300, 500]",
        ["u_max: must be a double or a double array", "write [300.0, 500.0]"],
    ),
    ("u_max: [300.0, 500.0]", "u_max: [300.0]  ", []),  # one bound for every input: accepted
    ("u_max: [300.0, 500.0]", "u_max: [300.0, 500.0, 1.0]", ["u_max: needs one bound per input"]),
    ("b0: [0.0033333333333333335, 0.0, 0.0, 0.00125]", "b0: [0.0033, 0.0, 0.0, 0.0]", ["model.b0[1]", "'y'"]),
    ("b: [-0.005, 0.0, 0.0, -0.0014285714285714286]", "b: [-0.005, 0.0, 0.0, 0.0]", ["sway_y", "uncontrollable"]),
    ("b0: [0.0033333333333333335, 0.0, 0.0, 0.00125]", "b0: [0.0033, 0.0, 0.0]", ["model.b0", "k x m = 2 x 2"]),
    ("sync: time", "sync: tme", ["sync: must be one of ['time', 'none', 'phase']"]),
    ("method: time_optimal", "method: robust_time_optimal", ["robust_time_optimal is not available for multi-input"]),
    ("rigid_bodies: [x, 'y']", "rigid_bodies: [x, y]", ["model.rigid_bodies", "quote a name such as 'y'"]),
    # the planner node's one-input features: the node's verdict (test_multi_axis) on the same file
    ("sync: time", "sync: time\n    output: trajectory", ["output: is one-input only for now, got 'trajectory'"]),
    ("sync: time", "sync: time\n    command_interface: velocity", ["command_interface: is one-input only for now"]),
    ("sync: time", "sync: time\n    output: stream", []),  # the force stream: accepted
    (
        "sync: time",
        "sync: time\n    feedback:\n      replan_period_s: 0.1",
        ["feedback.replan_period_s: closed-loop replanning is one-input only"],
    ),
]


@pytest.mark.parametrize("old, new, fragments", BAD_FILES)
def test_a_bad_multi_input_file_is_one_line(capsys, tmp_path, old, new, fragments):
    path = _file(tmp_path, old, new)
    argv = ["plan", "--config", path, "--goal", "1.0,1.0"]
    if not fragments:
        assert main([*argv, "--json"]) == 0
        return
    assert_refused(capsys, argv, *fragments)


def test_a_list_in_a_single_input_file_asks_for_model_inputs(capsys, tmp_path):
    path = _file(tmp_path, "u_max: 1.0", "u_max: [1.0, 2.0]", WB_CONFIG)
    assert_refused(capsys, ["plan", "--config", path, "--goal", "1"], "u_max", "set model.inputs")
    path = _file(tmp_path, "u_max: 1.0", "u_max: 1.0\n    sync: none", WB_CONFIG)
    assert_refused(capsys, ["plan", "--config", path, "--goal", "1"], "sync: is read by multi-input models only")


@pytest.mark.parametrize(
    "args, fragments",
    [
        (["--goal", "3.0"], ["goal: needs one target per rigid body ['x', 'y'] (2), got 1"]),
        (["--goal", "3.0,abc"], ["goal: --goal takes numbers"]),
        (["--goal", "3.0,nan"], ["goal: must be finite"]),
        (["--initial-state", "1,2,3"], ["initial_state: needs the whole state, 8 values", "sway_y_dot"]),
        (["--initial-velocity", "1.0"], ["initial_velocity", "--initial-state"]),
        ([], ["goal: give --goal"]),
        (["--goal", "1e300,1"], ["goal: the move needs at least", "max_move_duration_s"]),
        (["--goal", "1e4,1", "--rate", "1000"], ["max_move_samples = 100000"]),
    ],
)
def test_bad_goals_are_one_line(capsys, args, fragments):
    assert_refused(capsys, ["plan", "--config", str(GANTRY), *args], *fragments)


def test_single_input_takes_one_goal(capsys):
    assert_refused(capsys, ["plan", "--config", str(WB_CONFIG), "--goal", "1,2"], "goal", "takes one target")


def test_negative_comma_goal_is_a_value_not_an_option(capsys):
    out = run_json(capsys, "--config", str(GANTRY), "--goal", "-1.0,2.0")
    assert out["certified"] is True


@pytest.mark.parametrize(
    "argv, inputs, physical",
    [
        (
            ["gantry", "--trolley-mass", "10", "--bridge-mass", "40", "--payload-mass", "5", "--rope-length", "2"],
            ["trolley", "bridge"],
            ["trolley_x = +1 x", "payload_y = +1 y"],
        ),
        (
            ["chain", "--masses", "1,1,1,1", "--springs", "400,400,400", "--actuated", "0,3", "--u-max-each", "1,2"],
            ["f0", "f3"],
            ["x1 = +1 x", "x4 = +1 x"],
        ),
        (["two-mass", "--m1", "1", "--m2", "2", "--k", "3", "--actuated", "0,1"], ["f0", "f1"], ["x2 = +1 x"]),
    ],
)
def test_model_builders_write_files_that_plan_accepts(capsys, tmp_path, argv, inputs, physical):
    path = tmp_path / "model.yaml"
    assert main(["model", *argv, "-o", str(path)]) == 0
    capsys.readouterr()
    text = path.read_text()
    for fragment in physical:
        assert fragment in text, text
    assert f"inputs {inputs}" in text
    k = 2 if argv[0] == "gantry" else 1
    out = run_json(capsys, "--config", str(path), "--goal", ",".join(["0.5"] * k), "--rate", "200")
    assert out["inputs"] == inputs and out["certified"] is True
    assert np.array(out["commands"]).shape == (out["samples"], len(inputs))
    if "--u-max-each" in argv:
        assert np.max(np.abs(np.array(out["commands"])), axis=0).tolist() <= [1.0, 2.0]


@pytest.mark.parametrize(
    "argv, fragments",
    [
        (["chain", "--masses", "1,1", "--springs", "1", "--actuated", "0,5"], ["actuated: must be mass indices"]),
        (["chain", "--masses", "1,1", "--springs", "1", "--actuated", "0,x"], ["actuated", "0,3"]),
        (["two-mass", "--m1", "1", "--m2", "1", "--k", "1", "--u-max-each", "1,2"], ["u_max_each", "--actuated"]),
        (
            ["two-mass", "--m1", "1", "--m2", "1", "--k", "1", "--actuated", "0,1", "--u-max-each", "1,2,3"],
            ["u_max: needs one bound per actuated mass (2)"],
        ),
        (
            ["gantry", "--trolley-mass", "-1", "--bridge-mass", "1", "--payload-mass", "1", "--rope-length", "1"],
            ["trolley_mass"],
        ),
    ],
)
def test_bad_model_arguments_are_one_line(capsys, argv, fragments):
    assert_refused(capsys, ["model", *argv], *fragments)


def test_json_is_one_object(capsys):
    assert main(["plan", "--config", str(GANTRY), "--goal", "1,1", "--json"]) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and isinstance(json.loads(out), dict)


def test_a_femtometre_goal_on_the_gantry_is_already_there(capsys):
    """``plan --goal 1e-15,0 --rate 200``: the hold, said as for one input (a 0.53 ms, 4-sample move on 2b3dc69)."""
    assert main(["plan", "--config", str(GANTRY), "--goal", "1e-15,0", "--rate", "200"]) == 0
    text, _ = capsys.readouterr()
    assert "certified         True (already there: every state within" in text, text
    assert "samples           0 (0.000000 s, proved fewest)" in text
    assert "peak command      trolley 0, bridge 0" in text
    out = run_json(capsys, "--config", str(GANTRY), "--goal", "1e-15,0", "--rate", "200")
    assert out["already_there"] is True and out["duration"] == 0.0 and out["samples"] == 0
    assert out["commands"] == [] and out["certified"] is True
