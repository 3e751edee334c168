"""Certified minimum-time multi-input moves, against independent computations.

* ``m = k = 1`` equals the existing single-input solver;
* a decoupled gantry's ``T*`` equals the larger of the two single-axis certified
  optima of the existing solver (to 1e-9), whatever ``sync``;
* coupled two-input chains: certified, exact final state by our own expm, and
  ``T*`` bracketed by an independent LP co-state's weak-duality bound;
* repeated frequencies with two inputs; moves from a moving, vibrating state to
  rest with free final positions.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexmotion_ros.core import ModalModel, plan_time_optimal, rest_to_rest, state_to_rest
from flexmotion_ros.core.errors import ConfigError
from flexmotion_ros.core.multi_input import (
    MultiModel,
    multi_rest_to_rest,
    multi_state_to_rest,
    plan_multi_time_optimal,
)
from flexmotion_ros.core.multi_input.builders import gantry, multi_chain

from . import independent as ind

WIE = ModalModel(b0=0.5, omega=[2**0.5], zeta=[0.0], b=[1.0])
BEAM = ModalModel(b0=0.25, c=-0.05, omega=[1.3, 4.1], zeta=[0.02, 0.01], b=[0.7, -0.3])


def check_exact_and_bounded(problem, prof):
    u = prof.input()
    xT = ind.final_state(problem, u.breaks, u.levels)
    assert ind.relative_error(problem, xT, prof.duration, problem.u_max) < 1e-9
    assert np.all(np.abs(u.levels) <= problem.u_max)


@pytest.mark.parametrize(
    ("model", "x0", "target"),
    [
        (WIE, [0.0, 0.0, 0.0, 0.0], 1.0),
        (BEAM, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 2.0),
        (BEAM, [0.3, 0.5, 0.05, -0.1, 0.01, 0.02], -1.0),  # moving, vibrating
        (BEAM, [0.3, 0.5, 0.05, -0.1, 0.01, 0.02], None),  # ... to rest, position free
    ],
)
def test_single_input_equals_the_existing_solver(model, x0, target):
    ref = plan_time_optimal(state_to_rest(model, 1.3, np.array(x0), target))
    M = MultiModel.from_modal(model)
    p = multi_state_to_rest(M, [1.3], x0, None if target is None else [target])
    prof = plan_multi_time_optimal(p)
    assert prof.certified, prof.certificate.message
    assert abs(prof.duration - ref.duration) <= 1e-9 * ref.duration
    assert np.allclose(prof.switch_times[0], ref.switch_times, rtol=0, atol=1e-8 * ref.duration)
    check_exact_and_bounded(p, prof)


@pytest.mark.parametrize("sync", ["time", "none"])
@pytest.mark.parametrize("goal", [(3.0, 2.0), (0.5, 6.0)])
def test_decoupled_gantry_takes_the_slower_axis_time(sync, goal):
    g = gantry(10.0, 40.0, 5.0, 2.0, trolley_force=30.0, bridge_force=50.0)
    M = g.model
    axes = []
    for j in range(2):
        mm = ModalModel(b0=M.B0[j, j], omega=[M.omega[j]], zeta=[M.zeta[j]], b=[M.Bm[j, j]])
        axes.append(plan_time_optimal(rest_to_rest(mm, g.u_max[j], goal[j])))
    assert all(a.certified for a in axes)
    p = multi_rest_to_rest(M, g.u_max, list(goal))
    prof = plan_multi_time_optimal(p, sync)
    T_ref = max(a.duration for a in axes)
    assert abs(prof.duration - T_ref) <= 1e-9 * T_ref
    assert prof.certified, prof.certificate.message
    check_exact_and_bounded(p, prof)
    slow = int(np.argmax([a.duration for a in axes]))
    fast = 1 - slow
    roles = {tuple(d["inputs"]): d for d in prof.certificate.parts}
    fast_part = roles[(M.inputs[fast],)]
    if sync == "time":
        # both axes move until T*; the fast one at the lowest peak that arrives exactly then
        assert fast_part["role"] == "lowest_peak" and 0.0 < fast_part["peak_fraction"] < 1.0
        assert fast_part["peak_lower_bound"] >= fast_part["peak_fraction"] * (1 - 1e-8)
        assert np.max(np.abs(prof.levels[fast])) < g.u_max[fast]
        assert prof.switch_times[fast][-1] > 0.5 * T_ref
    else:
        # the fast axis is time-optimal on its own, then holds 0
        assert fast_part["role"] == "own_optimum"
        assert abs(prof.switch_times[fast][-1] - axes[fast].duration) <= 1e-9 * T_ref
        assert prof.levels[fast][-1] == 0.0
    # the independent weak-duality bound: no input arrives by T*(1 - 1e-6)
    nu = ind.costate_final(p, prof)
    assert ind.proves_infeasible(p, nu, prof.duration * (1 - 1e-6))


def test_phase_moves_on_the_straight_line_or_refuses():
    g = gantry(10.0, 40.0, 5.0, 2.0, trolley_force=30.0, bridge_force=50.0)
    p = multi_rest_to_rest(g.model, g.u_max, [3.0, 2.0])
    prof = plan_multi_time_optimal(p, "phase")
    T_star = plan_multi_time_optimal(p).duration
    assert prof.certified and prof.duration >= T_star
    check_exact_and_bounded(p, prof)
    # the rigid bodies stay on the line: p_y / p_x = 2 / 3 at every break, by our simulation
    A, B = ind.matrices(g.model)
    u = prof.input()
    x = np.zeros(8)
    from scipy.linalg import expm

    for h, row in zip(np.diff(u.breaks), u.levels):
        M = np.zeros((10, 10))
        M[:8, :8], M[:8, 8:] = A, B
        E = expm(M * h)
        x = E[:8, :8] @ x + E[:8, 8:] @ row
        assert abs(3.0 * x[2] - 2.0 * x[0]) <= 1e-9
    for bad, words in (
        (multi_state_to_rest(g.model, g.u_max, np.zeros(8), [3.0, None]), "target"),
        (multi_state_to_rest(g.model, g.u_max, [0, 1.0, 0, 0, 0, 0, 0, 0], [3.0, 2.0]), "velocity"),
    ):
        with pytest.raises(ConfigError) as err:
            plan_multi_time_optimal(bad, "phase")
        assert err.value.parameter == "sync" and words in err.value.reason
    with pytest.raises(ConfigError) as err:
        plan_multi_time_optimal(p, "diagonal")
    assert err.value.parameter == "sync"


@pytest.mark.parametrize(
    ("actuated", "u_max", "goal"),
    [((0, 3), [5.0, 3.0], 1.0), ((0, 1), [2.0, 6.0], 0.4), ((1, 3), [4.0, 4.0], -0.7)],
)
def test_coupled_chain_certified_and_bracketed_by_an_independent_lp(actuated, u_max, goal):
    c = multi_chain([1.0, 0.8, 1.2, 1.0], [100.0, 80.0, 120.0], [0.1, 0.1, 0.1], actuated=actuated, u_max=u_max)
    p = multi_rest_to_rest(c.model, c.u_max, [goal])
    prof = plan_multi_time_optimal(p)
    assert prof.certified, prof.certificate.message
    assert len(prof.certificate.parts) == 1 and prof.certificate.parts[0]["role"] == "critical"
    check_exact_and_bounded(p, prof)
    # every input bang-bang at its bound, with its own switches
    for i in range(2):
        assert np.all(np.abs(prof.levels[i]) == c.u_max[i])
    # T* from an independent LP: its co-state proves T*(1 - 1e-4) infeasible (our expm integrals)
    nu = ind.lp_costate(p, prof.duration * (1 - 1e-4))
    assert ind.proves_infeasible(p, nu, prof.duration * (1 - 1e-4))
    # ... and the bound is not vacuous: the planner's profile reaches rest at T*, so no co-state proves T*(1 + 1e-4)
    assert not ind.proves_infeasible(p, nu, prof.duration * (1 + 1e-4))


def test_repeated_frequencies_with_two_inputs():
    M = MultiModel(
        inputs=("a", "b"),
        rigid_bodies=("x",),
        b0=((0.5, 0.5),),
        c=(0.0,),
        omega=(2.0, 2.0, 5.0),
        zeta=(0.0, 0.0, 0.01),
        b=((1.0, 0.2), (-0.3, 1.0), (0.4, 0.4)),
    )
    p = multi_state_to_rest(M, [1.0, 2.0], [0.0, 0.3, 0.1, 0.0, 0.0, -0.2, 0.0, 0.0], [1.0])
    prof = plan_multi_time_optimal(p)
    assert prof.certified, prof.certificate.message
    check_exact_and_bounded(p, prof)
    nu = ind.costate_final(p, prof)
    assert ind.proves_infeasible(p, nu, prof.duration * (1 - 1e-6))


def test_moving_vibrating_two_bodies_to_rest_with_free_positions():
    g = gantry(10.0, 40.0, 5.0, 2.0, trolley_force=30.0, bridge_force=50.0)
    x0 = [0.0, 0.8, 1.0, -0.5, 0.1, 0.05, -0.2, 0.0]
    for goal in (None, [None, 4.0]):
        p = multi_state_to_rest(g.model, g.u_max, x0, goal)
        prof = plan_multi_time_optimal(p)
        assert prof.certified, prof.certificate.message
        check_exact_and_bounded(p, prof)
        d = prof.to_dict()
        assert len(d["levels"]) == len(d["switch_times"]) + 1 and all(len(r) == 2 for r in d["levels"])
        assert d["sync"] == "time" and d["certified"] is True


def test_already_at_rest():
    g = gantry(10.0, 40.0, 5.0, 2.0)
    p = multi_rest_to_rest(g.model, g.u_max, [0.0, 0.0])
    prof = plan_multi_time_optimal(p)
    assert prof.duration == 0.0 and prof.certified


def test_coupled_model_with_a_singular_input():
    """u1 reaches only the second mode: the optimal co-state does not see it (B_1^T lambda = 0); the others
    set T*, u1 finishes the move inside what it reaches with its lowest peak, proved by its own dual."""
    M = MultiModel(
        inputs=("u0", "u1", "u2"),
        rigid_bodies=("x",),
        b0=((-0.58, 0.0, -0.29),),
        c=(0.0,),
        omega=(0.88, 4.21),
        zeta=(0.002, 0.026),
        b=((0.4, 0.0, -0.7), (0.0, -0.94, 0.41)),
    )
    assert not M.is_normal
    p = multi_rest_to_rest(M, [2.6, 4.2, 0.6], [0.3])
    prof = plan_multi_time_optimal(p)
    assert prof.certified, prof.certificate.message
    check_exact_and_bounded(p, prof)
    stages = prof.certificate.parts[0]["stages"]
    assert [s["inputs"] for s in stages] == [["u1"]] and 0.0 < stages[0]["peak_fraction"] < 1.0
    assert stages[0]["peak_lower_bound"] >= stages[0]["peak_fraction"] * (1 - 1e-8)
    assert np.max(np.abs(prof.levels[1])) < 4.2 and np.all(np.abs(prof.levels[0]) == 2.6)
    nu = ind.costate_final(p, prof)
    assert ind.proves_infeasible(p, nu, prof.duration * (1 - 1e-6))
    assert not ind.proves_infeasible(p, nu, prof.duration * (1 + 1e-4))
