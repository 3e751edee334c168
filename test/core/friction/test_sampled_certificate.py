"""The discrete-time Pontryagin certificate of sampled friction moves with stick arcs (issue 18).

On main these moves came back ``exact_sampled`` with nothing proved; their pattern's least-peak LP is now
checked by a dual (``exact_sampled_pattern_optimal``), and the check fails when the move is perturbed.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexmotion_ros.core import ModalModel, MoveProblem
from flexmotion_ros.core.friction import plan_time_optimal_friction, simulate_coulomb
from flexmotion_ros.core.friction.certificate import FrictionStatus
from flexmotion_ros.core.friction.sampled_certificate import certify_sampled, pattern_rows
from flexmotion_ros.core.friction.sampled_lp import FrictionLP


def fuzz_1():
    """Seed-18 fuzz case 1 (4 modes, c < 0, F = 0.48 u_max): the body is held (stuck samples) while the modes
    are steered."""
    m = ModalModel(
        b0=1.003176367731772,
        c=-0.2676289595285799,
        omega=(0.6491458111072382, 1.8130612182653145, 21.262943145875255, 42.177984253296174),
        zeta=(0.25018047229182244, 0.29684426386984125, 0.2062001304227801, 0.013590468236303633),
        b=(1.4187124737392933, 1.8335021906310824, 0.32723066781884114, -0.4713028453796907),
    )
    return MoveProblem(m, 3.2089852554055973, [0.0] * m.n_states, -0.17455234139414605), 1.5344075972967939


def fuzz_6():
    """Seed-18 fuzz case 6 (one mode, F = 0.095 u_max): ends on a boundary arc, ``u = F`` while ``v = 0``."""
    m = ModalModel(
        b0=0.22106149135616687, c=0.0, omega=(4.553285923680454,), zeta=(0.16759128498152032,), b=(0.4024661304232754,)
    )
    return MoveProblem(m, 0.15155249369494478, [0.0] * m.n_states, 7.81753921874022e-06), 0.014468674290571545


def pattern_of(prof):
    """``(lp, commands, pattern)`` of a returned sampled move."""
    lp = FrictionLP(prof.problem, prof.coulomb_force, prof.sample_period)
    return lp, np.asarray(prof.levels, float), np.asarray(prof.sample_pattern, float)


@pytest.mark.parametrize("case", [fuzz_1, fuzz_6], ids=["fuzz1_stuck", "fuzz6_boundary_arc"])
def test_stick_arc_moves_carry_the_sampled_pattern_certificate(case):
    """Both came back ``exact_sampled`` (nothing proved) on main; now the discrete-time Pontryagin conditions
    of their pattern are checked: least peak for the pattern, with a proved bound; still exact and bounded."""
    problem, F = case()
    prof = plan_time_optimal_friction(problem, F, 100.0)
    cert = prof.certificate
    assert cert.status is FrictionStatus.SAMPLED_PATTERN
    assert not cert.passed  # not a continuous extremal: `certified` keeps its meaning
    assert "pattern" in cert.claim and "not proved" in cert.claim
    u = np.asarray(prof.levels, float)
    assert np.max(np.abs(u)) <= problem.u_max
    # the independent check: event-located friction simulation with matrix exponentials
    xf = problem.model.rest_state(problem.target)
    x = simulate_coulomb(problem.model, problem.x0, prof.input(), F, [prof.duration, 2.0 * prof.duration + 1.0])
    full = simulate_coulomb(problem.model, problem.x0, prof.input(), F, np.linspace(0.0, prof.duration, 200))
    scale = np.max(np.abs(full - xf), axis=0) + 1e-300
    assert np.max(np.abs(x - xf) / scale) < 1e-8


@pytest.fixture(scope="module")
def fuzz_1_plan():
    problem, F = fuzz_1()
    return plan_time_optimal_friction(problem, F, 100.0)


def _certified_plan(prof):
    lp, u, s = pattern_of(prof)
    assert np.any(s == 0.0)  # a stick arc
    pc = certify_sampled(lp, s, u)
    assert pc.passed, pc.message
    assert pc.peak <= pc.peak_lower_bound * (1.0 + 1e-4)
    return lp, u, s


def test_the_certificate_fails_on_a_perturbed_move(fuzz_1_plan):
    """One command moved by 1e-4 of itself: the move no longer lands (its pattern's arrival rows fail)."""
    lp, u, s = _certified_plan(fuzz_1_plan)
    k = int(np.argmax(np.abs(u) < 0.9 * np.max(np.abs(u))))
    bad = u.copy()
    bad[k] *= 1.0 + 1e-4
    pc = certify_sampled(lp, s, bad)
    assert not pc.passed
    assert "breaks its pattern's rows" in pc.message


def test_the_certificate_fails_on_a_move_that_is_not_least_peak(fuzz_1_plan):
    """A move of the same pattern that lands but with a larger peak (a direction that keeps every equality
    row, pushed into the largest command): the proved bound is below its peak, so it is not certified."""
    lp, u, s = _certified_plan(fuzz_1_plan)
    A_ub, b_ub, A_eq, b_eq, _ = pattern_rows(lp, s)
    E = A_eq.toarray()[:, : u.size]
    _, sv, Vt = np.linalg.svd(E)
    null = Vt[np.sum(sv > 1e-12 * sv[0]) :]  # directions that keep the arrival and the rest rows
    k = int(np.argmax(np.abs(u)))
    d = null.T @ null[:, k]  # the null-space direction closest to e_k
    d *= np.sign(u[k]) * 1e-2 * abs(u[k]) / abs(d[k])
    worse = u + d
    pc = certify_sampled(lp, s, worse)
    assert np.max(np.abs(worse)) > np.max(np.abs(u))
    assert not pc.passed
    assert "not proved least" in pc.message or "breaks" in pc.message


def test_the_bound_is_below_every_feasible_move_of_the_pattern(fuzz_1_plan):
    """The proved bound is a lower bound: the LP's own optimum (found by another HiGHS method) is not below it."""
    from scipy.optimize import linprog

    lp, u, s = _certified_plan(fuzz_1_plan)
    A_ub, b_ub, A_eq, b_eq, _ = pattern_rows(lp, s)
    cost = np.zeros(u.size + 1)
    cost[-1] = 1.0
    res = linprog(cost, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=b_eq, bounds=(None, None), method="highs-ipm")
    assert res.status == 0
    pc = certify_sampled(lp, s, u)
    assert pc.peak_lower_bound <= res.fun * (1.0 + 1e-7)
    assert res.fun <= pc.peak * (1.0 + 1e-4)


@pytest.mark.parametrize("case", [fuzz_1, fuzz_6], ids=["fuzz1_stuck", "fuzz6_boundary_arc"])
def test_the_dual_comes_from_a_sparse_lp_and_proves_the_dense_bound(case, spy):
    """Before: the dual came from the dense rows (``K^2 / 2`` nonzeros of velocity rows; 20-30 ms of a median
    plan at 190 samples).  Now one LP in scaled chain form (bounds for the peak and signs, a few nonzeros per
    sample) gives multipliers that pass the same numpy check on the dense rows, with the dense LP's bound."""
    from flexmotion_ros.core.friction import sampled_certificate as sc

    problem, F = case()
    prof = plan_time_optimal_friction(problem, F, 100.0)
    lp, u, s = pattern_of(prof)
    sizes = spy(
        sc,
        "solve_lp",
        lambda **kw: sum(
            A.nnz if hasattr(A, "nnz") else np.count_nonzero(A) for A in (kw["A_ub"], kw["A_eq"]) if A is not None
        ),
    )
    pc = sc.certify_sampled(lp, s, u)
    assert pc.passed, pc.message
    K, nI = u.size, lp.I.size
    # arrival K nI + nI, chain 4 K, stick rows 4 per stuck sample: O(K), not the dense rows' K^2 / 2
    assert len(sizes) == 1 and sizes[0] <= K * (nI + 8) + nI, sizes
    A_ub, b_ub, A_eq, b_eq, _ = pattern_rows(lp, s)
    status, dense = sc.dense_duals(lp, s, A_ub, b_ub, A_eq, b_eq, nI)
    assert dense is not None
    # the dense LP's own optimum (dual objective) is the least peak: the sparse dual's bound is within 1e-7 of it
    least = -float(np.maximum(dense[0], 0.0) @ b_ub) - float(dense[1] @ b_eq)
    assert abs(pc.peak_lower_bound - least) <= 1e-7 * least
