"""Issue 15's tail: the damped smoothed warm start (``smoothed_dual.inner_smooth(damping=True)``).

Fuzz case 3476 (seed 15; 8 modes, a moving start, ``T*`` = 11.59 s) went
to the full solver on 8f06a64 (286 exact co-state evaluations, ~0.5 s CPU):
the smoothed warm start stopped at 2.3 s.  On its coarse grid the reduced
Hessian of the smoothed problem is singular to rounding (condition 1e17),
Newton's steps were cut to 1e-11 by the line search, the solves stopped far
from their minima, and their ``m`` (upper bounds) closed the bracket on
``T`` far below the optimum.  Damped steps (Levenberg-Marquardt) solve
them; the fast path, run again from that start, answered.  Since ``wip/tail5`` the smoothed problem
orthonormalises its columns on the grid (``ORTHONORMALISE_ABOVE``): the Hessian no longer squares their
condition, the undamped solves reach the minimum too and the fast path answers from the first start.
"""

from __future__ import annotations

import math

import numpy as np
from reference_solutions import bang_bang_final_error

from flexmotion_ros.core import ModalModel
from flexmotion_ros.core.model.boundary import state_to_rest
from flexmotion_ros.core.results import SolverPath
from flexmotion_ros.core.simulation.prepared import prepare
from flexmotion_ros.core.time_optimal import smoothed_dual
from flexmotion_ros.core.time_optimal.reachable_set import Shooting
from flexmotion_ros.core.time_optimal.rigid_body import rigid_time
from flexmotion_ros.core.time_optimal.smoothed_dual import inner_smooth
from flexmotion_ros.core.time_optimal.solver import plan_time_optimal

MODEL_3476 = ModalModel(
    b0=0.4649236864781853,
    c=-0.4414063111140011,
    omega=(0.4695575829062288, 0.4968159060238022, 0.9029913883657643, 1.325346999713442, 6.396734162632054,
           11.395726905851083, 27.02525090764002, 58.76514296041203),
    zeta=(0.08557822377441389, 0.23228319629332717, 0.18228748199354852, 0.18298132688714888,
          0.022987170124490808, 0.07960185242900258, 0.08547229046164963, 0.003761749823054239),
    b=(1.1562903984378083, -1.7292649837552923, -1.3896992094634215, 1.9345874521740238, 1.8715876637416846,
       1.9116922303324788, -1.9656375463105853, 0.768880527645261),
)  # fmt: skip
U_MAX_3476 = 0.10298306799625742
X0_3476 = [0.0, -0.00011411941888659933, -0.0008540796639080543, -0.0006688479319616296, -0.0020030141649088297,
           0.00031615469610274025, -0.000191691537962801, -0.000479516557713995, -0.0001296549607446664,
           0.00018273233131704396, -4.215387795035999e-06, -2.7135608534292056e-05, -4.603943065281167e-06,
           -3.998020719831442e-05, -5.856332316458443e-07, 2.2890152199190736e-05, 4.1338180817410425e-08,
           -2.6260666740519267e-06]  # fmt: skip
TARGET_3476 = -0.0008379225192953929
#: Its certified optimum on 8f06a64 (the full solver), s.
T_3476 = 11.592729280519608


def _problem():
    return state_to_rest(MODEL_3476, U_MAX_3476, np.array(X0_3476), TARGET_3476)


def test_case_3476_is_answered_by_the_fast_path_from_the_damped_start(monkeypatch):
    monkeypatch.setattr(smoothed_dual, "ORTHONORMALISE_ABOVE", math.inf)  # the columns as before wip/tail5
    problem = _problem()
    profile = plan_time_optimal(problem)
    assert profile.certified, profile.certificate.message
    assert profile.extra["solver_path"] is SolverPath.FAST  # the full solver on 8f06a64
    assert profile.extra["fast_path_stage"] == "damped"
    assert profile.iterations == 0  # no exact co-state evaluation: 286 on 8f06a64
    assert abs(profile.duration - T_3476) <= 1e-9 * T_3476
    assert bang_bang_final_error(problem, profile) <= 1e-9  # own expm propagation
    assert np.all(np.abs(profile.levels) <= problem.u_max)


def test_case_3476_is_answered_by_the_fast_path_from_the_first_start():
    """With orthonormal columns the undamped smoothed start is good enough: no damped stage."""
    problem = _problem()
    profile = plan_time_optimal(problem)
    assert profile.certified, profile.certificate.message
    assert profile.extra["solver_path"] is SolverPath.FAST
    assert "fast_path_stage" not in profile.extra
    assert abs(profile.duration - T_3476) <= 1e-9 * T_3476
    assert bang_bang_final_error(problem, profile) <= 1e-9  # own expm propagation


def test_orthonormal_columns_reach_the_minimum_undamped():
    problem = _problem()
    move = prepare(problem)
    T_low = rigid_time(problem.model, problem.u_max, move.x0, problem.include_position)
    T = T_low + 0.5 * math.pi / min(problem.model.omega)
    smoothing = 0.02 / (problem.u_max * T)
    sh = Shooting(move.response, move.x0, problem.u_max, T)
    _, m_plain, _ = inner_smooth(sh, T, None, 0.02, smoothing=smoothing)
    _, m_damped, _ = inner_smooth(sh, T, None, 0.02, smoothing=smoothing, damping=True)
    assert m_plain < 1e-3  # 37.7 without (below): it closed the bracket at 3.6 s
    assert abs(m_plain - m_damped) <= 1e-6 * max(m_plain, m_damped) + 1e-12


def test_damped_steps_reach_the_minimum_the_undamped_ones_stop_short_of(monkeypatch):
    monkeypatch.setattr(smoothed_dual, "ORTHONORMALISE_ABOVE", math.inf)  # the columns as before wip/tail5
    problem = _problem()
    move = prepare(problem)
    T_low = rigid_time(problem.model, problem.u_max, move.x0, problem.include_position)
    T = T_low + 0.5 * math.pi / min(problem.model.omega)  # the planner's first guess
    level = 0.02
    smoothing = level / (problem.u_max * T)
    sh = Shooting(move.response, move.x0, problem.u_max, T)
    _, m_plain, _ = inner_smooth(sh, T, None, level, smoothing=smoothing)
    _, m_damped, _ = inner_smooth(sh, T, None, level, smoothing=smoothing, damping=True)
    # the same convex problem: the damped solve ends lower (the undamped m = 37.7 closed the bracket at 3.6 s)
    assert m_plain > 1.0
    assert m_damped < 1e-3 * m_plain
