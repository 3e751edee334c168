"""The measured state, ROS-free: settings, the state vector from joint names, staleness on a fake clock."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from flexmotion_ros.core.errors import ConfigError, GoalError
from flexmotion_ros.core.model.modal_model import ModalModel
from flexmotion_ros.execution.measured_state import (
    EarlyArrival,
    MeasuredState,
    StateSource,
    at_rest,
    state_settings,
    state_vector,
)


class FakeClock:
    def __init__(self) -> None:
        self.t = 10.0

    def __call__(self) -> float:
        return self.t


NAMES = ["rigid_body", "mode_1", "mode_2"]


def test_defaults_are_safe():
    s = state_settings({})
    assert s.source is StateSource.MEASURED and s.timeout_s == 0.5 and s.topic == "joint_states"
    assert s.early_arrival is EarlyArrival.REFUSE
    assert s.state_joint_names(2) == NAMES


def test_custom_joint_names():
    s = state_settings({"joint_name": "x", "state.mode_joint_names": ["a", "b"]})
    assert s.state_joint_names(2) == ["x", "a", "b"]
    with pytest.raises(GoalError, match=r"state.mode_joint_names: names 2 joint\(s\) but the model has 3 mode"):
        s.state_joint_names(3)


@pytest.mark.parametrize(
    "values, words",
    [
        (
            {"state.source": "measure"},
            "state.source: must be one of ['measured', 'assumed'], got 'measure' (closest: 'measured')",
        ),
        ({"state.timeout_s": 0.0}, "state.timeout_s: must be in (0, 3600] s, got 0.0"),
        ({"state.timeout_s": float("nan")}, "state.timeout_s: must be in (0, 3600] s"),
        ({"state.timeout_s": "soon"}, "state.timeout_s: must be a number of seconds"),
        ({"state.topic": " "}, "state.topic: must be a topic name"),
        ({"joint_name": ""}, "joint_name: must be a joint name"),
        ({"state.mode_joint_names": ["rigid_body"]}, "state.mode_joint_names: joint names must differ"),
        ({"trajectory.early_arrival": "late"}, "trajectory.early_arrival: must be one of ['refuse', 'optimum']"),
    ],
)
def test_bad_settings_name_the_parameter(values, words):
    with pytest.raises(ConfigError) as exc:
        state_settings(values)
    assert words in str(exc.value)


def test_state_vector_by_name_in_any_order():
    x = state_vector(NAMES, ["mode_2", "rigid_body", "mode_1", "other"], [3.0, 1.0, 2.0, 9.0], [30.0, 10.0, 20.0, 9.0])
    np.testing.assert_array_equal(x, [1.0, 10.0, 2.0, 20.0, 3.0, 30.0])


def test_state_vector_refuses_a_missing_joint_with_the_closest_name():
    with pytest.raises(GoalError, match=r"joint 'mode_2' missing .* \(closest: 'mode_3'\)"):
        state_vector(NAMES, ["rigid_body", "mode_1", "mode_3"], [0.0] * 3, [0.0] * 3)
    with pytest.raises(GoalError, match="has no position and velocity"):
        state_vector(NAMES, NAMES, [0.0] * 3, [0.0] * 2)
    with pytest.raises(GoalError, match="not finite"):
        state_vector(NAMES, NAMES, [0.0, float("nan"), 0.0], [0.0] * 3)


def test_missing_then_fresh_then_stale():
    clock = FakeClock()
    store = MeasuredState(clock)
    with pytest.raises(GoalError, match=r"^state.source: no measured state: nothing received on 'js'"):
        store.fresh(NAMES, 0.5, "js", wait=False)
    store.update(NAMES, [1.0, 2.0, 3.0], [0.1, 0.2, 0.3])
    clock.t += 0.5  # exactly the timeout: still fresh
    np.testing.assert_array_equal(store.fresh(NAMES, 0.5, "js", wait=False), [1.0, 0.1, 2.0, 0.2, 3.0, 0.3])
    clock.t += 0.01
    with pytest.raises(GoalError, match=r"^state.timeout_s: measured state on 'js' is stale: last received 0.51 s ago"):
        store.fresh(NAMES, 0.5, "js", wait=False)
    assert store.age() == pytest.approx(0.51) and store.received == 1


def test_a_goal_waits_for_the_next_message():
    store = MeasuredState()  # the real monotonic clock
    timer = threading.Timer(0.05, store.update, args=(NAMES, [4.0, 0.0, 0.0], [0.0, 0.0, 0.0]))
    timer.start()
    try:
        x = store.fresh(NAMES, 2.0, "js")
    finally:
        timer.cancel()
    assert x[0] == 4.0


def test_at_rest_judges_speed_and_every_modal_amplitude():
    model = ModalModel(b0=1.0, omega=(5.0, 13.0), zeta=(0.01, 0.02), b=(1.0, -0.7))
    x = model.rest_state(3.0)
    assert at_rest(model, x)
    assert not at_rest(model, x + np.array([0, 1e-6, 0, 0, 0, 0]))
    assert not at_rest(model, x + np.array([0, 0, 0, 0, 0, 1e-6]))  # the second mode swings
    assert at_rest(model, x + np.array([0, 1e-12, 1e-12, 0, 0, 0]))


def test_after_its_own_move_the_planner_waits_for_the_state_it_predicted():
    """Just after a move, the latest message may predate its end: wait (up to the timeout) for the predicted state."""
    store = MeasuredState()
    end = np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    store.update(NAMES, [0.99, 0.0, 0.0], [0.2, 0.0, 0.0])  # in flight from before the end: still moving
    timer = threading.Timer(0.05, store.update, args=(NAMES, [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]))
    timer.start()
    try:
        x = store.fresh(NAMES, 2.0, "js", expect=end)
    finally:
        timer.cancel()
    np.testing.assert_array_equal(x, end)
    # the machine is elsewhere (model error, friction): after the timeout the measurement is the truth
    clock = FakeClock()
    store = MeasuredState(clock)
    store.update(NAMES, [0.9, 0.0, 0.0], [0.1, 0.0, 0.0])
    x = store.fresh(NAMES, 0.5, "js", wait=False, expect=end)
    assert x[0] == 0.9 and x[1] == 0.1
