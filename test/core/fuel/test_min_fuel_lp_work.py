"""Every fuel LP runs under a work bound HiGHS honours (issue 15, fuzz seed 15 case 273 hung).

Case 273 (6 modes, ``c = -0.22``, a 1,058 s move): the seed LP of Newton's co-state (8,192
samples) ran past 8 minutes of CPU inside one dual-simplex call, where neither the fuzz's guard
nor a time limit reaches.  Now every fuel LP has an iteration limit (``LP_WORK_BUDGET``); the
seed and the blocked LP fall back to the interior-point method without crossover.  Values are
checked against independent computations: the seed's co-state by weak duality against the
sampled optimum found by another algorithm (the dual simplex with the rows in unit size: 2.8 s),
the sequences by the reference's own ``scipy.linalg.expm`` propagation.
"""

import numpy as np
from reference_solutions import expm_pieces
from scipy.linalg import expm

from flexmotion_ros.core import ModalModel
from flexmotion_ros.core.fuel import lp as lp_module
from flexmotion_ros.core.linear_program import LpMethod, LpStatus
from flexmotion_ros.core.model.boundary import MoveProblem
from flexmotion_ros.core.simulation.prepared import prepare
from flexmotion_ros.core.time_optimal.solver import plan_time_optimal

from .test_min_fuel_work_bound import CASE_577

# fuzz case 273: 6 modes at rest, two near 20 rad/s, T* = 882.08 s
CASE_273 = MoveProblem(
    ModalModel(
        b0=0.8640632829383935,
        c=-0.21798013862565324,
        omega=(0.32656606420449047, 0.831925824801856, 1.6419795723159585)
        + (2.2147462423854005, 19.428481290362082, 20.569781050016463),
        zeta=(0.12215332548205236, 0.005105584699318599, 0.2329912054996376)
        + (0.04431318340544693, 0.010940513416800602, 0.26684249037784086),
        b=(-0.1461849389887065, 1.4274996372535742, -0.9972371101472818)
        + (-0.4451424711980536, 0.1534846628902675, 1.0602120632245517),
    ),
    0.22139197025648485,
    [0.0] * 14,
    -763.6611528226014,
)
#: 1.2 T* (the method's default move time) and its seed LP's samples.
T_273, K_273 = 1.2 * 882.0778653878328, 8192
#: The sampled optimum of that LP (N s): the dual simplex with unit-size rows, arrival made exact.
FUEL_273 = 192.65135695756805


def _recording(monkeypatch) -> list:
    """Every ``solve_lp`` call of the fuel LPs: (method, iteration limit, status)."""
    calls = []
    original = lp_module.solve_lp

    def recorded(**kw):
        res = original(**kw)
        calls.append((kw.get("method", LpMethod.CHOOSE), kw.get("iteration_limit"), res.status))
        return res

    monkeypatch.setattr(lp_module, "solve_lp", recorded)
    return calls


def _weak_duality_bound(problem: MoveProblem, nu: np.ndarray, K: int, dt: float) -> float:
    """``nu^T w - u_max sum_m (|nu^T g_m| - dt)_+`` with ``g_m``, ``w`` by ``expm`` (the test's own)."""
    A, B = problem.model.A(), problem.model.B()
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n], M[:n, n] = A, B
    E = expm(M * dt)
    g = np.empty((K, n))
    g[0] = E[:n, n]
    for m in range(1, K):
        g[m] = E[:n, :n] @ g[m - 1]
    x0 = np.asarray(problem.shifted_initial(), float)
    w = -expm(A * K * dt) @ x0
    return float(nu @ w - problem.u_max * np.sum(np.maximum(np.abs(g @ nu) - dt, 0.0)))


def test_the_seed_lp_of_case_273_ends_within_its_work_bound(monkeypatch):
    """The seed LP hung (over 8 min CPU in one HiGHS call); now bounded, and its co-state near-optimal.

    The work bound is lowered to 1,220 iterations here (the planner's: 12,207) to keep the test short.
    """
    monkeypatch.setattr(lp_module, "LP_WORK_BUDGET", 2e7)
    calls = _recording(monkeypatch)
    move = prepare(CASE_273)
    nu = lp_module.seed_costate(move.response, move.x0, CASE_273.u_max, K_273, T_273 / K_273)
    assert nu is not None
    assert calls and all(limit is not None for _, limit, _ in calls)  # every call under a work bound
    assert calls[0][2] is LpStatus.TIME_LIMIT  # the dual simplex reached it
    assert calls[-1][0] is LpMethod.IPM and calls[-1][2] is LpStatus.OPTIMAL
    bound = _weak_duality_bound(CASE_273, nu, K_273, T_273 / K_273)
    assert bound <= FUEL_273 * (1.0 + 1e-9)  # weak duality against the other algorithm's optimum
    assert bound >= FUEL_273 * (1.0 - 1e-6)  # and a near-optimal co-state


def test_a_blocked_lp_without_a_simplex_verdict_still_gives_an_exact_sequence(monkeypatch):
    """Every dual simplex stopped by its work bound: the blocked LP by the interior method, exact after correction."""
    monkeypatch.setattr(lp_module, "LP_WORK_BUDGET", 1.0)
    monkeypatch.setattr(lp_module, "MIN_LP_ITERATIONS", 3)
    calls = _recording(monkeypatch)
    move = prepare(CASE_577)
    T = 1.2 * plan_time_optimal(move).duration
    K, dt = int(np.ceil(T * 100.0 * (1.0 - 1e-12))), 0.01
    assert K > lp_module.MAX_FREE_SAMPLES
    sol = lp_module.min_fuel_lp(move.response, move.x0, CASE_577.u_max, K, dt)
    assert any(status is LpStatus.TIME_LIMIT for _, _, status in calls)
    assert any(method is LpMethod.IPM and status is LpStatus.OPTIMAL for method, _, status in calls)
    assert not sol.gap_closed
    assert np.max(np.abs(sol.u)) <= CASE_577.u_max
    assert sol.bound <= sol.fuel
    u = sol.u[::-1]  # samples-to-go order reversed
    err = expm_pieces(CASE_577, np.full(K, dt), u)[-1] - CASE_577.model.rest_state(CASE_577.target)
    scale = max(abs(CASE_577.target), float(np.max(np.abs(CASE_577.x0))))
    assert np.max(np.abs(err)) <= 1e-9 * scale
