"""The design figure (``plots/design.py``), read back: a failed design point is drawn where the optimum star
cannot hide it, the bounds are lines (no shading over the whole plot), every curve is in the legend."""

import math
from pathlib import Path

import numpy as np

from flexmotion_ros.cli.main import main
from flexmotion_ros.core.errors import SolverError
from flexmotion_ros.core.methods import table
from flexmotion_ros.plots import design as design_plot

ROOT = Path(__file__).resolve().parents[2]


def test_failed_point_is_visible_and_bounds_do_not_fill_the_plot(tmp_path, monkeypatch, capsys):
    figures = []
    original = design_plot.plot_design

    def keep(*a, **k):
        figures.append(original(*a, **k))
        return figures[-1]

    monkeypatch.setattr(design_plot, "plot_design", keep)
    # one design point must fail; the planner no longer fails on any of this sweep (issue 15), so a
    # failure is injected at the middle of the log grid, k = sqrt(0.5 * 20) N/m (omega = sqrt(2 k) rad/s)
    plan_move = table.plan_move

    def failing_plan_move(config, problem, rate_hz=None):
        if abs(config.model.omega[0] - math.sqrt(2.0 * math.sqrt(10.0))) < 1e-9:
            raise SolverError("injected failure")
        return plan_move(config, problem, rate_hz)

    monkeypatch.setattr(table, "plan_move", failing_plan_move)
    png = tmp_path / "design.png"
    argv = ["design", "--config", str(ROOT / "config" / "design_two_mass.yaml"), "--param", "k=0.5:20"]
    assert main([*argv, "--goal", "1.0", "--grid", "9", "--plot", str(png)]) == 0
    capsys.readouterr()
    assert png.stat().st_size > 10_000
    ax = figures[0].axes[0]
    by_label = {ln.get_label(): ln for ln in ax.get_lines()}
    star = next(ln for k, ln in by_label.items() if k.startswith("optimum"))
    failed = next(ln for k, ln in by_label.items() if k.startswith("infeasible / failed"))
    assert failed.get_zorder() > star.get_zorder() and failed.get_color() != star.get_color()
    # in display coordinates the cross is well away from the star, even at the same parameter value
    fig = figures[0]
    fig.canvas.draw()
    p_star = ax.transData.transform(np.column_stack([star.get_xdata(), star.get_ydata()]))[0]
    p_bad = failed.get_transform().transform(np.column_stack([failed.get_xdata(), failed.get_ydata()]))
    assert np.min(np.abs(p_bad[:, 1] - p_star[1])) > 20.0  # pixels
    # no patch (axvspan) spans the plot: the bounds are vertical lines
    x0, x1 = ax.get_xlim()
    for patch in ax.patches:
        ext = patch.get_extents()
        assert ext.width < 0.5 * ax.bbox.width
    assert any(k.startswith("bounds") for k in by_label)
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    for label in by_label:
        if not label.startswith("_"):
            assert label in legend
    assert "(N/m)" in ax.get_xlabel() and "(s)" in ax.get_ylabel()
    assert x0 < x1
