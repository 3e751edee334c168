"""``flexmotion shaper``, ``flexmotion compare`` and the shaping methods through ``flexmotion plan``."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from flexmotion_ros.cli.main import main
from flexmotion_ros.core import load_config, rest_to_rest, simulate_samples
from flexmotion_ros.core.methods import METHODS, plan_move
from flexmotion_ros.core.shaping.shapers import SHAPERS

WB_FILE = str(Path(__file__).resolve().parents[2] / "config" / "wie_bernstein.yaml")
WB_TEXT = Path(WB_FILE).read_text()


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_shaper_json(capsys):
    code, out, err = run(capsys, "shaper", "zvd", "--omega", "2", "--zeta", "0", "--json")
    assert code == 0 and err == ""
    d = json.loads(out)
    assert d["amplitudes"] == pytest.approx([0.25, 0.5, 0.25], abs=1e-15)
    assert d["times"] == pytest.approx([0.0, math.pi / 2, math.pi], abs=1e-15)
    code, out, _ = run(capsys, "shaper", "ei", "--omega", "2", "--zeta", "0.05")
    assert code == 0 and "numerically solved" in out and "insensitivity" in out


@pytest.mark.parametrize(
    "argv,param",
    [
        (["shaper", "zv", "--omega", "-2", "--zeta", "0"], "omega[0]"),
        (["shaper", "ei", "--omega", "2", "--zeta", "0", "--tolerance", "0.9"], "shaper.tolerance"),
        (["shaper", "zv", "--omega", "2,3", "--zeta", "0"], "omega/zeta"),
        (["shaper", "nope", "--omega", "2", "--zeta", "0"], "invalid choice"),
        (["compare", "--config", WB_FILE, "--goal", "1", "--freq-error", "1.5"], "freq_error"),
        (["compare", "--config", WB_FILE, "--goal", "1", "--methods", "zv,bogus"], "methods"),
        (
            ["plan", "--config", WB_FILE, "--goal", "1", "--method", "robust_time_optimal", "--robust-order", "9"],
            "robust_order",
        ),
    ],
)
def test_errors_are_one_line_exit_2(capsys, argv, param):
    code = None
    try:
        code, out, err = run(capsys, *argv)
    except SystemExit as e:  # argparse errors exit directly
        code = e.code
        out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and param in err


def test_plan_with_shaper_and_robust_methods(capsys):
    code, out, _ = run(capsys, "plan", "--config", WB_FILE, "--goal", "1", "--method", "zvd", "--json", "--rate", "100")
    assert code == 0
    d = json.loads(out)
    assert d["method"] == "zvd"
    assert d["duration"] == pytest.approx(4.2178665 + 3.0534, abs=1e-3)  # rigid 2 sqrt(2) + Td = 2 pi / sqrt 2
    assert d["added_time_s"] == pytest.approx(d["duration"] - d["time_optimal_duration"], abs=1e-12)
    assert d["shaper_insensitivity_width"][0] == pytest.approx(0.2871, abs=1e-4)
    assert max(abs(v) for v in d["commands"]) <= 1.0 and d["sampled_final_state_error_relative"] < 1e-9
    code, out, _ = run(
        capsys,
        "plan",
        "--config",
        WB_FILE,
        "--goal",
        "1",
        "--method",
        "robust_time_optimal",
        "--robust-order",
        "1",
        "--json",
    )
    d = json.loads(out)
    assert d["duration"] == pytest.approx(5.866, abs=5e-4) and d["certified"] and d["robust_order"] == 1
    code, out, _ = run(capsys, "plan", "--config", WB_FILE, "--goal", "1", "--method", "um_zv")
    assert code == 0 and "um_zv" in out and "certified         False" in out


def test_every_method_is_registered_and_plans_exactly():
    assert set(SHAPERS) | {"robust_time_optimal", "time_optimal"} <= set(METHODS)
    cfg = load_config(WB_FILE)
    pb = rest_to_rest(cfg.model, cfg.u_max, 1.0)
    for m in sorted(SHAPERS) + ["robust_time_optimal"]:
        r = plan_move(cfg.with_changes(method=m), pb, rate_hz=50.0)
        x = simulate_samples(cfg.model, pb.x0, r.sampled.commands, r.sampled.dt)[-1]
        assert np.max(np.abs(x - [1.0, 0, 0, 0])) < 1e-9, m
        assert np.max(np.abs(r.sampled.commands)) <= cfg.u_max
        assert r.info["added_time_s"] > 0 and "insensitivity_width" in r.info


def test_options_are_validated(tmp_path, capsys):
    text = WB_TEXT + "    shaper:\n      tolerance: 0.7\n"
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    code, out, err = run(capsys, "plan", "--config", str(f), "--goal", "1", "--method", "ei")
    assert code == 2 and out == "" and "shaper.tolerance" in err and "(0, 0.5)" in err
    good = tmp_path / "good.yaml"
    good.write_text(WB_TEXT + "    shaper:\n      tolerance: 0.1\n")
    code, out, _ = run(capsys, "plan", "--config", str(good), "--goal", "1", "--method", "ei", "--json")
    assert code == 0 and json.loads(out)["residual_percent"] > 0  # EI leaves V at the design point


def test_compare_table_json_and_plot(tmp_path, capsys):
    png = tmp_path / "cmp.png"
    code, out, _ = run(
        capsys,
        "compare",
        "--config",
        WB_FILE,
        "--goal",
        "1",
        "--methods",
        "zv,zvd,robust_time_optimal",
        "--json",
        "--plot",
        str(png),
    )
    assert code == 0 and png.stat().st_size > 10_000
    rows = {r["method"]: r for r in json.loads(out)}
    assert list(rows) == ["time_optimal", "zv", "zvd", "robust_time_optimal"]
    assert rows["time_optimal"]["added_time_s"] == 0.0
    for r in rows.values():
        assert r["residual_percent"] < 1e-9 and r["peak_command"] <= 1.0
    # robustness ordering within +/-10 %: time-optimal worst, ZVD best of these
    worst = {m: r["worst_in_band_percent"] for m, r in rows.items()}
    assert worst["zvd"] < worst["robust_time_optimal"] < worst["time_optimal"]
    code, out, _ = run(capsys, "compare", "--config", WB_FILE, "--goal", "1", "--methods", "zv")
    assert code == 0 and "worst" in out and "zv" in out
