"""Property tests on near-degenerate structures: omega T near multiples of 2 pi, switch times merging.

A machine whose modes complete whole periods in each half of the rigid
body's bang-bang (``omega_i T_r / 2 = 2 pi k_i (1 + delta_i)``) is the
structure ``flexmotion design`` recommends: at ``delta = 0`` the rigid
optimum leaves every mode at rest; nearby the optimum grows a notch at the
rigid switch whose three switch times merge as ``delta -> 0`` (below
rounding for ``|delta| < ~1e-5``, where the switching function's sign there
is noise).  Every plan must reach the target (our own ``scipy.linalg.expm``)
and be certified: fully, or, where the sign test cannot decide, within
``GAP_RTOL`` of the rigid body's minimum time computed here in closed form;
or (two modes tuned at once: a quintuple of switches below rounding, 5e-7
above the bound) not certified, with the bound it states checked here.
Before this work the planner refused such machines ("missed the target",
after 2-10 s): e.g. one mode at ``omega T_r / 2 = 2 pi (1 - 1e-3)`` with
``zeta = 1e-4`` (now certified optimal, found by the structure search), and
the same two-mode machine undamped.

Known gaps (xfail below): a lightly damped mode tuned within ~1e-6 of a
whole period (``zeta`` 1e-4..1e-3), and two modes tuned with different
detunings (1e-4 and 1e-3), are still refused ("missed the target") or
planned uncertified with a loose bound.  The strategy draws one undamped
mode; the two-mode machine with equal detunings is an explicit example.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from reference_solutions import bang_bang_final_error as final_error
from reference_solutions import rigid_min_time

from flexmotion_ros.core import ModalModel, MoveProblem, PlannerConfig
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.results import CertificateStatus
from flexmotion_ros.core.tolerances import GAP_RTOL


def log_uniform(lo: float, hi: float):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: 10.0**e)


@st.composite
def tuned_problems(draw):
    """A rest-to-rest move on a machine tuned near whole periods per half of the rigid move."""
    b0 = draw(log_uniform(0.2, 5.0))
    u_max = draw(log_uniform(0.2, 5.0))
    distance = draw(log_uniform(0.05, 20.0))
    T_r = 2.0 * math.sqrt(distance / (b0 * u_max))  # closed form, c = 0
    n_modes = 1  # two modes tuned at once: the explicit examples below
    ks = sorted(draw(st.lists(st.integers(1, 3), min_size=n_modes, max_size=n_modes, unique=True)))
    omega, b = [], []
    for k in ks:
        delta = draw(st.sampled_from([-1.0, 1.0])) * draw(log_uniform(1e-9, 1e-3))
        omega.append(4.0 * math.pi * k / T_r * (1.0 + delta))
        b.append(draw(st.sampled_from([-1.0, 1.0])) * draw(log_uniform(0.3, 2.0)))
    zeta = [0.0 for _ in ks]  # undamped: the notch at the rigid switch (damped: see the xfail below)
    model = ModalModel(b0=b0, c=0.0, omega=tuple(omega), zeta=tuple(zeta), b=tuple(b))
    return MoveProblem(model, u_max, np.zeros(model.n_states), distance)


@settings(max_examples=12, suppress_health_check=[HealthCheck.too_slow], deadline=None)
@given(problem=tuned_problems())
def test_machines_tuned_near_whole_periods_plan_and_certify(problem):
    config = PlannerConfig(model=problem.model, u_max=problem.u_max, method="time_optimal", options={})
    profile = plan_move(config, problem, None).continuous
    assert final_error(problem, profile) <= 1e-9
    T_rigid = rigid_min_time(problem.model, problem.u_max, -problem.target, 0.0, True)
    assert profile.duration >= T_rigid * (1.0 - 1e-12)
    status = profile.certificate.status
    if status is CertificateStatus.WITHIN_GAP:  # proved by the independent bound here
        assert profile.duration <= T_rigid * (1.0 + GAP_RTOL)
    elif status is CertificateStatus.FAILED:
        # a notch below rounding too far from the bound for the gap (two modes tuned at once): the plan
        # states the bound it has, which must hold (independent closed form) and be tight
        gap = float(re.search(r"within ([0-9.e+-]+) \(relative\)", profile.certificate.message).group(1))
        assert (profile.duration - T_rigid) / profile.duration <= gap * 1.1 + 1e-15
        assert gap <= 1e-5
    sw = profile.switch_times
    assert np.all(np.diff(sw) > 0.0) and (sw.size == 0 or (sw[0] > 0.0 and sw[-1] < profile.duration))


@pytest.mark.xfail(strict=True, reason="known gap: a lightly damped mode tuned to a whole period (issue 15)")
def test_a_lightly_damped_mode_tuned_to_a_whole_period_is_certified():
    model = ModalModel(b0=1.0, c=0.0, omega=(6.283184678861056,), zeta=(1e-4,), b=(-1.0,))
    problem = MoveProblem(model, 1.0, np.zeros(model.n_states), 1.0)
    config = PlannerConfig(model=model, u_max=1.0, method="time_optimal", options={})
    profile = plan_move(config, problem, None).continuous
    assert profile.certified and final_error(problem, profile) <= 1e-9


def test_a_damped_mode_near_a_whole_period_is_planned_and_certified():
    """``omega T_r / 2 = 2 pi (1 - 1e-3)``, ``zeta = 1e-4``: refused after seconds before the structure search."""
    model = ModalModel(b0=1.0, c=0.0, omega=(6.276902121872407,), zeta=(1e-4,), b=(-1.0,))
    problem = MoveProblem(model, 1.0, np.zeros(model.n_states), 1.0)
    config = PlannerConfig(model=model, u_max=1.0, method="time_optimal", options={})
    profile = plan_move(config, problem, None).continuous
    assert profile.certified, profile.certificate.message
    assert final_error(problem, profile) <= 1e-9


def test_two_modes_tuned_alike_plan_exactly_with_the_bound_they_state():
    """Both modes at ``(1 - 1e-3)`` of whole periods: a quintuple of switches, 5e-7 above the rigid bound."""
    model = ModalModel(b0=1.0, c=0.0, omega=(6.276902121872407, 12.553804243744814), zeta=(0.0, 0.0), b=(-1.0, -1.0))
    problem = MoveProblem(model, 1.0, np.zeros(model.n_states), 1.0)
    config = PlannerConfig(model=model, u_max=1.0, method="time_optimal", options={})
    profile = plan_move(config, problem, None).continuous
    assert final_error(problem, profile) <= 1e-9
    T_rigid = rigid_min_time(model, 1.0, -1.0, 0.0, True)
    assert T_rigid <= profile.duration <= T_rigid * (1.0 + 1e-6)
    assert profile.certified or "within" in profile.certificate.message


def test_two_modes_tuned_differently_plan():
    # a known gap (xfail) until wip/tail3: with the continuous smoothed warm start the bounded structure
    # search (fallbacks) reaches the target
    model = ModalModel(b0=1.0, c=0.0, omega=(6.282556988648868, 12.553804243744814), zeta=(0.0, 0.0), b=(-1.0, -1.0))
    problem = MoveProblem(model, 1.0, np.zeros(model.n_states), 1.0)
    config = PlannerConfig(model=model, u_max=1.0, method="time_optimal", options={})
    profile = plan_move(config, problem, None).continuous
    assert final_error(problem, profile) <= 1e-9
