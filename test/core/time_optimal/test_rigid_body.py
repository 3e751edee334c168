"""Rigid body (no modes): the planner against the closed-form optimum.

A rigid body ``p'' = c p' + b0 u`` stops in at most one switch; its minimum time is
known in closed form (the textbook double integrator for ``c = 0``; for ``c < 0`` the
independent :func:`reference_solutions.rigid_min_time`, itself checked here against
the textbook formula and our own simulation).  Every plan also passes all the checks
of :func:`test_solver_properties.plan_and_check`.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from reference_solutions import closed_form_double_integrator, rigid_min_time
from scipy.optimize import brentq

from flexmotion_ros.core import (
    ModalModel,
    PiecewiseConstant,
    final_state,
    motion_to_rest,
    rest_to_rest,
    state_to_rest,
)
from flexmotion_ros.core.time_optimal.rigid_body import rigid_profile

from .test_solver_properties import (
    SETTINGS,
    log_uniform,
    plan_and_check,
    signs,
    units,
)


@pytest.mark.parametrize(
    "b0, u_max, v, stop, T",
    [
        (1.0, 1.0, 1.0, 0.5, 1.0),
        (1.0, 1.0, 10.0, 50.0, 10.0),
        (0.5, 1.0, -1.0, -1.0, 2.0),
        (-2.0, 0.25, 2.0, 4.0, 4.0),
        (
            1.0,
            1.0,
            56.23413251903491,
            1581.13883008419,
            56.23413251903491,
        ),  # within rounding of the stop point
    ],
)
def test_stop_exactly_where_the_free_stop_ends(b0, u_max, v, stop, T):
    """Rigid body moving at ``v``: full braking stops it at ``v |v| / 2a`` after ``|v| / a``
    (all exact in binary).  With that point as the target the optimum is the same
    single-level profile: a degenerate but legitimate goal (e.g. 'stop here')."""
    model = ModalModel(b0=b0)
    free = plan_and_check(motion_to_rest(model, u_max, v))
    assert free.duration == pytest.approx(T, rel=1e-12)
    assert float(free.final_state[0]) == pytest.approx(stop, rel=1e-12)
    fixed = plan_and_check(state_to_rest(model, u_max, [0.0, v], stop))
    # a target off the stop point by d costs ~2 sqrt(d / a) more (square root: ill-conditioned)
    a = abs(b0) * u_max
    d = abs(stop - v * abs(v) / (2 * a)) + 4 * np.finfo(float).eps * abs(stop)
    assert abs(fixed.duration - T) <= 1e-9 * T + 2.0 * math.sqrt(d / a)
    if stop == v * abs(v) / (2 * a):
        assert fixed.switch_times.size == 0


def test_one_bang_stop_on_the_target_is_the_reference_minimum():
    """A damped rigid body (one undamped mode) braked by one full bang stops, within rounding, on
    the target (a case hypothesis found replanning).  The reference's root search in the first
    phase's length is flat there (quadratic), so it used to give ~sqrt(rounding) too much time and the
    plan's correct T* = t_stop seemed to beat the rigid-body minimum by 1.1e-7 relative."""
    model = ModalModel(
        b0=-0.2171196699034846, c=-1.9330367946433071, omega=(22.530278347427398,),
        zeta=(0.0,), b=(0.37782299220926774,),
    )  # fmt: skip
    u_max = 0.7487201123422123
    x0 = [-0.0036133843365933165, -0.012100175739656474, -0.0005550707090549378, 0.01255561260458926]
    problem = state_to_rest(model, u_max, x0, -0.004024703258424338)
    p, v = (float(z) for z in problem.shifted_initial()[:2])
    a = abs(model.b0) * u_max
    t_stop = math.log1p(-model.c * abs(v) / a) / -model.c  # full braking against v, closed form
    assert rigid_min_time(model, u_max, p, v, True) == pytest.approx(t_stop, rel=1e-14)
    profile = plan_and_check(problem)  # includes T* >= rigid minimum (1 - 1e-9)
    assert profile.duration == pytest.approx(t_stop, rel=1e-12)


#: A replan along a 3-mode plan's last (braking) arc, 6.8e-14 m off the rigid switching curve
#: (hypothesis, ``test_warm_and_cold_give_the_same_certified_optimum``, seed 11).
ON_CURVE_REPLAN = state_to_rest(
    ModalModel(
        b0=-9.224441671487169, c=-1.0, omega=(1.0, 2.848990930279117, 5.413082767530322),
        zeta=(0.0, 0.0, 0.0), b=(0.8092988905170001, -0.210697162316109, -1.0),
    ),
    3.414831501603354,
    [-29.88082617878343, -11.206641871565942, -0.12702517721080933, 0.8282288805505517,
     0.03129024337684237, -0.1925601855226323, 0.12547951048015005, -0.6289897072460245],
    -31.49991400449708,
)  # fmt: skip


def test_the_rigid_bound_of_a_start_on_the_viscous_switching_curve_is_the_braking_time():
    """One braking arc lands within rounding of the target: the rigid optimum is that arc.

    The viscous solver's scan bracketed no root there (rounding put it at t < 0) and answered
    with a two-arc move of 0.574 s: a "lower bound" above the 0.304 s optimum, which the
    certificate's gap test would have taken for proof.  No move to rest is shorter than
    braking at full force, and the reference minimum is at most sqrt(rounding) longer.
    """
    problem = ON_CURVE_REPLAN
    model, u_max = problem.model, problem.u_max
    p, v = (float(z) for z in problem.shifted_initial()[:2])
    a = abs(model.b0) * u_max
    t_stop = math.log1p(-model.c * abs(v) / a) / -model.c  # full braking against v, closed form
    rigid = rigid_profile(model, u_max, problem.shifted_initial(), True)
    assert rigid.duration == pytest.approx(t_stop, rel=1e-14)
    assert rigid.switch_times.size == 0
    assert rigid.duration <= rigid_min_time(model, u_max, p, v, True)  # a lower bound (the exact one: 3e-7 more)
    profile = plan_and_check(problem)  # includes T* >= rigid minimum within the plan's own final error
    assert profile.duration == pytest.approx(t_stop, rel=1e-12)


# ------------------------------------------- rigid body: closed-form optimum
@st.composite
def rigid_problems(draw):
    b0 = draw(signs) * draw(log_uniform(0.1, 10.0))
    c = 0.0 if draw(st.booleans()) else -draw(log_uniform(1e-2, 3.0))
    model = ModalModel(b0=b0, c=c)
    u_max = draw(log_uniform(0.1, 10.0))
    size = draw(log_uniform(1e-3, 1e3))
    kind = draw(st.sampled_from(["rest", "motion", "state"]))
    if kind == "rest":
        return rest_to_rest(model, u_max, draw(signs) * size)
    v = draw(signs) * abs(b0) * u_max * size
    if kind == "motion":
        return motion_to_rest(model, u_max, v)
    p = draw(units) * size
    target = None if draw(st.booleans()) else draw(units) * size
    return state_to_rest(model, u_max, [p, draw(units) * v], target)


@settings(max_examples=40, **SETTINGS)
@given(rigid_problems())
@example(rest_to_rest(ModalModel(b0=1.0), 1.0, 1.0))
@example(motion_to_rest(ModalModel(b0=-0.43), 1.0, 0.5))
@example(state_to_rest(ModalModel(b0=2.0, c=-0.5), 1.0, [0.3, -4.0], None))
@example(rest_to_rest(ModalModel(b0=1.0, c=-1.0), 1.0, 1000.0))
@example(rest_to_rest(ModalModel(b0=1.0, c=-1.0), 0.1, 1000.0))
def test_rigid_body_closed_form_minimum_time(problem):
    m, um = problem.model, problem.u_max
    a = abs(m.b0) * um
    fixed = problem.target is not None
    x = problem.shifted_initial() if fixed else None
    p, v = (float(x[0]), float(x[1])) if fixed else (0.0, float(problem.x0[1]))
    if m.c == 0.0:
        if fixed:
            s = math.copysign(1.0, m.b0)  # u -> sign(b0) u makes the gain positive
            T_ref = closed_form_double_integrator(a, s * p, s * v)
        else:
            T_ref = abs(v) / a
    elif not fixed:
        T_ref = math.log1p(-m.c * abs(v) / a) / -m.c
    else:
        T_ref = rigid_min_time(m, um, p, v, True)
    profile = plan_and_check(problem)
    assert profile.duration == pytest.approx(T_ref, rel=1e-9, abs=1e-12)
    assert profile.switch_times.size <= 1


def test_rigid_min_time_helper_matches_the_textbook_formula():
    """The helper used as the independent lower bound, checked against the closed form."""
    m = ModalModel(b0=-2.0)
    for p, v in [(1.0, 0.0), (-3.0, 2.0), (0.5, -7.0), (0.0, 1.0)]:
        assert rigid_min_time(m, 0.5, p, v, True) == pytest.approx(
            closed_form_double_integrator(1.0, -p, -v), rel=1e-12
        )
    damped = ModalModel(b0=1.0, c=-1.0)
    T = rigid_min_time(damped, 1.0, -1.0, 0.0, True)
    assert T > 2.0  # friction makes it slower than the undamped optimum, 2 s
    # our own simulation: some one-switch input of length T reaches rest at the target...

    def v_end(t1, T):
        return final_state(damped, [-1.0, 0.0], PiecewiseConstant.from_switches([t1], [1.0, -1.0], T))

    t1 = brentq(lambda t: v_end(t, T)[1], 1e-9, T - 1e-9, xtol=1e-15)
    assert abs(v_end(t1, T)[0]) < 1e-12
    # ...and none of length 0.999 T does (velocity zero leaves the position short)
    Ts = 0.999 * T
    t1s = brentq(lambda t: v_end(t, Ts)[1], 1e-9, Ts - 1e-9, xtol=1e-15)
    assert v_end(t1s, Ts)[0] < -1e-4
