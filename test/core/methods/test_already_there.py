"""Near-zero moves (issue 16.1): every method, every shipped config, answered "already there" or planned.

A move shorter than the resolution (the state within ``FINAL_STATE_RTOL`` of
the target's rest state relative to one sample's reach) is the hold: zero
samples, zero duration, certified, and the state checked here by our own
``scipy.linalg.expm`` (:func:`reference_solutions.one_sample_reach`).  A goal
equal to the current position re-sent at rest (a few ulps off) is such a
move.  Before this fix, ``--goal 1e-15 --rate 200`` on the 3-mode beam raised
``IndexError`` in the ZOH least-norm solver (checked against 4d66c99), and
the friction example refused every goal <= 1e-6.

Moves just above the resolution are real moves: planned (each plan checked by
our own expm) or refused with a :class:`FlexmotionError`, never a crash.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from reference_solutions import one_sample_reach, sampled_final_error

from flexmotion_ros.core.config import PlannerConfig, load_config
from flexmotion_ros.core.methods.table import METHODS, plan_move
from flexmotion_ros.core.model.boundary import state_to_rest
from flexmotion_ros.core.multi_input.dispatch import load_any_config
from flexmotion_ros.core.sampled.zoh import plan_time_optimal_zoh
from flexmotion_ros.core.tolerances import FINAL_STATE_RTOL

# the single-input configs (the multi-input ones, gantry and chain, plan through core.multi_input: their
# near-zero moves are tested in test/core/multi_input)
CONFIGS = [
    p
    for p in sorted((Path(__file__).resolve().parents[3] / "config").glob("*.yaml"))
    if isinstance(load_any_config(p), PlannerConfig)
]
assert len(CONFIGS) >= 5, CONFIGS  # the shipped single-input configs are found


def options_for(method: str, u_max: float) -> dict:
    """The options a method requires, set to plain values."""
    return {
        "time_optimal_friction": {"coulomb_force": 0.2 * u_max},
        "fixed_time": {"arrival_time": 5.0},
        "limited": {"limits.velocity_max": 1.0},
    }.get(method, {})


def config_for(path: Path, method: str) -> PlannerConfig:
    base = load_config(path)
    return PlannerConfig(model=base.model, u_max=base.u_max, method=method, options=options_for(method, base.u_max))


def assert_already_there(problem, result, rate: float) -> None:
    assert result.info.get("already_there") is True
    assert result.continuous.duration == 0.0 and result.continuous.certified
    assert result.sampled is not None and result.sampled.samples == 0
    x0 = np.asarray(problem.x0, float)
    target = problem.model.rest_state(problem.target if problem.target is not None else 0.0)
    dev, size = x0 - target, np.maximum(np.abs(x0), np.abs(target))
    if problem.target is None:
        dev, size = dev[1:], size[1:]
    reach = one_sample_reach(problem, 1.0 / rate)
    # below the tolerance of one sample's reach, or a difference of rounding (4 ulps) only
    there = (np.abs(dev) <= 1.01 * FINAL_STATE_RTOL * reach) | (np.abs(dev) <= 4 * np.finfo(float).eps * size)
    assert np.all(there), (dev, reach)


@pytest.mark.parametrize("path", CONFIGS, ids=[p.stem for p in CONFIGS])
@settings(max_examples=8)
@given(
    method=st.sampled_from(list(METHODS)),
    position=st.floats(-3.0, 3.0, allow_subnormal=False),
    ulps=st.integers(-4, 4),
    rate=st.sampled_from([100.0, 200.0, 1000.0]),
)
def test_a_goal_at_the_current_position_is_already_there(path, method, position, ulps, rate):
    """A goal re-sent at rest (the move is a few ulps) is the hold, for every method and config."""
    config = config_for(path, method)
    model = config.model
    goal = position
    for _ in range(abs(ulps)):
        goal = math.nextafter(goal, math.copysign(math.inf, ulps))
    problem = state_to_rest(model, config.u_max, model.rest_state(position), goal)
    result = plan_move(config, problem, rate)
    assert_already_there(problem, result, rate)


@pytest.mark.parametrize("method", list(METHODS))
@pytest.mark.parametrize("path", CONFIGS, ids=[p.stem for p in CONFIGS])
def test_a_femtometre_goal_is_already_there(path, method):
    """``--goal 1e-15 --rate 200`` (the issue's CLI reproducer), and a stop from 1e-18 m/s."""
    config = config_for(path, method)
    model = config.model
    problem = state_to_rest(model, config.u_max, np.zeros(model.n_states), 1e-15)
    assert_already_there(problem, plan_move(config, problem, 200.0), 200.0)
    x0 = np.zeros(model.n_states)
    x0[1] = 1e-18
    stop = state_to_rest(model, config.u_max, x0, None)
    assert_already_there(stop, plan_move(config, stop, 200.0), 200.0)


def test_the_sampled_planner_itself_plans_a_move_of_fewer_samples_than_states():
    """``plan_time_optimal_zoh`` called directly (no 'already there' in front): IndexError before the fix."""
    config = load_config(CONFIGS[0].with_name("flexible_beam_3mode.yaml"))
    problem = state_to_rest(config.model, config.u_max, np.zeros(config.model.n_states), 1e-15)
    sampled = plan_time_optimal_zoh(problem, 200.0)
    assert np.max(np.abs(sampled.commands)) <= config.u_max
    assert sampled_final_error(problem, sampled.commands, sampled.dt, reach=True) <= 1e-8


@pytest.mark.parametrize("path", CONFIGS, ids=[p.stem for p in CONFIGS])
@pytest.mark.parametrize("goal", [1e-12, 1e-9, 1e-6])
def test_tiny_real_moves_are_planned_exactly(path, goal):
    """Just above the resolution: a plan, checked by our own expm, for the time-optimal, shaper and robust methods.

    (Friction's small moves are its planner's, issue 18: today it refuses
    them after seconds, "continuation ... stalled"; not tested here.)
    """
    for method in ("time_optimal", "zv", "robust_time_optimal"):
        config = config_for(path, method)
        problem = state_to_rest(config.model, config.u_max, np.zeros(config.model.n_states), goal)
        result = plan_move(config, problem, 200.0)
        assert np.max(np.abs(result.sampled.commands), initial=0.0) <= config.u_max
        assert sampled_final_error(problem, result.sampled.commands, result.sampled.dt, reach=True) <= 1e-8


@pytest.mark.parametrize("path", CONFIGS, ids=[p.stem for p in CONFIGS])
def test_a_stop_just_before_a_move_ends_is_planned_exactly(path):
    """A stop from 1..30 samples before the end of a move (issue 16.1: 0.25-2.5 s and one refusal on 4d66c99).

    Planned sampled-first when the remaining move is a few samples: the count
    is proved fewest (``minimal``); each sequence checked by our own expm.
    """
    config = config_for(path, "time_optimal")
    model = config.model
    move = plan_move(config, state_to_rest(model, config.u_max, np.zeros(model.n_states), 0.5), 200.0).sampled
    for back in (1, 3, 5, 10, 30):
        stop = state_to_rest(model, config.u_max, move.states[move.samples - back], None)
        s = plan_move(config, stop, 200.0).sampled
        assert s.samples <= back and s.minimal
        assert np.max(np.abs(s.commands), initial=0.0) <= config.u_max
        assert sampled_final_error(stop, s.commands, s.dt, reach=True) <= 1e-8
