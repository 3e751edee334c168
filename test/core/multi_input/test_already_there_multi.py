"""Near-zero moves with several inputs (issue 15.1 on the planner of issue 12): "already there" or planned.

The single-input rule (``core/methods/already_there.py``) on the multi-input
path: a goal within the resolution of the current state (the state within
``FINAL_STATE_RTOL`` of the targets' rest state relative to one sample's
reach), a goal equal to the current position re-sent at rest (a few ulps
off) and a stop from a state moving at 1e-18 are the ``m``-input hold: zero
samples ``(0, m)``, zero duration, certified, for every multi-input method.
The state is checked here by our own ``scipy.linalg.expm`` (the reach of one
sample of every input at its bound).  Before this rule (checked against main
2b3dc69), ``--goal 1e-15,0 --rate 200`` on the gantry planned a 0.53 ms
bang-bang move (4 switches at +-300 N, 4 samples) and ``--goal 1e-15`` on the
two-drive chain raised ``SolverError`` ("no extremal converged").

Moves just above the resolution (1e-9, 1e-6 m) are real moves: planned (each
sequence checked by our own expm) or refused with a :class:`FlexmotionError`,
never a crash.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm

from flexmotion_ros.core.errors import FlexmotionError
from flexmotion_ros.core.multi_input.config import MultiPlannerConfig
from flexmotion_ros.core.multi_input.dispatch import load_any_config, plan
from flexmotion_ros.core.multi_input.methods import MULTI_METHODS, plan_multi_move
from flexmotion_ros.core.multi_input.problem import multi_state_to_rest
from flexmotion_ros.core.tolerances import FINAL_STATE_RTOL

from . import independent as ind

# the shipped multi-input configs (gantry, chain): every config/*.yaml that loads as a MultiPlannerConfig
CONFIGS = [
    p
    for p in sorted((Path(__file__).resolve().parents[3] / "config").glob("*.yaml"))
    if isinstance(load_any_config(p), MultiPlannerConfig)
]
assert {p.stem for p in CONFIGS} >= {"gantry", "chain_two_drives"}, CONFIGS

#: The options each method requires, set to plain values.
OPTIONS = {"fixed_time": {"arrival_time": 1.0}, "min_fuel": {"move_time": 1.0}}


def config_for(path: Path, method: str) -> MultiPlannerConfig:
    return replace(load_any_config(path), method=method, options=OPTIONS.get(method, {}))


def one_sample_reach(problem, dt: float) -> np.ndarray:
    """How far every input at its bound moves each kept state within one sample ``dt`` (own expm, 16 instants)."""
    A, B, _ = ind.reduced(problem)
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = A, B
    reach = np.zeros(n)
    for tau in np.linspace(dt / 16.0, dt, 16):
        reach = np.maximum(reach, np.abs(expm(M * tau)[:n, n:]) @ np.asarray(problem.u_max, float))
    return reach


def assert_already_there(problem, result, rate: float) -> None:
    m = problem.model.m
    assert result.info.get("already_there") is True, result.info
    cont = result.continuous
    assert cont is not None and cont.duration == 0.0 and cont.certified, cont
    assert "already there" in cont.certificate.message
    assert all(np.all(lv == 0.0) for lv in cont.levels)  # the hold on every input
    s = result.sampled
    assert s is not None and s.samples == 0 and s.commands.shape == (0, m) and s.minimal
    assert s.dt == pytest.approx(1.0 / rate)
    # our own check: the shifted state (free positions dropped) within the tolerance of one sample's reach,
    # or a difference of rounding (4 ulps) only
    _, _, dev = ind.reduced(problem)
    target = np.array([0.0 if t is None else t for t in problem.targets])
    full_target = np.zeros(problem.model.n_states)
    full_target[0 : 2 * problem.model.k : 2] = target
    size = np.maximum(np.abs(problem.x0), np.abs(full_target))[problem.kept]
    reach = one_sample_reach(problem, 1.0 / rate)
    there = (np.abs(dev) <= 1.01 * FINAL_STATE_RTOL * reach) | (np.abs(dev) <= 4 * np.finfo(float).eps * size)
    assert np.all(there), (dev, reach)


@pytest.mark.parametrize("path", CONFIGS, ids=[p.stem for p in CONFIGS])
@settings(max_examples=6, deadline=None)
@given(
    method=st.sampled_from(MULTI_METHODS),
    position=st.floats(-3.0, 3.0, allow_subnormal=False),
    ulps=st.integers(-4, 4),
    rate=st.sampled_from([100.0, 200.0, 1000.0]),
)
def test_a_goal_at_the_current_position_is_already_there(path, method, position, ulps, rate):
    """A goal re-sent at rest (a few ulps off, on every rigid body) is the hold, for every method and config."""
    config = config_for(path, method)
    model = config.model
    goal = position
    for _ in range(abs(ulps)):
        goal = math.nextafter(goal, math.copysign(math.inf, ulps))
    problem = multi_state_to_rest(model, config.u_max, model.rest_state([position] * model.k), [goal] * model.k)
    assert_already_there(problem, plan(config, problem, rate), rate)


@pytest.mark.parametrize("method", MULTI_METHODS)
@pytest.mark.parametrize("path", CONFIGS, ids=[p.stem for p in CONFIGS])
def test_a_femtometre_goal_and_a_stop_from_1e_18_are_already_there(path, method):
    """``--goal 1e-15,0 --rate 200`` (the issue's reproducer), and a stop from 1e-18 m/s."""
    config = config_for(path, method)
    model = config.model
    goal = [1e-15] + [0.0] * (model.k - 1)
    problem = multi_state_to_rest(model, config.u_max, model.rest_state(), goal)
    assert_already_there(problem, plan(config, problem, 200.0), 200.0)
    x0 = model.rest_state()
    x0[1] = 1e-18
    stop = multi_state_to_rest(model, config.u_max, x0, None)
    assert_already_there(stop, plan(config, stop, 200.0), 200.0)


@pytest.mark.parametrize("path", CONFIGS, ids=[p.stem for p in CONFIGS])
def test_without_a_rate_the_resolution_is_the_configured_rate(path):
    """No rate: judged at ``config.rate_hz`` (the node's), as for one input; ``plan_multi_move`` at a rate too."""
    config = config_for(path, "time_optimal")
    model = config.model
    problem = multi_state_to_rest(model, config.u_max, model.rest_state([2.0] * model.k), [2.0] * model.k)
    result = plan(config, problem, None)
    assert result.info.get("already_there") is True and result.continuous.duration == 0.0
    assert result.continuous.certified and result.sampled is None  # no rate: no sampled plan asked for
    nudged = [math.nextafter(2.0, 3.0)] + [2.0] * (model.k - 1)
    direct = plan_multi_move(
        multi_state_to_rest(model, config.u_max, model.rest_state([2.0] * model.k), nudged), rate_hz=200.0
    )
    assert direct.info.get("already_there") is True and direct.sampled.samples == 0


@pytest.mark.parametrize("goal", [1e-9, 1e-6])
@pytest.mark.parametrize("path", CONFIGS, ids=[p.stem for p in CONFIGS])
def test_tiny_real_moves_are_planned_exactly_or_refused(path, goal):
    """Just above the resolution, every method: a plan checked by our own expm, or a FlexmotionError."""
    for method in MULTI_METHODS:
        config = config_for(path, method)
        model = config.model
        problem = multi_state_to_rest(model, config.u_max, model.rest_state(), [goal] + [0.0] * (model.k - 1))
        try:
            result = plan(config, problem, 200.0)
        except FlexmotionError:
            continue  # refused with a reason: allowed (a crash is not)
        assert not result.info.get("already_there")
        s = result.sampled
        assert s.samples >= 1 and np.all(np.abs(s.commands) <= np.asarray(config.u_max))
        xK = ind.final_state(problem, s.dt * np.arange(s.samples + 1), s.commands)
        if method.startswith("ei"):  # a designed residual vibration: the rigid bodies arrive exactly
            xK = xK[: 2 * model.k]
        scale = np.maximum(np.abs(ind.reduced(problem)[2]), one_sample_reach(problem, s.duration))
        assert np.max(np.abs(xK) / scale[: xK.size]) <= 1e-8, (method, xK)
