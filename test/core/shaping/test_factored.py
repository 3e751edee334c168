"""Convolved shapers evaluated by their factors: same figures and final state, work of the factors only.

An 8-mode UM-ZVD or EI3 shaper has 5^8 = 390,625 impulses and its shaped
command about a million pieces: the exact check simulated it piece by piece
(one ``expm`` each, over a minute of CPU: fuzz seed 15, cases 0, 2, 20, 25 ran
past the 30 s guard) and the insensitivity figures summed every impulse at
every ratio.  These tests hold the factorised evaluations to the direct ones
on small shapers, and bound the work on a large one by counting exponentials.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import flexmotion_ros.core.shaping.shaped_command as shaped_command_module
import flexmotion_ros.core.simulation.exact as exact_module
from flexmotion_ros.core.model.boundary import rest_to_rest
from flexmotion_ros.core.model.modal_model import ModalModel
from flexmotion_ros.core.shaping.numerical_shapers import impulse_vibration
from flexmotion_ros.core.shaping.sensitivity import command_insensitivity, shaper_insensitivity
from flexmotion_ros.core.shaping.shaped_command import ShapedCommand, factored_final_state
from flexmotion_ros.core.shaping.shaped_profile import plan_shaped
from flexmotion_ros.core.shaping.shaper import Shaper
from flexmotion_ros.core.shaping.shapers import design
from flexmotion_ros.core.simulation.exact import PiecewiseConstant, simulate

M3 = ModalModel(b0=0.7, c=-0.2, omega=(1.3, 4.1, 9.7), zeta=(0.05, 0.12, 0.2), b=(1.1, -0.6, 0.4))


def plain(shaper: Shaper) -> Shaper:
    """The same impulses without their factors (evaluated directly)."""
    return Shaper(shaper.name, shaper.times, shaper.amplitudes, shaper.omega, shaper.zeta, shaper.exact)


@pytest.mark.parametrize("name", ["um_zvd", "ei3", "zvd", "sna"])
def test_convolved_shaper_keeps_its_factors_and_the_same_vibration(name):
    s = design(name, M3.omega, M3.zeta)
    assert len(s.factors) == 3
    w = np.linspace(0.2, 20.0, 301)
    for z in (0.0, 0.1):
        direct = impulse_vibration(s.times, s.amplitudes, w, z)
        assert np.allclose(s.vibration(w, z), direct, rtol=1e-9, atol=1e-12)
    for mode in range(3):
        a, b = shaper_insensitivity(s, 0.05, mode), shaper_insensitivity(plain(s), 0.05, mode)
        assert a.low == pytest.approx(b.low, abs=1e-9) and a.high == pytest.approx(b.high, abs=1e-9)


@pytest.mark.parametrize("name", ["um_zvd", "ei3", "zvdd"])
def test_shaped_command_figures_and_final_state_by_factors_equal_the_direct_ones(name):
    problem = rest_to_rest(M3, 0.9, 1.7)
    profile = plan_shaped(problem, design(name, M3.omega, M3.zeta), name)
    cmd = profile.command
    assert isinstance(cmd, ShapedCommand) and len(cmd.factors) == 3
    direct = PiecewiseConstant(cmd.breaks, cmd.levels)
    a = command_insensitivity(cmd, M3, 0.05, 0.9)
    b = command_insensitivity(direct, M3, 0.05, 0.9)
    assert a.low == pytest.approx(b.low, abs=1e-8) and a.high == pytest.approx(b.high, abs=1e-8)
    x_sim = simulate(M3, problem.x0, direct, times=[direct.duration])[0]
    x_fac = factored_final_state(M3, problem.x0, cmd)
    scale = np.max(np.abs(simulate(M3, problem.x0, direct) - x_sim), axis=0)
    assert np.all(np.abs(x_fac - x_sim) <= 1e-10 * np.maximum(scale, 1e-300) + 1e-14)


def test_a_six_mode_um_zvd_is_checked_by_its_factors_not_piece_by_piece(monkeypatch):
    # 5^6 = 15,625 impulses, ~47,000 pieces: the old check took one expm per piece (this test's
    # counter stops it at 2,000); by factors it takes a few per factor impulse
    m = ModalModel(
        b0=0.5,
        c=0.0,
        omega=(0.9, 2.3, 5.1, 11.0, 23.0, 41.0),
        zeta=(0.02, 0.1, 0.05, 0.2, 0.15, 0.08),
        b=(1.0, -0.7, 0.5, 0.9, -1.2, 0.3),
    )
    calls = [0]
    real_expm = exact_module.expm

    def counted(*args, **kwargs):
        calls[0] += 1
        if calls[0] > 2_000:
            raise AssertionError("over 2,000 matrix exponentials: the command was simulated piece by piece")
        return real_expm(*args, **kwargs)

    monkeypatch.setattr(exact_module, "expm", counted)
    monkeypatch.setattr(shaped_command_module, "expm", counted)
    exact_module._step_cached.cache_clear()
    problem = rest_to_rest(m, 1.0, 2.0)
    profile = plan_shaped(problem, design("um_zvd", m.omega, m.zeta), "um_zvd")
    assert profile.command.levels.size > shaped_command_module.MAX_SIMULATED_PIECES
    assert np.max(np.abs(profile.command.levels)) <= 1.0
    assert profile.final_state_error_relative <= 1e-9
    assert np.max(profile.residual_percent) < 1e-6


@settings(max_examples=60, deadline=None)
@given(
    t=st.lists(st.floats(0.0, 10.0), min_size=1, max_size=40),
    dup=st.lists(st.integers(0, 39), max_size=10),
)
def test_merging_impulses_groups_by_the_definition(t, dup):
    """Each group starts at the first impulse past the previous group's start + tol and sums what it covers.

    Checked against the definition, not against a copy of the loop ``group_impulses`` falls back to.
    """
    from flexmotion_ros.core.shaping.shaper import group_impulses

    t = np.array(t + [t[i % len(t)] + 1e-13 * (k % 3) for k, i in enumerate(dup)])
    t.sort()
    a = np.arange(1.0, t.size + 1.0)
    tol = 1e-12 * max(float(t[-1]), 1e-300)
    gt, ga = group_impulses(t, a, tol)
    assert gt[0] == t[0] and ga.shape == gt.shape
    for j, start in enumerate(gt):
        covered = (t >= start) & (t <= start + tol)
        assert ga[j] == pytest.approx(a[covered].sum(), rel=1e-15)
        later = t[t > start + tol]
        if j + 1 < gt.size:
            assert gt[j + 1] == later[0]  # the next group starts at the first impulse it does not cover
        else:
            assert later.size == 0
    assert ga.sum() == pytest.approx(a.sum(), rel=1e-15)


def test_a_chain_of_near_coincident_impulses_is_split_at_tol_from_each_group_start():
    from flexmotion_ros.core.shaping.shaper import group_impulses

    tol = 1e-12
    t = np.array([0.0, 0.6, 1.2, 1.8, 2.4]) * tol  # every gap <= tol, the chain spans 2.4 tol
    gt, ga = group_impulses(t, np.ones(5), tol)
    assert np.array_equal(gt, t[[0, 2, 4]]) and np.array_equal(ga, [2.0, 2.0, 1.0])
