"""Sensitivity curves and insensitivity widths against exact simulation and closed forms."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flexmotion_ros.core import (
    ModalModel,
    PiecewiseConstant,
    plan_time_optimal,
    rest_to_rest,
    simulate,
)
from flexmotion_ros.core.shaping.numerical_shapers import impulse_vibration
from flexmotion_ros.core.shaping.sensitivity import (
    command_curve,
    command_damping_curve,
    command_insensitivity,
    command_vibration,
    insensitivity,
    residual_amplitudes,
    shaper_curve,
    shaper_damping_curve,
    shaper_insensitivity,
    worst_in_band,
)
from flexmotion_ros.core.shaping.shaped_profile import shape
from flexmotion_ros.core.shaping.shapers import Shaper, design
from flexmotion_ros.core.simulation.exact import modal_amplitudes
from flexmotion_ros.core.time_optimal.robust import plan_robust_time_optimal

WB = ModalModel(b0=0.5, c=0.0, omega=[np.sqrt(2.0)], zeta=[0.0], b=[1.0])


def simulated_command_vibration(u, w, z, u_ref, b=1.3):
    """Residual amplitude after ``u`` by exact simulation, over what a step of ``u_ref`` leaves."""
    m = ModalModel(b0=1.0, omega=[w], zeta=[z], b=[b])
    x = simulate(m, m.rest_state(), u, times=[u.duration])[0]
    return modal_amplitudes(m, x)[0] / (abs(b) * u_ref / (w * w * math.sqrt(1 - z * z)))


@settings(max_examples=40, deadline=None)
@given(
    levels=st.lists(st.floats(-2.0, 2.0), min_size=1, max_size=6),
    lengths=st.lists(st.floats(0.05, 3.0), min_size=6, max_size=6),
    w=st.floats(0.3, 8.0),
    z=st.floats(0.0, 0.5),
)
def test_command_vibration_formula_equals_simulation(levels, lengths, w, z):
    breaks = np.concatenate([[0.0], np.cumsum(lengths[: len(levels)])])
    u = PiecewiseConstant(breaks, np.array(levels))
    if u.max_abs() < 1e-3:
        return
    assert command_vibration(u, w, z, 1.0) == pytest.approx(simulated_command_vibration(u, w, z, 1.0), abs=1e-11)


@settings(max_examples=30, deadline=None)
@given(
    amps=st.lists(st.floats(-1.5, 1.5), min_size=2, max_size=5),
    gaps=st.lists(st.floats(0.05, 2.0), min_size=4, max_size=4),
    w=st.floats(0.3, 8.0),
    z=st.floats(0.0, 0.4),
)
def test_shaper_vibration_is_the_ratio_of_shaped_to_unshaped_residual(amps, gaps, w, z):
    """V of any impulse sequence (negative too) = shaped command's residual / unshaped command's."""
    a = np.array(amps)
    t = np.concatenate([[0.0], np.cumsum(gaps[: a.size - 1])])
    s = Shaper("test", t, a, (w,), (z,))
    u = PiecewiseConstant(np.array([0.0, 0.7, 1.9]), np.array([1.0, -0.4]))
    unshaped = simulated_command_vibration(u, w, z, 1.0)
    # Singhose's V refers to an impulse at t_n: the unshaped command delayed by t_n, observed at the same time
    shaped = simulated_command_vibration(shape(u, s), w, z, 1.0)
    assert shaped == pytest.approx(float(s.vibration(w, z)) * unshaped, abs=1e-11)


def test_zv_insensitivity_closed_form_and_grid_independence():
    zv = design("zv", 3.0, 0.0)
    for tol in (0.05, 0.1, 0.2):
        ins = shaper_insensitivity(zv, tol)
        assert ins.width == pytest.approx(4 / math.pi * math.asin(tol), abs=1e-10)
        assert 1.0 - ins.low == pytest.approx(ins.high - 1.0, abs=1e-10)  # undamped: symmetric
    coarse = insensitivity(lambda r: zv.vibration(3.0 * r, 0.0), 0.05, step=1e-2)
    assert coarse.width == pytest.approx(4 / math.pi * math.asin(0.05), abs=1e-10)


def test_ei_hump_touching_the_tolerance_does_not_end_the_interval():
    ei = design("ei", 1.0, 0.0, tolerance=0.05)
    assert float(ei.vibration(1.0, 0.0)) == pytest.approx(0.05, abs=1e-15)
    assert shaper_insensitivity(ei, 0.05).width > 0.39
    assert shaper_insensitivity(ei, 0.049).width == 0.0  # the design point itself is above 4.9 %


def test_curves_versus_ratio_and_damping():
    zvd = design("zvd", 2.0, 0.0)
    r = np.array([0.8, 1.0, 1.25])
    assert shaper_curve(zvd, r) == pytest.approx(100 * np.cos(np.pi * r / 2) ** 2, abs=1e-12)
    # damping error: ZVD designed for zeta = 0 on a damped mode, compared with simulation
    zetas = np.array([0.0, 0.05, 0.2])
    curve = shaper_damping_curve(zvd, zetas)
    assert curve[0] == pytest.approx(0.0, abs=1e-12) and np.all(np.diff(curve) > 0)
    u = PiecewiseConstant(np.array([0.0, 0.9]), np.array([1.0]))
    for z, c in zip(zetas, curve):
        expect = (
            100 * simulated_command_vibration(shape(u, zvd), 2.0, z, 1.0) / simulated_command_vibration(u, 2.0, z, 1.0)
        )
        assert c == pytest.approx(expect, rel=1e-9, abs=1e-10)
    d = command_damping_curve(shape(u, zvd), ModalModel(b0=1, omega=[2.0], zeta=[0.0], b=[1.0]), zetas)
    assert d[0] == pytest.approx(0.0, abs=1e-12)


def test_time_optimal_and_robust_profiles():
    """Time-optimal profiles: zero residual at the nominal model, growing off it; the robust one is flatter."""
    pb = rest_to_rest(WB, 1.0, 1.0)
    to = plan_time_optimal(pb).input()
    rto = plan_robust_time_optimal(pb, 1).input()
    for u in (to, rto):
        assert np.max(residual_amplitudes(WB, pb.x0, u)) < 1e-12
        assert command_curve(u, WB, [1.0], 1.0)[0, 0] < 1e-10
    h = 1e-3  # first-order robustness: the residual is O(h^2) instead of O(h)
    v_to = command_vibration(to, WB.omega[0] * (1 + h), 0.0, 1.0)
    v_rto = command_vibration(rto, WB.omega[0] * (1 + h), 0.0, 1.0)
    assert v_rto < 1e-2 * v_to
    assert command_insensitivity(rto, WB, 0.05, 1.0).width > 5 * command_insensitivity(to, WB, 0.05, 1.0).width
    assert worst_in_band(rto, WB, 0.1, 1.0) < worst_in_band(to, WB, 0.1, 1.0)
    # the band's worst agrees with simulation of the perturbed model at the band's ends
    for r in (0.9, 1.1):
        m = WB.with_changes(omega=(WB.omega[0] * r,))
        amp = residual_amplitudes(m, pb.x0, rto)[0] / (1.0 / m.omega[0] ** 2)
        assert command_curve(rto, WB, [r], 1.0)[0, 0] / 100 == pytest.approx(amp, rel=1e-9)


def test_impulse_vibration_broadcasts():
    V = impulse_vibration([0.0, 1.0], [0.5, 0.5], np.array([[1.0], [2.0]]), np.array([0.0, 0.1]))
    assert V.shape == (2, 2)
