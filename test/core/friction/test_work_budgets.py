"""The friction planner's budgets are work, not wall time (issue 18): its answer does not depend on the load.

The budgets that stop a search (the zero-order-hold search's, each friction LP's, the sampled certificate's
LP's) are counts: LPs solved, simplex iterations.  A planner slowed down (here: a clock that jumps 1,000 s at
every reading) gives the same answer to the last bit; every friction LP is given an iteration limit and no
time limit.
"""

from __future__ import annotations

import types

import numpy as np
import pytest

from flexmotion_ros.core import ModalModel, MoveProblem
from flexmotion_ros.core.friction import plan_time_optimal_friction, sampled_certificate, sampled_lp
from flexmotion_ros.core.friction import zoh as zoh_mod
from flexmotion_ros.core.friction.zoh import plan_time_optimal_friction_zoh
from flexmotion_ros.core.linear_program import LpMethod, LpStatus, solve_lp

from .test_sampled_certificate import fuzz_1


def fuzz_67():
    """Seed-18 fuzz case 67 (one mode, c < 0): a certified extremal whose sampled move needs windowed LPs."""
    m = ModalModel(
        b0=1.7833363541254401,
        c=-0.7784554639529992,
        omega=(1.3410556525515076,),
        zeta=(0.04373624532853857,),
        b=(1.1502574252746183,),
    )
    u_max = 0.40496234856323615
    return MoveProblem(m, u_max, [0.0] * m.n_states, 4.721991935241248), 0.12455884882821287 * u_max


def _slow_clock():
    """A ``perf_counter`` that jumps 1,000 s at every reading (a planner starved of CPU by the load)."""
    now = [0.0]

    def tick() -> float:
        now[0] += 1000.0
        return now[0]

    return tick


@pytest.mark.parametrize("case", [fuzz_67, fuzz_1])
def test_a_slowed_planner_gives_the_same_sampled_move(monkeypatch, case):
    problem, F = case()
    continuous = plan_time_optimal_friction(problem, F, 100.0)
    ref = plan_time_optimal_friction_zoh(problem, F, 100.0, continuous)
    monkeypatch.setattr(zoh_mod, "time", types.SimpleNamespace(perf_counter=_slow_clock()))
    slow = plan_time_optimal_friction_zoh(problem, F, 100.0, continuous)
    assert slow.samples == ref.samples
    assert np.array_equal(slow.commands, ref.commands)


def test_every_friction_lp_has_a_work_budget_and_no_time_limit(monkeypatch):
    calls: list[dict] = []

    def spy(**kwargs):
        calls.append(kwargs)
        return solve_lp(**kwargs)

    for module in (sampled_lp, sampled_certificate):
        monkeypatch.setattr(module, "solve_lp", spy)
    for case in (fuzz_67, fuzz_1):
        problem, F = case()
        plan_time_optimal_friction_zoh(problem, F, 100.0)
    assert len(calls) > 10
    assert all(c.get("time_limit_s") is None for c in calls)
    assert all(isinstance(c.get("iteration_limit"), int) and c["iteration_limit"] >= 1000 for c in calls)


def test_an_lp_past_its_iteration_limit_is_not_a_verdict():
    """``iteration_limit`` stops HiGHS (``TIME_LIMIT``: nothing proved); without it the same LP is optimal."""
    rng = np.random.default_rng(3)
    n, m = 40, 30
    A = rng.normal(size=(m, n))
    b = A @ rng.uniform(0.1, 1.0, n)
    c = rng.uniform(0.5, 1.5, n)
    kw = dict(cost=c, A_eq=A, b_eq=b, method=LpMethod.DUAL_SIMPLEX, presolve=False)
    full = solve_lp(**kw)
    assert full.status is LpStatus.OPTIMAL
    assert solve_lp(**kw, iteration_limit=1).status is LpStatus.TIME_LIMIT
    again = solve_lp(**kw, iteration_limit=10_000)  # the option is reset, not left at 1
    assert again.status is LpStatus.OPTIMAL and again.objective == pytest.approx(full.objective, rel=1e-12)
    assert solve_lp(**kw).status is LpStatus.OPTIMAL
