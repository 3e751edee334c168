"""The continuation skipped where its first step says the frictionless structure ends early (issue 18).

A first Newton solve at the full force ``F`` whose step has no valid trial point (steps 1, 1/2 and 1/4 of
it all put switches out of order) ends the continuation: to first order in ``F`` the structure changes
before ``F / 4``.  A first solve that fails otherwise still halves the force (seed-18 fuzz case 91 reaches
``F`` through ``F / 2``).
"""

from __future__ import annotations

import numpy as np

from flexmotion_ros.core import ModalModel, MoveProblem
from flexmotion_ros.core.friction import continuation, plan_time_optimal_friction
from flexmotion_ros.core.friction.contact import simulate_coulomb
from flexmotion_ros.core.friction.continuation import continue_in_friction
from flexmotion_ros.core.friction.time_optimal import frictionless_scales
from flexmotion_ros.core.time_optimal.solver import plan_time_optimal


def fuzz_121() -> tuple[MoveProblem, float]:
    """Seed-18 fuzz case 121: one mode; a 0.73 N friction of 1.63 N ends the frictionless structure early."""
    m = ModalModel(b0=0.17135064541034994, c=0.0, omega=(22.81455269225928,), zeta=(0.18179159878757656,),
                   b=(1.7935677482751857,))  # fmt: skip
    return MoveProblem(m, 1.6296826945114566, [0.0] * m.n_states, 0.02057722232542427), 0.7285077450354095


def fuzz_91() -> tuple[MoveProblem, float]:
    """Seed-18 fuzz case 91: two modes; the first solve at F fails, F / 2 and F converge."""
    m = ModalModel(b0=0.1624385351501347, c=0.0, omega=(2.6775175325948934, 31.339179580365897),
                   zeta=(0.26172554781448876, 0.22173607794199518), b=(1.0036100418740708, -1.1396792058990308))  # fmt: skip
    return MoveProblem(m, 0.3372766423691558, [0.0] * m.n_states, -1.3695952924153657e-05), 0.051444966175545455


def _solves(spy, problem: MoveProblem, F: float):
    base = plan_time_optimal(problem)
    scale, _ = frictionless_scales(problem, base)
    calls = spy(continuation, "newton_solve", lambda *args, **kwargs: float(args[2]))  # the force of each solve
    return continue_in_friction(problem, base, F, scale), calls


def test_first_step_without_a_valid_trial_ends_the_continuation(spy):
    problem, F = fuzz_121()
    out, forces = _solves(spy, problem, F)
    assert out is None
    assert forces == [F]  # was [F, F / 2]: the half step failed too, 2-6 ms of exact runs per such case


def test_a_first_solve_that_fails_otherwise_still_halves_the_force(spy):
    problem, F = fuzz_91()
    out, forces = _solves(spy, problem, F)
    assert out is not None
    assert forces[:2] == [F, F / 2] and forces[-1] == F


def test_the_plan_after_a_skipped_continuation_rests_at_the_target():
    problem, F = fuzz_121()
    prof = plan_time_optimal_friction(problem, F, 100.0)
    assert np.all(np.abs(prof.levels) <= problem.u_max)
    assert prof.duration >= prof.lower_bound * (1.0 - 1e-9)
    # replayed by the matrix-exponential friction simulator (not the planner's closed forms), then held at rest
    end = simulate_coulomb(problem.model, problem.x0, prof.input(), F, [prof.duration, 2.0 * prof.duration])
    target = problem.model.rest_state(problem.target)
    assert np.allclose(end, [target, target], rtol=0.0, atol=1e-6 * max(abs(problem.target), 1e-300))
