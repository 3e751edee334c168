"""PreparedMove: built once per plan, same responses and scales as building them directly."""

from __future__ import annotations

import numpy as np
import pytest

from flexmotion_ros.core.config import PlannerConfig
from flexmotion_ros.core.errors import ConfigError
from flexmotion_ros.core.methods import plan_move
from flexmotion_ros.core.model.boundary import motion_to_rest, rest_to_rest
from flexmotion_ros.core.model.modal_model import ModalModel
from flexmotion_ros.core.sampled.fixed_time import plan_fixed_time_zoh
from flexmotion_ros.core.sampled.zoh import plan_time_optimal_zoh
from flexmotion_ros.core.simulation import modal_response
from flexmotion_ros.core.simulation.error_scale import state_scale
from flexmotion_ros.core.simulation.modal_response import ModalResponse
from flexmotion_ros.core.simulation.prepared import PreparedMove, prepare
from flexmotion_ros.core.time_optimal.fixed_time import plan_fixed_time
from flexmotion_ros.core.time_optimal.reachable_set import state_scale as reexported_scale
from flexmotion_ros.core.time_optimal.solver import plan_time_optimal

MODEL = ModalModel(b0=1.0, c=0.0, omega=(6.0, 15.0), zeta=(0.02, 0.01), b=(0.8, -0.5))
RATE = 200.0


@pytest.mark.parametrize("problem", [rest_to_rest(MODEL, 1.0, 0.7), motion_to_rest(MODEL, 1.0, 0.4)])
def test_prepared_move_matches_direct_construction(problem):
    move = PreparedMove.of(problem)
    direct = ModalResponse(problem.model, problem.include_position)
    tau = np.linspace(0.0, 2.0, 17)
    assert move.response.n == direct.n and move.response.include_position == problem.include_position
    np.testing.assert_array_equal(move.response.input_integral(tau), direct.input_integral(tau))
    np.testing.assert_array_equal(move.x0, problem.shifted_initial())
    for T in (0.3, 1.7):
        np.testing.assert_array_equal(move.error_scale(T), state_scale(direct, problem.shifted_initial(), 1.0, T))
        np.testing.assert_array_equal(move.error_scale(T), move.error_scale(T))  # cached, still a fresh copy
    assert reexported_scale is state_scale
    assert prepare(move) is move and prepare(problem).problem is problem


def test_with_continuous_and_with_bound():
    problem = rest_to_rest(MODEL, 1.0, 0.7)
    move = prepare(problem)
    best = plan_time_optimal(move)
    attached = move.with_continuous(best)
    assert attached.continuous is best and move.continuous is None and attached.response is move.response
    half = move.with_bound(0.5)
    assert half.u_max == 0.5 and half.response is move.response and half.continuous is None
    np.testing.assert_array_equal(half.error_scale(1.0), state_scale(move.response, move.x0, 0.5, 1.0))
    with pytest.raises(Exception):  # frozen  # noqa: B017, PT011
        attached.continuous = None  # type: ignore[misc]


def _count_full_model_responses(monkeypatch) -> list[int]:
    """Count ModalResponse constructions of the move's own model (the rigid-body bound builds its own)."""
    count = [0]
    original = modal_response.ModalResponse.__init__

    def counting(self, model, include_position=True):
        if model.n_modes:
            count[0] += 1
        original(self, model, include_position)

    monkeypatch.setattr(modal_response.ModalResponse, "__init__", counting)
    return count


def test_time_optimal_plan_builds_the_response_once(monkeypatch):
    problem = rest_to_rest(MODEL, 1.0, 0.7)
    before_cont = plan_time_optimal(problem)  # the planners called directly, as before
    before = plan_time_optimal_zoh(problem, RATE, before_cont)
    count = _count_full_model_responses(monkeypatch)
    result = plan_move(PlannerConfig(model=MODEL, u_max=1.0), problem, RATE)
    assert count[0] == 1
    np.testing.assert_array_equal(result.continuous.switch_times, before_cont.switch_times)
    assert result.continuous.duration == before_cont.duration
    np.testing.assert_array_equal(result.sampled.commands, before.commands)
    assert result.sampled.final_state_error_relative == before.final_state_error_relative
    assert result.problem is problem and result.sampled.problem is problem


def test_fixed_time_plan_builds_the_response_once(monkeypatch):
    problem = rest_to_rest(MODEL, 1.0, 0.7)
    before_cont = plan_fixed_time(problem, 2.5)
    before = plan_fixed_time_zoh(problem, before_cont.duration, RATE, before_cont)
    count = _count_full_model_responses(monkeypatch)
    cfg = PlannerConfig(model=MODEL, u_max=1.0, method="fixed_time", options={"arrival_time": 2.5})
    result = plan_move(cfg, problem, RATE)
    assert count[0] == 1
    np.testing.assert_array_equal(result.continuous.switch_times, before_cont.switch_times)
    np.testing.assert_array_equal(result.continuous.levels, before_cont.levels)
    np.testing.assert_array_equal(result.sampled.commands, before.commands)
    assert result.info["time_optimal_duration"] == before_cont.extra["time_optimal_duration"]


@pytest.mark.parametrize("rate", [-1.0, float("nan"), 2.0e6])
def test_plan_move_validates_the_rate_once(rate):
    with pytest.raises(ConfigError) as exc:
        plan_move(PlannerConfig(model=MODEL, u_max=1.0), rest_to_rest(MODEL, 1.0, 0.7), rate)
    assert exc.value.parameter == "rate_hz" and "(0, 1e6] Hz" in exc.value.reason
