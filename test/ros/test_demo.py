"""``flexmotion demo`` for one input, the README's main job, shortened: planner and plant processes over real DDS."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_demo_arrives_at_rest_and_draws_the_move(tmp_path, capsys):
    from flexmotion_ros.cli.main import main

    png = tmp_path / "demo.png"
    config = str(ROOT / "config" / "wie_bernstein.yaml")
    status = main(["demo", "--config", config, "--goal", "0.5", "--rate", "100.0", "--plot", str(png)])
    out = capsys.readouterr().out
    assert status == 0, out
    assert "measured arrival     " in out and "within 1e-06 of the move" in out, out
    assert "certified true" in out and "peak |command|" in out, out
    assert png.stat().st_size > 10_000
