"""``flexmotion plan`` printouts say what is true: where a stop ends, levels that are zero printed as 0 with
the tolerance, what a friction certificate proved, and the sampled plan's own solve time in JSON."""

import json
from pathlib import Path

from flexmotion_ros.cli.main import main
from flexmotion_ros.cli.plan_cmd import LEVEL_ZERO, _text

ROOT = Path(__file__).resolve().parents[2]
WB = str(ROOT / "config" / "wie_bernstein.yaml")


def _run(capsys, *argv) -> str:
    assert main(["plan", "--config", WB, *argv]) == 0
    return capsys.readouterr().out


def test_a_stop_prints_where_it_stops(capsys):
    data = json.loads(_run(capsys, "--initial-velocity", "0.8", "--rate", "1000", "--json"))
    assert data["stop_position"] == data["final_state"][0] and data["stop_position"] > 0.5
    assert abs(data["sampled_stop_position"] - data["stop_position"]) < 1e-2
    text = _run(capsys, "--initial-velocity", "0.8", "--rate", "1000")
    assert f"stops at          {data['stop_position']:.9f} (final position free)" in text
    assert f"sampled stops at  {data['sampled_stop_position']:.9f}" in text
    assert "stops at" not in _run(capsys, "--goal", "1")


def test_rounding_level_zero_is_printed_as_zero_with_the_tolerance():
    text = _text({"method": "limited", "levels": [1.0, -8.22118e-14, 0.5, -1.0]})
    line = next(ln for ln in text.splitlines() if ln.startswith("levels"))
    assert "e-14" not in line and "+1, 0, +0.5, -1" in line and f"{LEVEL_ZERO:g} of the largest" in line
    assert "printed as 0" not in _text({"method": "x", "levels": [1.0, -1.0]})


def test_friction_prints_only_what_was_proved(capsys):
    text = _run(capsys, "--goal", "2", "--method", "time_optimal_friction", "--option", "coulomb_force=0.1")
    assert "certified         True" not in text
    cert = next(ln for ln in text.splitlines() if ln.startswith("certificate"))
    assert "necessary conditions only" in cert and "not proved" in cert
    assert "lower bound" in text


def test_json_with_a_rate_has_the_sampled_solve_time(capsys):
    data = json.loads(_run(capsys, "--goal", "1", "--rate", "1000", "--json"))
    assert data["sampled_solve_time_s"] > 0.0
    assert data["plan_time_s"] >= data["sampled_solve_time_s"] and data["plan_time_s"] >= data["solve_time_s"]
    assert "sampled_solve_time_s" not in json.loads(_run(capsys, "--goal", "1", "--json"))
