"""Builders: two-mass vs the analytic formulas; crane and chain vs an independent
simulation of the PHYSICAL equations (M x'' + D x' + K x = F u, built here)."""

import math

import numpy as np
import pytest
from scipy.linalg import expm

from flexmotion_ros.core import (
    ModelError,
    PiecewiseConstant,
    chain,
    crane,
    simulate,
    two_mass,
)

# an input with several levels and uneven intervals, to excite everything
U = PiecewiseConstant(np.array([0.0, 0.37, 1.1, 1.9, 3.05, 4.0]), np.array([1.0, -0.6, 0.25, -1.0, 0.8]))
TIMES = np.linspace(0.0, 7.0, 57)  # past the end of the input: free vibration too


def line_matrices(masses, springs, dampers):
    """Mass, damping and stiffness matrices of masses in a line joined by springs/dampers."""
    n = len(masses)
    M = np.diag(np.asarray(masses, float))
    K = np.zeros((n, n))
    D = np.zeros((n, n))
    for i in range(n - 1):
        for mat, val in ((K, springs[i]), (D, dampers[i])):
            mat[i : i + 2, i : i + 2] += val * np.array([[1.0, -1.0], [-1.0, 1.0]])
    return M, D, K


def physical_trajectory(M, D, K, force_on, u, times):
    """Positions and velocities of M x'' + D x' + K x = e_force_on u(t), from rest, by expm."""
    n = M.shape[0]
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ D]])
    B = np.concatenate([np.zeros(n), Minv[:, force_on]])
    aug = np.zeros((2 * n + 1, 2 * n + 1))
    aug[: 2 * n, : 2 * n] = A
    aug[: 2 * n, 2 * n] = B

    def step(x, h, level):
        E = expm(aug * h)
        return E[: 2 * n, : 2 * n] @ x + E[: 2 * n, 2 * n] * level

    at_breaks = [np.zeros(2 * n)]
    for a, b, level in zip(u.breaks[:-1], u.breaks[1:], u.levels):
        at_breaks.append(step(at_breaks[-1], b - a, level))
    out = []
    for t in times:
        k = min(int(np.searchsorted(u.breaks, t, side="right")) - 1, u.levels.size)
        level = u.levels[k] if k < u.levels.size else 0.0
        out.append(step(at_breaks[k], t - u.breaks[k], level))
    out = np.array(out)
    return out[:, :n], out[:, n:]


def modal_trajectory(built, u, times):
    """Positions and velocities from the modal model, mapped back to physical coordinates."""
    X = simulate(built.model, built.model.rest_state(), u, times=times)
    pos = built.physical_positions(X)
    vel = np.concatenate([X[:, 1:2], X[:, 3::2]], axis=1) @ built.modal_to_physical.T
    return pos, vel


def assert_same_motion(built, M, D, K, force_on, rtol=1e-9):
    pos_ref, vel_ref = physical_trajectory(M, D, K, force_on, U, TIMES)
    pos, vel = modal_trajectory(built, U, TIMES)
    np.testing.assert_allclose(pos, pos_ref, rtol=0, atol=rtol * np.max(np.abs(pos_ref)))
    np.testing.assert_allclose(vel, vel_ref, rtol=0, atol=rtol * np.max(np.abs(vel_ref)))


# ------------------------------------------------------------- two-mass
@pytest.mark.parametrize("m1, m2, k, d", [(1.0, 1.0, 1.0, 0.0), (2.0, 0.5, 30.0, 0.4), (0.1, 7.0, 3.0, 0.05)])
def test_two_mass_analytic(m1, m2, k, d):
    built = two_mass(m1, m2, k, d)
    m = built.model
    w = math.sqrt(k * (1 / m1 + 1 / m2))
    assert m.n_modes == 1
    assert m.b0 == pytest.approx(1 / (m1 + m2), rel=1e-14)
    assert m.c == 0.0
    assert m.omega[0] == pytest.approx(w, rel=1e-12)
    # the mode coordinate is the spring deflection x1 - x2: q'' = -w^2 q - d (1/m1 + 1/m2) q' + f/m1
    assert m.b[0] == pytest.approx(1 / m1, rel=1e-12)
    assert m.zeta[0] == pytest.approx(d * (1 / m1 + 1 / m2) / (2 * w), rel=1e-12, abs=1e-15)
    # x1 = p + m2/(m1+m2) q, x2 = p - m1/(m1+m2) q (p: centre of mass)
    np.testing.assert_allclose(
        built.modal_to_physical,
        [[1.0, m2 / (m1 + m2)], [1.0, -m1 / (m1 + m2)]],
        rtol=1e-12,
        atol=1e-14,
    )
    assert built.kind == "two_mass"
    assert built.parameters == {"m1": m1, "m2": m2, "k": k, "d": d}


@pytest.mark.parametrize("d", [0.0, 0.3])
def test_two_mass_vs_physical_simulation(d):
    built = two_mass(2.0, 0.5, 30.0, d)
    M, D, K = line_matrices([2.0, 0.5], [30.0], [d])
    assert_same_motion(built, M, D, K, 0)


# ---------------------------------------------------------------- crane
@pytest.mark.parametrize(
    "cart, payload, L, g, zeta",
    [
        (20.0, 5.0, 2.0, 9.81, 0.0),
        (3.0, 12.0, 0.7, 9.81, 0.05),
        (1.0, 1.0, 1.0, 1.62, 0.0),
    ],
)
def test_crane_vs_physical_pendulum(cart, payload, L, g, zeta):
    """Linearised cart-pendulum: M xc'' = f + m g s / L, m xp'' = -m g s / L with s = xp - xc.

    That is a two-mass chain with a spring m g / L; swing damping ``zeta`` is a damper
    between the two with ``d (1/M + 1/m) = 2 zeta omega``.
    """
    built = crane(cart, payload, L, g, zeta)
    w = math.sqrt(g * (cart + payload) / (cart * L))
    m = built.model
    assert m.omega[0] == pytest.approx(w, rel=1e-14)
    assert m.b0 == pytest.approx(1 / (cart + payload), rel=1e-14)
    assert m.b[0] == pytest.approx(-1 / cart, rel=1e-14)  # s'' = ... - f / M
    assert m.zeta[0] == zeta
    assert built.coordinates == ("cart", "payload")
    k = payload * g / L
    d = 2 * zeta * w / (1 / cart + 1 / payload)
    M, D, K = line_matrices([cart, payload], [k], [d])
    assert_same_motion(built, M, D, K, 0)


# ---------------------------------------------------------------- chain
CHAINS = [
    ([1.0, 1.0, 1.0], [10.0, 10.0], None, 0),
    ([0.5, 0.5, 0.5, 0.5], [400.0, 400.0, 400.0], None, 0),
    ([2.0, 0.3, 1.1, 0.7, 1.5], [5.0, 30.0, 12.0, 8.0], None, 2),
    ([1.0, 2.0, 0.5], [3.0, 7.0], None, 2),
    ([1.0, 3.0, 0.5, 2.0], [40.0, 12.0, 25.0], "proportional", 1),
]


@pytest.mark.parametrize("masses, springs, damping, force_on", CHAINS)
def test_chain_vs_physical_simulation(masses, springs, damping, force_on):
    # stiffness-proportional damping (d_i = alpha k_i) is exactly modal: D = alpha K
    dampers = [0.004 * k for k in springs] if damping == "proportional" else None
    built = chain(masses, springs, dampers, force_on)
    n = len(masses)
    assert built.model.n_modes == n - 1
    assert built.coordinates == tuple(f"x{i + 1}" for i in range(n))
    assert built.modal_to_physical.shape == (n, n)
    M, D, K = line_matrices(masses, springs, dampers or [0.0] * (n - 1))
    assert_same_motion(built, M, D, K, force_on)
    # frequencies are the generalized eigenvalues of (K, M)
    lam = np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real)[1:]
    np.testing.assert_allclose(built.model.omega, np.sqrt(lam), rtol=1e-10)
    # the rigid coordinate is the centre of mass: b0 = 1 / total mass
    assert built.model.b0 == pytest.approx(1 / sum(masses), rel=1e-13)
    if damping == "proportional":
        assert built.notes["damping_coupling"] < 1e-10
        np.testing.assert_allclose(built.model.zeta, 0.5 * 0.004 * np.asarray(built.model.omega), rtol=1e-10)


def test_chain_mode_coordinate_is_the_largest_spring_deflection():
    built = chain([2.0, 0.3, 1.1, 0.7], [5.0, 30.0, 12.0], force_on=1)
    T = built.modal_to_physical
    for i in range(1, T.shape[1]):
        shape = T[:, i]  # physical displacement per unit q_i
        defl = shape[:-1] - shape[1:]
        j = int(np.argmax(np.abs(defl)))
        assert defl[j] == pytest.approx(1.0, rel=1e-12)


def test_chain_nonproportional_damping_reports_coupling():
    built = chain([1.0, 1.0, 1.0], [10.0, 10.0], [1.0, 0.0])
    assert built.notes["damping_coupling"] > 0.01
    assert all(0.0 < z < 1.0 for z in built.model.zeta)


def test_chain_matches_flexible_beam_example():
    built = chain([0.5] * 4, [400.0] * 3, [0.4] * 3)
    m = built.model
    np.testing.assert_allclose(m.omega, [21.647844005847876, 40.0, 52.262518595055056], rtol=1e-12)
    np.testing.assert_allclose(np.abs(m.b), [0.7071067811865475, 1.0, 0.7071067811865475], rtol=1e-12)


@pytest.mark.parametrize(
    "call, parameter",
    [
        (lambda: chain([1.0], []), "masses"),
        (lambda: chain([1.0, -1.0], [1.0]), "masses[1]"),
        (lambda: chain([1.0, 1.0], [0.0]), "springs[0]"),
        (lambda: chain([1.0, 1.0, 1.0], [1.0]), "springs"),
        (lambda: chain([1.0, 1.0], [1.0], [-0.1]), "dampers[0]"),
        (lambda: chain([1.0, 1.0], [1.0], [math.nan]), "dampers[0]"),
        (lambda: chain([1.0, 1.0], [1.0], force_on=2), "force_on"),
        (lambda: chain([1.0, 1.0], [1.0], [100.0]), "dampers"),
        (lambda: two_mass(1.0, math.inf, 1.0), "masses[1]"),
        (lambda: crane(1.0, 1.0, 0.0), "cable_length"),
        (lambda: crane(0.0, 1.0, 1.0), "cart_mass"),
        (lambda: crane(1.0, 1.0, 1.0, zeta=1.0), "model.zeta[0]"),
    ],
)
def test_builders_refuse_bad_parameters(call, parameter):
    with pytest.raises(ModelError) as exc:
        call()
    assert exc.value.parameter == parameter
