"""Minimum fuel on long moves: bounded work (issue 15, fuzz seed 15 cases 73, 121, 257 hung).

Case 73 (7 modes, a 853 s move at 100 Hz): 82 dual evaluations took 81.7 s, then one HiGHS
call over all 85,308 samples ran for minutes.  Now: each dual evaluation reuses one grid's
trigonometric basis, the evaluations of one plan are counted against the root grid's size, and
no fuel LP frees more than ``MAX_FREE_SAMPLES`` samples: past it the best feasible sequence is
returned with its proved lower bound.  Answers are checked by an independent matrix-exponential
propagation (``scipy.linalg.expm``).
"""

import math

import numpy as np
from reference_solutions import expm_pieces

from flexmotion_ros.core import ModalModel
from flexmotion_ros.core.config import PlannerConfig
from flexmotion_ros.core.fuel import dual as dual_module
from flexmotion_ros.core.fuel import lp as lp_module
from flexmotion_ros.core.fuel import min_fuel as fuel_module
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.model.boundary import MoveProblem
from flexmotion_ros.core.simulation.prepared import prepare
from flexmotion_ros.core.time_optimal.solver import plan_time_optimal
from flexmotion_ros.core.time_optimal.switching import sample_grid

from .test_min_fuel_bounded import CASE_191

# fuzz case 363: a damped rigid body, three modes, a 79 s move (7,900 samples at 100 Hz)
CASE_363 = MoveProblem(
    ModalModel(
        b0=0.1498373836355894,
        c=-0.8758198996261823,
        omega=(0.4779453975768604, 3.7023039881829414, 6.0633531823690126),
        zeta=(0.0177256669349635, 0.04964871150950839, 0.1329047875898608),
        b=(1.095954844947544, -1.9012153757912378, -0.1632015140998304),
    ),
    0.7421935207680813,
    [0.0] * 8,
    7.922660418721213,
)


def _final_error(problem: MoveProblem, u: np.ndarray, dt: float) -> np.ndarray:
    """Final state minus the target (forward-order samples), by the reference's own expm."""
    return expm_pieces(problem, np.full(len(u), dt), u)[-1] - problem.model.rest_state(problem.target)


def test_dual_evaluations_share_one_grid_basis(monkeypatch):
    """Each evaluation built a fresh grid and recomputed exp, sin, cos at every point (1.6-2.5 s on case 73)."""
    move = prepare(CASE_191)
    T = 1.2 * plan_time_optimal(move).duration
    system = move.response
    points = sample_grid(system, T).size
    big = []
    original = system._mode_trig

    def counted(tau):
        if np.size(tau) >= points // 2:
            big.append(np.size(tau))
        return original(tau)

    monkeypatch.setattr(system, "_mode_trig", counted)
    w = -system.expm_x(T, move.x0)
    nu = np.linspace(0.1, 1.0, move.x0.size)
    first = fuel_module.dual_eval(system, nu, w, T, CASE_191.u_max)
    for k in range(3):
        again = fuel_module.dual_eval(system, nu * (1.0 + 0.1 * k), w, T, CASE_191.u_max)
    assert len(big) <= 1  # the grid's basis once, not per evaluation
    assert np.isfinite(first.value) and np.isfinite(again.value)


def test_dual_evaluations_of_one_plan_are_counted_against_the_grid(monkeypatch):
    """Both Newton starts share one budget (case 191: 2 x 41 evaluations before; case 73: 82, 81.7 s)."""
    move = prepare(CASE_191)
    to = plan_time_optimal(move)
    T = 1.2 * to.duration
    points = sample_grid(move.response, T).size
    monkeypatch.setattr(dual_module, "DUAL_WORK_BUDGET", 20 * points)
    assert dual_module.dual_evaluation_budget(move.response, T) == 20
    calls = []
    original = fuel_module.dual_eval

    def counted(*args):
        calls.append(1)
        return original(*args)

    monkeypatch.setattr(fuel_module, "dual_eval", counted)
    try:
        fuel_module.plan_min_fuel(move, T, to)
    except fuel_module.BangOffBangMissed as exc:
        assert exc.costate.shape == (6,)
    assert len(calls) <= 20


def test_the_fuel_lp_past_its_work_bound_returns_an_exact_sequence_with_a_proved_bound(monkeypatch):
    """No LP frees more than ``max_free`` samples; the answer arrives exactly, within u_max, above its bound."""
    move = prepare(CASE_363)
    T = 1.2 * plan_time_optimal(move).duration
    K, dt = math.ceil(T * 100.0), 0.01
    sizes = []
    original = lp_module.solve_lp

    def recorded(**kw):
        sizes.append(kw["A_eq"].shape[1] // 2)
        return original(**kw)

    monkeypatch.setattr(lp_module, "solve_lp", recorded)
    sol = lp_module.min_fuel_lp(move.response, move.x0, CASE_363.u_max, K, dt, max_free=1000)
    assert K > 7000 and max(sizes) <= 1000
    assert np.max(np.abs(sol.u)) <= CASE_363.u_max
    err = np.abs(_final_error(CASE_363, sol.u[::-1], dt))
    assert np.max(err[:2]) <= 1e-9 * abs(CASE_363.target) and np.max(err[2:]) <= 1e-9
    exact = lp_module.min_fuel_lp(move.response, move.x0, CASE_363.u_max, K, dt, max_free=K)  # the full LP
    assert sol.bound <= exact.fuel * (1.0 + 1e-9)
    assert exact.fuel <= sol.fuel * (1.0 + 1e-7)  # both within the LP solver's accuracy
    assert sol.bound <= sol.fuel


def test_min_fuel_past_the_work_bound_plans_and_says_it_is_not_proved(monkeypatch):
    """The method answers with the best window, exact; ``certified`` only if its gap closed."""
    monkeypatch.setattr(lp_module, "MAX_FREE_SAMPLES", 1000)
    config = PlannerConfig(model=CASE_363.model, u_max=CASE_363.u_max, method="min_fuel", options={})
    result = plan_move(config, CASE_363, 100.0)
    extra = result.sampled.extra
    assert extra["fuel_lower_bound"] <= extra["fuel"]
    closed = extra["fuel"] - extra["fuel_lower_bound"] <= 1e-9 * extra["fuel"]
    assert extra["fuel_gap_closed"] == closed
    if result.info.get("continuous_note"):
        assert result.continuous.certified == closed
    u = result.sampled.commands
    assert np.max(np.abs(u)) <= CASE_363.u_max
    err = np.abs(_final_error(CASE_363, u, result.sampled.dt))
    assert np.max(err[:2]) <= 1e-9 * abs(CASE_363.target) and np.max(err[2:]) <= 1e-9


# fuzz case 577: a damped rigid body moving at the start, a 55 rad/s mode, a 605 s move (60,463 samples)
CASE_577 = MoveProblem(
    ModalModel(
        b0=0.13866879849571917,
        c=-0.7463476176120513,
        omega=(0.4572367048841147, 5.1262480211833, 55.003919473933834),
        zeta=(0.11707610190294038, 0.16150283179729, 0.043676472537085786),
        b=(-1.8565537516934325, 1.0497777831218185, 0.2024843288590551),
    ),
    1.28328982297138,
    [0.0, -91.18759884359766, -1441.9441019067365, -386.9194554734878]
    + [-1.0361470487664985, 37.800604191644055, -0.022941309362976087, -0.8807320562869948],
    -241.1555875353133,
)


def test_a_long_move_past_the_work_bound_plans_from_the_blocked_lp():
    """Case 577: the blocked LP with block-sized costs got no verdict from HiGHS ("Not Set"): refused."""
    move = prepare(CASE_577)
    T = 1.2 * plan_time_optimal(move).duration
    K, dt = math.ceil(T * 100.0 * (1.0 - 1e-12)), 0.01
    assert K > lp_module.MAX_FREE_SAMPLES
    sol = lp_module.min_fuel_lp(move.response, move.x0, CASE_577.u_max, K, dt)
    assert np.max(np.abs(sol.u)) <= CASE_577.u_max
    assert sol.bound <= sol.fuel
    err = np.abs(_final_error(CASE_577, sol.u[::-1], dt))
    scale = max(abs(CASE_577.target), float(np.max(np.abs(CASE_577.x0))))  # 1,442: the start's largest state
    assert np.max(err) <= 1e-9 * scale
