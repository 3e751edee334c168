"""The Wie-Bernstein benchmark against its published optimum and an independent solve."""

import numpy as np
import pytest
from scipy.optimize import fsolve

from flexmotion_ros.core import (
    ModalModel,
    PiecewiseConstant,
    final_state,
    plan_time_optimal,
    rest_to_rest,
    two_mass,
)
from flexmotion_ros.core.time_optimal import solver as time_optimal
from flexmotion_ros.core.time_optimal.switching import isolate_roots

WB = ModalModel(b0=0.5, c=0.0, omega=[np.sqrt(2.0)], zeta=[0.0], b=[1.0])


def independent_wb(gamma: float, T0: float, d0: float) -> tuple[float, np.ndarray]:
    """Antisymmetric 3-switch profile solved by fsolve on the expm simulation.

    Switches ``T/2 - d, T/2, T/2 + d``: two unknowns, two conditions (position
    and mode deflection; antisymmetry zeroes both velocities).
    """

    def residual(z):
        T, d = z
        u = PiecewiseConstant.from_switches([T / 2 - d, T / 2, T / 2 + d], [1, -1, 1, -1], T)
        x = final_state(WB, WB.rest_state(), u)
        return [x[0] - gamma, x[2]]

    (T, d) = fsolve(residual, [T0, d0], xtol=1e-13)
    assert np.max(np.abs(residual([T, d]))) < 1e-12
    return T, np.array([T / 2 - d, T / 2, T / 2 + d])


def test_published_optimum():
    p = plan_time_optimal(rest_to_rest(WB, 1.0, 1.0))
    # Wie & Bernstein (1992) / Liu & Wie: t_f = 4.2179 s, switches 1.0026, 2.1089, 3.2152
    assert p.duration == pytest.approx(4.2179, abs=5e-5)
    assert p.switch_times == pytest.approx([1.0026, 2.1089, 3.2152], abs=2e-4)
    assert list(p.levels) == [1.0, -1.0, 1.0, -1.0]
    assert p.certified, p.certificate.message
    assert p.final_state_error < 1e-12


def test_matches_independent_computation_to_the_microsecond():
    p = plan_time_optimal(rest_to_rest(WB, 1.0, 1.0))
    T, sw = independent_wb(1.0, 4.2, 1.1)
    assert abs(p.duration - T) < 1e-9
    assert np.max(np.abs(p.switch_times - sw)) < 1e-9


def test_two_mass_builder_gives_the_benchmark():
    m = two_mass(1.0, 1.0, 1.0).model
    assert m.b0 == pytest.approx(0.5)
    assert m.omega[0] == pytest.approx(np.sqrt(2.0))
    assert abs(m.b[0]) == pytest.approx(1.0)


@pytest.mark.parametrize("gamma", [250.0])
def test_long_move_finds_a_close_cluster_of_switches(gamma):
    """Long moves: the optimum is almost rigid bang-bang with a short blip at mid-move."""
    p = plan_time_optimal(rest_to_rest(WB, 1.0, gamma))
    T, sw = independent_wb(gamma, 44.7224, 0.1)
    assert p.certified, p.certificate.message
    assert abs(p.duration - T) < 1e-9
    assert np.max(np.abs(p.switch_times - sw)) < 1e-8


@pytest.mark.parametrize("fast_path", [True, False], ids=["fast-path", "full-solver"])
def test_switch_at_mid_move_on_a_bisection_point_is_certified(fast_path, monkeypatch):
    """Regression: the full solver's optimum failed its certificate ("1 sign change(s) that are not switches").

    The middle switch sits at ``T/2``, a simple zero of ``S`` (``|S'| = 5e-4``,
    not a tangency: ``S'' = 0`` there only by antisymmetry).  The certificate
    drops the grid point at ``T/2`` (too close to a switch), bisects the cell
    exactly there, and ``S(T/2)`` rounded to exactly 0: a zero sign at a cell
    end hid the sign change from both halves, so the switch looked like one
    where ``S`` does not change sign.  Now such a midpoint is moved off the zero.
    """
    monkeypatch.setattr(time_optimal, "FAST_PATH", fast_path)
    p = plan_time_optimal(rest_to_rest(WB, 1.0, 32.09624297057221))
    assert p.extra["solver_path"] == ("fast" if fast_path else "full")
    assert p.certified and p.certificate.message == "ok", p.certificate.message
    T, sw = independent_wb(32.09624297057221, 16.1, 0.57)
    assert abs(p.duration - T) <= 1e-9 * T
    assert np.max(np.abs(p.switch_times - sw)) <= 1e-9 * T
    assert p.duration == pytest.approx(16.10523197474254, rel=1e-12)


class _CubicSwitching:
    """``S(tau) = x + k x^3`` with ``x = tau - 1/2``: one simple zero at 1/2 (``S' >= 1``)."""

    k = 10.0

    def switching(self, nu, tau, derivative=False, order=None):
        x = np.asarray(tau, float) - 0.5
        d = [x + self.k * x**3, 1.0 + 3.0 * self.k * x**2, 6.0 * self.k * x, np.full_like(x, 6.0 * self.k)]
        d += [np.zeros_like(x)] * max(0, (order or 1) - 3)
        return tuple(d[: (order or 1) + 1]) if derivative or order else d[0]

    def switching_magnitude(self, nu, T):
        return 0.5 + self.k / 8.0, 1.0 + 0.75 * self.k

    def switching_derivative_bound(self, nu, order):
        return 6.0 * self.k if order == 3 else (0.0 if order > 3 else np.inf)


def test_root_isolation_finds_a_zero_on_a_bisection_midpoint():
    """The cell [0, 1] is not provably monotone, so it is halved exactly on the zero."""
    iso = isolate_roots(_CubicSwitching(), np.zeros(1), 1.0, np.array([0.0, 1.0]))
    assert iso.unproved == 0
    assert iso.roots.size == 1 and abs(iso.roots[0] - 0.5) <= 1e-15
    assert iso.sign0 == -1.0
