"""Minimum fuel on the fuzz cases of issue 15 that refused or took seconds: bounded work, exact answers.

Cases are ``bench/fuzz.py`` seed 15 (``--rate 100``); each was a refusal of a
valid model or a tail on the code before this file.  Answers are checked by an
independent matrix-exponential propagation (``scipy.linalg.expm``).
"""

import math

import numpy as np
import pytest
from scipy.linalg import expm

from flexmotion_ros.core import ModalModel
from flexmotion_ros.core.errors import SolverError
from flexmotion_ros.core.fuel import min_fuel as fuel_module
from flexmotion_ros.core.fuel.lp import min_fuel_lp
from flexmotion_ros.core.model.boundary import MoveProblem
from flexmotion_ros.core.simulation.prepared import prepare
from flexmotion_ros.core.time_optimal.solver import plan_time_optimal

# fuzz case 191: a damped rigid body (c = -0.47), a fast damped mode, a 340 s move
CASE_191 = MoveProblem(
    ModalModel(
        b0=3.827857075311419,
        c=-0.47005080689106726,
        omega=(0.9515288359977838, 39.46764504597698),
        zeta=(0.09892532295431575, 0.1159604645695962),
        b=(1.3542651680788085, -1.8998907854323366),
    ),
    0.180775650470088,
    [0.0] * 6,
    409.1455944305457,
)
# fuzz case 39: a moving, vibrating start, a 26 rad/s mode, a 457 s move
CASE_39 = MoveProblem(
    ModalModel(
        b0=0.2989494484569723,
        c=0.0,
        omega=(0.3495416455297388, 0.7527230020885213, 26.266836477552904),
        zeta=(0.19625085252476357, 0.15375431565123043, 0.19560541246894783),
        b=(1.9483881174342992, 1.150907274752632, -1.098634831401376),
    ),
    0.5288718700716437,
    [0.0, -23.523644948605565, 1559.7443224651138, 555.0741570853902, 120.22408968624428]
    + [-102.54663196080284, 0.07012485288892525, 4.599068108673503],
    288.6076110869027,
)


def _final_state_by_expm(problem: MoveProblem, u: np.ndarray, dt: float) -> np.ndarray:
    """State after the samples (forward order), one expm of the augmented matrix."""
    A, B = problem.model.A(), problem.model.B()
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n], M[:n, n] = A, B
    E = expm(M * dt)
    x = np.asarray(problem.x0, float)
    for uk in u:
        x = E[:n, :n] @ x + E[:n, n] * uk
    return x


def test_the_lp_units_see_a_fast_damped_mode():
    """The LP's units come from the move's error scale: HiGHS had entries of 1e22 ("model error").

    Before: the 33 uniform instants of the coarse scale gave the 39 rad/s mode's rate a unit of
    1.8e-24; the LP failed at every sample count and the planner refused after 400 LPs (23 s).
    """
    move = prepare(CASE_191)
    T = 1.2 * plan_time_optimal(move).duration
    K = 1024
    sol = min_fuel_lp(move.response, move.x0, CASE_191.u_max, K, T / K)
    assert sol is not None
    assert np.max(np.abs(sol.u)) <= CASE_191.u_max
    assert sol.fuel >= sol.bound - 1e-9 * sol.fuel  # weak duality
    x = _final_state_by_expm(CASE_191, sol.u[::-1], T / K)  # samples-to-go order reversed
    target = CASE_191.model.rest_state(CASE_191.target)
    assert np.max(np.abs(x - target)[:2]) <= 1e-8 * abs(CASE_191.target)


def test_newton_without_a_bang_off_bang_optimum_stops_early(monkeypatch):
    """No bang-off-bang optimum (the dual's maximum leaves a miss): each Newton start is bounded.

    Before: 1,891 dual evaluations (57 s) before the same refusal; the sampled LP plans the move.
    """
    calls = []
    original = fuel_module.dual_eval

    def counted(*args):
        calls.append(1)
        return original(*args)

    monkeypatch.setattr(fuel_module, "dual_eval", counted)
    move = prepare(CASE_191)
    to = plan_time_optimal(move)
    with pytest.raises(SolverError, match="misses the target") as info:
        fuel_module.plan_min_fuel(move, 1.2 * to.duration, to)
    assert len(calls) <= 2 * (fuel_module.MAX_DUAL_EVALUATIONS + 1)
    # the best dual iterate comes with the refusal (the sampled LP's window guess)
    assert isinstance(info.value, fuel_module.BangOffBangMissed)
    assert info.value.costate.shape == (6,)


def test_the_seed_lp_stays_small(monkeypatch):
    """The LP that seeds Newton's co-state is capped: it asked for 61,000 samples (9 s of HiGHS, twice)."""
    sizes = []
    original = fuel_module.seed_costate

    def recorded(system, x0, um, K, dt):
        sizes.append(K)
        return original(system, x0, um, K, dt)

    monkeypatch.setattr(fuel_module, "seed_costate", recorded)
    move = prepare(CASE_39)
    to = plan_time_optimal(move)
    T = 1.2 * to.duration
    prof = fuel_module.plan_min_fuel(move, T, to)
    assert max(sizes) <= 8192
    assert prof.certified
    assert math.isclose(prof.duration, T)
    # independent check: the bang-off-bang input propagated piece by piece with expm
    A, B = CASE_39.model.A(), CASE_39.model.B()
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n], M[:n, n] = A, B
    x = np.append(np.asarray(CASE_39.x0, float), 0.0)
    breaks = np.concatenate([[0.0], prof.switch_times, [T]])
    peak = np.zeros(n)
    for h, level in zip(np.diff(breaks), prof.levels):
        x[n] = level
        x = expm(M * h) @ x
        peak = np.maximum(peak, np.abs(x[:n] - CASE_39.model.rest_state(CASE_39.target)))
    assert np.all(np.abs(prof.levels) <= CASE_39.u_max)
    err = np.abs(x[:n] - CASE_39.model.rest_state(CASE_39.target))
    assert np.max(err / np.maximum(peak, 1e-300)) <= 1e-7


def test_the_exact_arrival_correction_falls_back_to_every_inner_sample():
    """The LP optimum's fractional samples alone made an ill-conditioned correction (4e-3 missed).

    Fuzz case 363 (a damped rigid body, three modes, a 79 s move at 100 Hz): the least-norm change
    of the few fractional samples left the bound and was clipped away; every sample strictly inside
    the bound now moves when that misses.
    """
    problem = MoveProblem(
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
    move = prepare(problem)
    T = 1.2 * plan_time_optimal(move).duration
    K, dt = math.ceil(T * 100.0), 0.01
    sol = min_fuel_lp(move.response, move.x0, problem.u_max, K, dt)
    assert sol is not None and np.max(np.abs(sol.u)) <= problem.u_max
    x = _final_state_by_expm(problem, sol.u[::-1], dt)
    target = problem.model.rest_state(problem.target)
    assert np.max(np.abs(x - target)[:2]) <= 1e-9 * abs(problem.target)
    assert np.max(np.abs(x - target)[2:]) <= 1e-9
