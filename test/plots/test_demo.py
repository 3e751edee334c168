"""The demo figure (``plots/demo.py``), read back from the Figure: the time axis covers a few periods of the
slowest mode after arrival, the residual panel shows 1e-3 of the move, units come from the parameter file,
and the legend names every curve.  Synthetic data: the exact plant response, no DDS."""

import math
from pathlib import Path

import numpy as np
import pytest

from flexmotion_ros.core.config import load_config
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.model.boundary import rest_to_rest
from flexmotion_ros.core.simulation.exact import modal_amplitudes, simulate_samples
from flexmotion_ros.plots.demo import PERIODS_AFTER, RESIDUAL_MARK, continuation, meaning_from_file, plot_demo

ROOT = Path(__file__).resolve().parents[2]
CRANE = ROOT / "config" / "crane.yaml"
WB = ROOT / "config" / "wie_bernstein.yaml"


def legend_covers_every_curve(ax) -> None:
    """Every labelled line of ``ax`` is in its legend, with its own entry."""
    legend = ax.get_legend()
    assert legend is not None
    texts = [t.get_text() for t in legend.get_texts()]
    labels = [ln.get_label() for ln in ax.get_lines() if not ln.get_label().startswith("_")]
    assert labels, "no labelled curve"
    for label in labels:
        assert label in texts, f"{label!r} not in the legend {texts}"


def _demo_figure(path, config_file, goal, omega_scale):
    config = load_config(config_file)
    rate = 1000.0
    dt = 1.0 / rate
    result = plan_move(config, rest_to_rest(config.model, config.u_max, goal), rate_hz=rate)
    u = np.append(result.sampled.commands, 0.0)  # the move, then one hold sample
    plant = config.model.with_changes(omega=tuple(omega_scale * w for w in config.model.omega))
    X = simulate_samples(plant, plant.rest_state(), u, dt)[1:]  # the state after each command
    t_x = dt * np.arange(1, len(X) + 1)
    t_after, X_after = continuation(plant, float(t_x[-1]), X[-1])
    fig = plot_demo(
        path,
        dt * np.arange(u.size),
        u,
        config.u_max,
        t_x,
        X,
        dt * np.arange(u.size),
        np.linspace(0.0, goal, u.size),
        goal,
        plant.names,
        "test",
        model=plant,
        meaning=meaning_from_file(config_file, config.model),
        t_arrival=result.sampled.duration,
        t_after=t_after,
        states_after=X_after,
    )
    return fig, plant, t_x, X, X_after


def test_crane_with_model_error_shows_the_residual_swing_after_arrival(tmp_path):
    fig, plant, t_x, X, X_after = _demo_figure(tmp_path / "demo.png", CRANE, 2.0, 1.1)
    assert (tmp_path / "demo.png").stat().st_size > 10_000
    ax_u, ax_p, ax_q, ax_r = fig.axes[:4]
    slowest = 2.0 * math.pi / float(np.min(plant.omega_d))
    lo, hi = ax_r.get_xlim()
    assert lo <= 0.0 and hi >= t_x[-1] + PERIODS_AFTER * slowest - 1e-9  # the post-arrival window is on the axis
    # the continuation is the plant's free response: its swing amplitude is the summary's residual
    amp_end = modal_amplitudes(plant, X[-1])
    assert amp_end[0] > 0.1  # 10 % frequency error on the crane: tens of cm of swing
    t_after = np.linspace(t_x[-1], t_x[-1] + PERIODS_AFTER * slowest, len(X_after))
    decay = np.exp(-plant.zeta[0] * plant.omega[0] * (t_after - t_x[-1]))
    assert np.allclose(modal_amplitudes(plant, X_after)[:, 0], amp_end[0] * decay, rtol=1e-9)
    swing = [ln for ln in ax_q.get_lines() if "computed" in ln.get_label()]
    # its first peak is the swing amplitude, damped a little
    assert swing and np.max(np.abs(swing[0].get_ydata())) == pytest.approx(amp_end[0], rel=3e-2)
    ylo, yhi = ax_q.get_ylim()
    assert ylo < -amp_end[0] and yhi > amp_end[0]  # the swing is inside the deflection axis
    # units named by the file's builder header
    assert ax_q.get_ylabel() == "deflection (m)"
    assert "centre of mass" in ax_p.get_ylabel() and "(m)" in ax_p.get_ylabel()
    assert any("payload offset from the cart" in ln.get_label() for ln in ax_q.get_lines())
    assert ax_u.get_ylabel() == "command u (N)"
    # residual panel: log scale on which 1e-3 of the move is well inside
    assert ax_r.get_yscale() == "log"
    rlo, rhi = ax_r.get_ylim()
    assert rlo <= RESIDUAL_MARK / 100 and rhi >= RESIDUAL_MARK * 100
    assert "move" in ax_r.get_ylabel() and "time" in ax_r.get_xlabel() and "(s)" in ax_r.get_xlabel()
    for ax in (ax_u, ax_p, ax_q, ax_r):
        legend_covers_every_curve(ax)


def test_without_a_physical_map_the_deflection_is_a_modal_coordinate(tmp_path):
    fig, *_ = _demo_figure(tmp_path / "demo.png", WB, 1.0, 1.0)
    ax_p, ax_q = fig.axes[1], fig.axes[2]
    assert ax_q.get_ylabel().startswith("modal coordinate")
    assert "(m)" not in ax_q.get_ylabel() and "(m)" not in ax_p.get_ylabel()
    assert "rigid-body coordinate" in ax_p.get_ylabel()


def test_meaning_comes_only_from_a_header_that_matches_the_model(tmp_path):
    crane = load_config(CRANE)
    m = meaning_from_file(CRANE, crane.model)
    assert m.unit == "m" and m.deflections == ("payload offset from the cart",)
    edited = tmp_path / "edited.yaml"  # same header, different model: the map no longer holds
    edited.write_text(CRANE.read_text().replace("2.4761361028828768", "3.0"))
    assert meaning_from_file(edited, load_config(edited).model).unit is None
    assert meaning_from_file(WB, load_config(WB).model).unit is None
