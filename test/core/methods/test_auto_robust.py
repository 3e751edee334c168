"""``auto_robust`` against an independent check: the exact simulation of each candidate's commands on
models whose frequency is moved across the interval (matrix exponentials, from rest)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flexmotion_ros.core.config import load_config
from flexmotion_ros.core.errors import ConfigError
from flexmotion_ros.core.methods.auto_robust import CANDIDATES, GRID, worst_vibration
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.model.boundary import rest_to_rest, state_to_rest
from flexmotion_ros.core.shaping.sensitivity import command_vibration
from flexmotion_ros.core.simulation.exact import PiecewiseConstant, modal_amplitudes, simulate_samples

ROOT = Path(__file__).resolve().parents[3]
RATE = 100.0


def exact_worst(commands, config, lo, hi, points=41, x0=None) -> float:
    """Worst residual over the interval, relative to a step of u_max, by exact simulation of perturbed models."""
    m = config.model
    worst = 0.0
    for w in np.linspace(lo, hi, points):
        true = m.with_changes(omega=(w,))
        x = simulate_samples(true, true.rest_state() if x0 is None else x0, commands, 1.0 / RATE)[-1]
        step = abs(m.b[0]) * config.u_max / (w * w * np.sqrt(1.0 - m.zeta[0] ** 2))
        worst = max(worst, float(modal_amplitudes(true, x)[0]) / step)
    return worst


@pytest.fixture(scope="module")
def config():
    return load_config(ROOT / "config" / "wie_bernstein.yaml")


def test_a_known_frequency_gets_the_time_optimal_move(config):
    cfg = config.with_changes(method="auto_robust", options={"auto_robust.relative_error": 0.0})
    problem = rest_to_rest(cfg.model, cfg.u_max, 1.0)
    res = plan_move(cfg, problem, RATE)
    ref = plan_move(config.with_changes(method="time_optimal"), problem, RATE)
    assert res.info["chosen_method"] == "time_optimal" and res.method == "auto_robust"
    np.testing.assert_array_equal(res.sampled.commands, ref.sampled.commands)


@pytest.mark.parametrize("error", [0.03, 0.12])
def test_the_choice_covers_the_interval_and_nothing_faster_does(config, error):
    w = config.model.omega[0]
    lo, hi = w * (1 - error), w * (1 + error)
    cfg = config.with_changes(
        method="auto_robust", options={"auto_robust.omega_min": [lo], "auto_robust.omega_max": [hi]}
    )
    problem = rest_to_rest(cfg.model, cfg.u_max, 1.0)
    res = plan_move(cfg, problem, RATE)
    report = res.info["auto_robust"]
    assert report["chosen"] != "time_optimal"
    assert exact_worst(res.sampled.commands, cfg, lo, hi) <= 0.05 * (1 + 1e-6)
    # every faster candidate leaves more than the tolerance somewhere in the interval (exact simulation)
    for label, method, extra in CANDIDATES:
        other = plan_move(config.with_changes(method=method, options=extra), problem, RATE)
        if other.sampled.duration < res.sampled.duration - 1e-12:
            assert exact_worst(other.sampled.commands, cfg, lo, hi, points=81) > 0.05, label


def test_bad_intervals_are_refused(config):
    problem = rest_to_rest(config.model, config.u_max, 1.0)
    for options, name in (
        ({"auto_robust.omega_min": [1.0]}, "auto_robust.omega_min/omega_max"),
        ({"auto_robust.omega_min": [1.0, 2.0], "auto_robust.omega_max": [2.0, 3.0]}, "auto_robust.omega_min"),
        ({"auto_robust.omega_min": [2.0], "auto_robust.omega_max": [1.0]}, "auto_robust.omega_min[0]"),
        ({"auto_robust.relative_error": 1.5}, "auto_robust.relative_error"),
    ):
        with pytest.raises(ConfigError) as err:
            plan_move(config.with_changes(method="auto_robust", options=options), problem, RATE)
        assert err.value.parameter == name, err.value


def test_the_worst_case_from_a_vibrating_start_matches_the_exact_simulation(config):
    """From rest the closed form is the shaping module's; from a vibrating state, the exact simulation's."""
    w = config.model.omega[0]
    lo, hi = np.array([0.9 * w]), np.array([1.1 * w])
    x0 = np.array([0.2, 0.1, 0.3, -0.2])
    problem = state_to_rest(config.model, config.u_max, x0, 1.0)
    res = plan_move(config, problem, RATE)
    u = PiecewiseConstant.from_samples(res.sampled.commands, 1.0 / RATE)
    for start in (None, x0):
        closed = worst_vibration(u, config, lo, hi, start)
        grid = np.linspace(lo[0], hi[0], GRID)
        exact = exact_worst(res.sampled.commands, config, lo[0], hi[0], points=GRID, x0=start)
        assert closed == pytest.approx(exact, rel=1e-9), (start, closed, exact)
        if start is None:
            ref = float(np.max(command_vibration(u, grid, config.model.zeta[0], config.u_max)))
            assert closed == ref
