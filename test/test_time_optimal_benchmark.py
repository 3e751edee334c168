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
