"""Goals and runtime values that cannot be planned are refused up front, in microseconds, with the reason.

Issue 16.3/16.4 and 15: ``--goal 1e300`` ended in ``ValueError: Maximum
allowed size exceeded`` (``np.linspace`` in the zero isolation); a mode above
the Nyquist frequency of the rate hung the next plan for 37 s; ``u_max =
1e12`` ended in "linear program failed at 5 samples"; ``c = -1e12`` in a
``MemoryError``.  Each is now a plan (checked here by our own expm) or a
one-line :class:`InputError` naming the parameter, for every method.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from reference_solutions import sampled_final_error

from flexmotion_ros.core import ModalModel, PlannerConfig
from flexmotion_ros.core.errors import ConfigError, GoalError, ModelError
from flexmotion_ros.core.methods.common import check_plannable
from flexmotion_ros.core.methods.table import METHODS, plan_move
from flexmotion_ros.core.model.boundary import state_to_rest

MODEL = ModalModel(b0=1.0, c=0.0, omega=(5.0, 13.0), zeta=(0.01, 0.02), b=(1.0, -0.7))
OPTIONS = {"time_optimal_friction": {"coulomb_force": 2.0}, "fixed_time": {"arrival_time": 5.0}}


def config(method: str = "time_optimal", model: ModalModel = MODEL, u_max: float = 10.0) -> PlannerConfig:
    return PlannerConfig(model=model, u_max=u_max, method=method, options=OPTIONS.get(method, {}))


@pytest.mark.parametrize("method", list(METHODS))
def test_an_absurd_goal_is_refused_up_front_by_every_method(method):
    problem = state_to_rest(MODEL, 10.0, np.zeros(MODEL.n_states), 1e300)
    t0 = time.perf_counter()
    with pytest.raises(GoalError, match="max_move_duration_s"):
        plan_move(config(method), problem, 200.0)
    assert time.perf_counter() - t0 < 0.5


def test_a_move_over_the_sample_budget_is_refused_naming_it():
    problem = state_to_rest(MODEL, 10.0, np.zeros(MODEL.n_states), 100.0)  # >= 6.3 s: over 5e6 samples at 1 MHz
    with pytest.raises(GoalError, match="sample budget"):
        plan_move(config(), problem, 1e6)


def test_a_mode_above_the_nyquist_frequency_is_refused_naming_the_rate():
    fast = MODEL.with_changes(omega=(5.0, 1e5))
    with pytest.raises(ConfigError) as err:
        check_plannable(config(model=fast), 1000.0)
    assert err.value.parameter == "rate_hz" and "Nyquist" in err.value.reason
    with pytest.raises(ConfigError):
        plan_move(config(model=fast), state_to_rest(fast, 10.0, np.zeros(6), 1.0), 1000.0)
    assert check_plannable(config(model=fast), 40000.0) == 40000.0  # above omega / pi: fine


def test_a_viscous_term_too_stiff_for_double_precision_is_refused_naming_it():
    stiff = MODEL.with_changes(c=-1e12)
    with pytest.raises(ModelError) as err:
        plan_move(config(model=stiff), state_to_rest(stiff, 10.0, np.zeros(6), 1e-9), 200.0)
    assert err.value.parameter == "model.c"


@pytest.mark.parametrize("u_max", [1e12, 1e-3])
def test_extreme_bounds_plan_exactly_or_refuse_by_the_budget(u_max):
    problem = state_to_rest(MODEL, u_max, np.zeros(MODEL.n_states), 1.0)
    try:
        result = plan_move(config(u_max=u_max), problem, 200.0)
    except GoalError as exc:
        assert "max_move_duration_s" in str(exc) and u_max < 1.0
        return
    s = result.sampled
    assert np.max(np.abs(s.commands)) <= u_max
    assert sampled_final_error(problem, s.commands, s.dt, reach=True) <= 1e-8
