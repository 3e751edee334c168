"""The one error hierarchy: a root, input errors that name their parameter, solver errors."""

import pytest

from flexmotion_ros.core import ModalModel, PlannerConfig, rest_to_rest
from flexmotion_ros.core.errors import (
    ConfigError,
    FlexmotionError,
    GoalError,
    InputError,
    ModelError,
    SolverError,
    UnreachableError,
)
from flexmotion_ros.core.methods import plan_move


@pytest.mark.parametrize("cls", [InputError, ModelError, GoalError, ConfigError])
def test_input_errors_name_the_parameter_and_are_value_errors(cls):
    exc = cls("u_max", "must be > 0 N, got -1")
    assert isinstance(exc, FlexmotionError) and isinstance(exc, ValueError) and not isinstance(exc, RuntimeError)
    assert (exc.parameter, exc.reason, str(exc)) == ("u_max", "must be > 0 N, got -1", "u_max: must be > 0 N, got -1")


@pytest.mark.parametrize("cls", [SolverError, UnreachableError])
def test_solver_errors_are_runtime_errors_under_the_same_root(cls):
    exc = cls("limited planner: no 12-sample sequence reaches the target")
    assert isinstance(exc, FlexmotionError) and isinstance(exc, RuntimeError) and not isinstance(exc, ValueError)
    assert not isinstance(exc, InputError)


def test_one_except_catches_bad_input_and_solver_failures():
    model = ModalModel(b0=1.0, omega=[2.0], zeta=[0.0], b=[1.0])
    with pytest.raises(FlexmotionError):
        ModalModel(b0=1.0, omega=[-2.0], zeta=[0.0], b=[1.0])
    with pytest.raises(FlexmotionError):
        plan_move(PlannerConfig(model=model, method="fixed_time"), rest_to_rest(model, 1.0, 1.0))
    with pytest.raises(ConfigError, match="^arrival_time: required by method fixed_time"):
        plan_move(PlannerConfig(model=model, method="fixed_time"), rest_to_rest(model, 1.0, 1.0))


def test_a_bound_violation_is_a_solver_fault_not_bad_input(monkeypatch):
    from flexmotion_ros.core.methods import table

    model = ModalModel(b0=1.0, omega=[2.0], zeta=[0.0], b=[1.0])
    cfg = PlannerConfig(model=model)
    real = table.METHODS["time_optimal"]

    def over_the_bound(config, problem, rate_hz):
        result = real.planner(config, problem, rate_hz)
        result.sampled.commands[0] = 1.5 * problem.u_max
        return result

    monkeypatch.setitem(
        table.METHODS, "time_optimal", table.Method(name="time_optimal", description="", planner=over_the_bound)
    )
    with pytest.raises(SolverError, match="u_max"):
        plan_move(cfg, rest_to_rest(model, 1.0, 1.0), 100.0)
