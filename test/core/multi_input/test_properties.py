"""Property tests over random coupled models with m in {2, 3} inputs (hypothesis).

For every example: the planner succeeds with a certificate; no level exceeds its
input's bound; the final state is exact by OUR matrix exponentials; and the
certificate's co-state proves, by weak duality evaluated here (expm integrals
between brentq-refined zeros), that no admissible input reaches rest by
``T* (1 - 1e-6)``.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st

from flexmotion_ros.core.errors import ModelError, SolverError
from flexmotion_ros.core.multi_input import MultiModel, multi_state_to_rest, plan_multi_time_optimal
from flexmotion_ros.core.multi_input.parts import mode_free_push

from . import independent as ind


def gain(lo: float):
    return st.floats(lo, 1.0).flatmap(lambda v: st.sampled_from([v, -v]))


@st.composite
def moves(draw):
    m = draw(st.sampled_from([2, 3]))
    N = draw(st.integers(1, 3))
    omega = sorted(draw(st.lists(st.floats(0.5, 8.0), min_size=N, max_size=N, unique=True)))
    if min(np.diff(omega), default=1.0) < 0.05:
        omega = [0.5 + 1.3 * i for i in range(N)]
    zeta = draw(st.lists(st.floats(0.0, 0.05), min_size=N, max_size=N))
    b0 = [draw(st.floats(0.2, 2.0)) for _ in range(m)]
    b = [[draw(gain(0.05)) for _ in range(m)] for _ in range(N)]
    model = MultiModel(
        inputs=tuple(f"u{i}" for i in range(m)),
        rigid_bodies=("x",),
        b0=(tuple(b0),),
        c=(draw(st.sampled_from([0.0, -0.05])),),
        omega=tuple(omega),
        zeta=tuple(zeta),
        b=tuple(tuple(r) for r in b),
    )
    u_max = [draw(st.floats(0.5, 5.0)) for _ in range(m)]
    x0 = np.zeros(model.n_states)
    x0[1] = draw(st.floats(-0.5, 0.5))
    x0[2::2] = [draw(st.floats(-0.05, 0.05)) for _ in range(N)]
    goal = draw(st.floats(0.2, 4.0)) * draw(st.sampled_from([1.0, -1.0]))
    return multi_state_to_rest(model, u_max, x0, [goal])


def _one_rigid_one_mode(b0, omega: float, u_max, goal: float):
    model = MultiModel(
        inputs=tuple(f"u{i}" for i in range(len(b0))), rigid_bodies=("x",), b0=(tuple(b0),), c=(0.0,),
        omega=(omega,), zeta=(0.0,), b=((1.0,) * len(b0),),
    )  # fmt: skip
    return multi_state_to_rest(model, u_max, np.zeros(4), [goal])


#: Issue 15 (local seed 16): T* lies 1e-11 (relative) above the rigid-body bound 1.68960 s, where
#: omega T / 2 = 2 pi (1 + 4e-6): the rigid bang-bang nearly leaves the mode at rest, and the optimum
#: finishes it with a blip of a few microseconds beside a switch (u0 - u1 pushes the rigid body alone).
NEAR_RESONANT_RIGID_BOUND = _one_rigid_one_mode((1.2, 0.201171875), 7.4375, [1.0, 1.0], 1.0)


@settings(max_examples=20, suppress_health_check=[HealthCheck.too_slow])
@given(moves())
@example(NEAR_RESONANT_RIGID_BOUND)
def test_random_coupled_models_are_certified_exact_bounded_and_proved_optimal(problem):
    prof = plan_multi_time_optimal(problem)
    assert prof.certified, prof.certificate.message
    u = prof.input()
    assert np.all(np.abs(u.levels) <= problem.u_max)
    xT = ind.final_state(problem, u.breaks, u.levels)
    assert ind.relative_error(problem, xT, prof.duration, problem.u_max) < 1e-9
    nu = ind.costate_final(problem, prof)
    assert ind.proves_infeasible(problem, nu, prof.duration * (1 - 1e-6))


@st.composite
def non_normal_moves(draw):
    """Coupled models where each gain may be zero: rigid bodies or modes only some inputs reach."""
    m = draw(st.sampled_from([2, 3]))
    k = draw(st.sampled_from([1, 2]))
    N = draw(st.integers(1, 2))
    b0 = [[draw(st.sampled_from([0.0, 0.3, -0.7, 1.1])) for _ in range(m)] for _ in range(k)]
    b = [[draw(st.sampled_from([0.0, 0.4, -0.6, 0.9])) for _ in range(m)] for _ in range(N)]
    omega = [1.3, 4.1][:N]
    zeta = [0.01, 0.03][:N]
    try:
        model = MultiModel(
            inputs=tuple(f"u{i}" for i in range(m)),
            rigid_bodies=tuple(f"p{j}" for j in range(k)),
            b0=tuple(tuple(r) for r in b0),
            c=(0.0,) * k,
            omega=tuple(omega),
            zeta=tuple(zeta),
            b=tuple(tuple(r) for r in b),
        )
    except ModelError:
        assume(False)
    u_max = [draw(st.sampled_from([0.8, 2.0, 3.5])) for _ in range(m)]
    goal = [draw(st.floats(0.3, 3.0)) * draw(st.sampled_from([1.0, -1.0])) for _ in range(k)]
    return multi_state_to_rest(model, u_max, np.zeros(model.n_states), goal)


def _three_inputs_one_mode(b0: tuple[float, float, float]):
    """A unit move of one rigid body and one mode (1.3 rad/s) driven by three inputs of bound 0.8, from rest;
    u0 does not reach the mode, u1 and u2 drive it alike (gain 0.4): the rigid gains ``b0`` decide the rest."""
    model = MultiModel(
        inputs=("u0", "u1", "u2"), rigid_bodies=("p0",), b0=(b0,), c=(0.0,), omega=(1.3,), zeta=(0.01,),
        b=((0.0, 0.4, 0.4),),
    )  # fmt: skip
    return multi_state_to_rest(model, [0.8, 0.8, 0.8], np.zeros(4), [1.0])


#: Issue 15 (seed 12): T* is the rigid-body bound with u0 and u2 at full push and u1 cancelling the mode;
#: the optimal co-state has no mode component (u1 singular), but the smoothed dual only approaches it.
RIGID_BOUND_WITH_SINGULAR_MODE_INPUT = _three_inputs_one_mode((-0.7, 0.0, 0.3))
#: Seed 12 after that fix: T* the rigid-body bound again, every input pushing the rigid body and u1, u2's
#: mode drives cancelling exactly (same gain and bound): no input singular, the plain Newton singular.
RIGID_BOUND_WITH_CANCELLING_MODE_DRIVES = _three_inputs_one_mode((0.3, 0.3, -0.7))
#: Seed 12 after both: u1 gives up its rigid push to cancel u2's mode drive, all three switching together;
#: a family of co-states fits (the switch-time Newton's Jacobian is singular).
CANCELLING_MODE_DRIVES_ABOVE_RIGID_BOUND = _three_inputs_one_mode((0.3, 0.3, 1.1))


def _rigid_and_modes(b0, b, u_max, goal: float):
    """One rigid body and the modes 1.3 and 4.1 rad/s of :func:`non_normal_moves`, from rest."""
    model = MultiModel(
        inputs=tuple(f"u{i}" for i in range(len(b0))), rigid_bodies=("p0",), b0=(tuple(b0),), c=(0.0,),
        omega=(1.3, 4.1), zeta=(0.01, 0.03), b=tuple(tuple(r) for r in b),
    )  # fmt: skip
    return multi_state_to_rest(model, u_max, np.zeros(6), [goal])


#: Issue 15 (local seed 20): T* the rigid-body bound (u1 alone pushes it); u0 reaches both modes exactly as
#: u1 does, so the lowest peak (0.8 / 3.5) mirrors u1 with one switch: four mode equations, two unknowns
#: (switch, peak), a family of co-states -- the switch-time Newton's Jacobian singular by its shape.
MIRRORED_MODE_DRIVE = _rigid_and_modes((0.0, 0.3), ((0.4, 0.4), (0.4, 0.4)), [3.5, 0.8], 0.30078125)
#: Issue 15 (local seed 27): the same with two inputs (u0, u1) cancelling u2's drive on both modes.
TWO_INPUTS_CANCELLING_MODE_DRIVE = _rigid_and_modes(
    (0.0, 0.0, 0.3), ((0.4, 0.4, 0.0), (0.4, -0.6, 0.4)), [3.5, 3.5, 3.5], 0.5
)


@settings(max_examples=12, suppress_health_check=[HealthCheck.too_slow])
@given(non_normal_moves())
@example(MIRRORED_MODE_DRIVE)
@example(TWO_INPUTS_CANCELLING_MODE_DRIVE)
@example(RIGID_BOUND_WITH_SINGULAR_MODE_INPUT)
@example(RIGID_BOUND_WITH_CANCELLING_MODE_DRIVES)
@example(CANCELLING_MODE_DRIVES_ABOVE_RIGID_BOUND)
def test_random_non_normal_models_are_certified_exact_and_proved_optimal(problem):
    prof = plan_multi_time_optimal(problem)
    assert prof.certified, prof.certificate.message
    u = prof.input()
    assert np.all(np.abs(u.levels) <= problem.u_max)
    xT = ind.final_state(problem, u.breaks, u.levels)
    assert ind.relative_error(problem, xT, prof.duration, problem.u_max) < 1e-9
    nu = ind.costate_final(problem, prof)
    assert ind.proves_infeasible(problem, nu, prof.duration * (1 - 1e-6))


def _coupled(b0, omega, zeta, b, u_max, x0, goal: float, c: float = 0.0):
    model = MultiModel(
        inputs=tuple(f"u{i}" for i in range(len(b0))), rigid_bodies=("x",), b0=(tuple(b0),), c=(c,),
        omega=tuple(omega), zeta=tuple(zeta), b=tuple(tuple(r) for r in b),
    )  # fmt: skip
    return multi_state_to_rest(model, u_max, np.asarray(x0, float), [goal])


#: Issue 15, still refused ("no extremal converged"; main refuses them too), found by local seeds 1..60 of
#: the two properties above.  Common to all three: a combination of the inputs drives the rigid body
#: alone (the mode drives cancel), so switches coincide and the switch-time Jacobian is singular.
STILL_REFUSED = {
    # local seed 3: u1 - u0 pushes the rigid body alone; u1 nearly singular (|S_1| peak 0.7 % of |S_0|), Newton
    # stalls at residual 1.6e-6 with 6 switches for 8 final-state equations: a 3000-sample LP shows u1
    # with 7 switches, three of them within 15 ms near t = 1.22 s (T* = 3.0545 s)
    "seed3_nearly_singular_input": _coupled(
        (0.2, 0.4947409680408328),
        (0.5, 0.8074384573542, 7.03125),
        (0.0, 0.025390625, 0.025390625),
        ((1.0, 1.0), (0.05, 0.05), (1.0, 1.0)),
        [0.5, 4.0],
        [0, 0, 0, 0, -0.03081051, 0, 0, 0],
        0.2,
        c=-0.05,
    ),  # fmt: skip
    # local seed 16 (after NEAR_RESONANT_RIGID_BOUND): three inputs, one switch each, T* = 3.3259 s, 4e-4 above
    # the rigid-body bound (the same mode, 7.4375 rad/s); the mode-free push is u0 - 2 u1
    "seed16_three_inputs_one_mode": _coupled(
        (0.201171875, 0.2, 0.203125),
        (7.4375,),
        (0.0,),
        ((0.125, 0.0625, 0.25),),
        [0.5, 0.5, 0.5],
        [0, 0.5, 0, 0],
        0.203125,
    ),  # fmt: skip
    # local seed 20 (after the two examples above): u1 + u2 - u0 pushes the rigid body alone; u0 and u1
    # switch together near T/2 (T* = 2.7073 s, above the rigid-body bound 2.18 s)
    "seed20_rigid_only_combination": _rigid_and_modes(
        (0.0, 0.3, 0.3), ((0.4, 0.0, 0.4), (0.4, 0.4, 0.0)), [0.8, 0.8, 2.0], 1.0
    ),
}


@pytest.mark.parametrize("name", sorted(STILL_REFUSED))
def test_known_refusals_name_the_degenerate_push(name):
    """Still refused, in one line that names the physical trait (update this test when they plan)."""
    with pytest.raises(SolverError, match="pushes the rigid bodies without exciting any mode") as info:
        plan_multi_time_optimal(STILL_REFUSED[name])
    assert "\n" not in str(info.value)


def test_the_degenerate_push_is_named_only_where_it_exists():
    """``mode_free_push``: true where a combination of inputs moves the rigid body with no mode drive."""
    assert mode_free_push(STILL_REFUSED["seed20_rigid_only_combination"].model)  # u1 + u2 - u0
    assert mode_free_push(NEAR_RESONANT_RIGID_BOUND.model)  # u0 - u1
    assert mode_free_push(RIGID_BOUND_WITH_SINGULAR_MODE_INPUT.model)  # u0 alone (planned since wip/mi4)
    # the mode gains invertible: every push excites a mode
    assert not mode_free_push(_rigid_and_modes((0.3, 0.3), ((0.4, 0.4), (0.4, -0.6)), [1.0, 1.0], 1.0).model)
    # u0 + u1 - u2 cancels both modes and, here, its rigid push too
    one = [1.0, 1.0, 1.0]
    assert not mode_free_push(_rigid_and_modes((0.3, 0.3, 0.6), ((0.4, 0.0, 0.4), (0.0, 0.4, 0.4)), one, 1.0).model)
