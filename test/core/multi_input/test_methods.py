"""Other methods on multi-input models: shapers on every input, fixed arrival time, weighted minimum fuel,
and clear refusals; checked by independent expm simulation and an independent LP."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog

from flexmotion_ros.core.errors import ConfigError, GoalError, InputError
from flexmotion_ros.core.multi_input import multi_rest_to_rest, multi_state_to_rest, plan_multi_time_optimal
from flexmotion_ros.core.multi_input.builders import gantry, multi_chain
from flexmotion_ros.core.multi_input.methods import REFUSED, plan_multi_move

from . import independent as ind

GANTRY = gantry(10.0, 40.0, 5.0, 2.0, trolley_force=30.0, bridge_force=50.0)


def gantry_move():
    return multi_rest_to_rest(GANTRY.model, GANTRY.u_max, [3.0, 2.0])


@pytest.mark.parametrize("method", ["zv", "zvd", "mzv"])
def test_zero_vibration_shapers_on_every_input_leave_every_mode_at_rest(method):
    p = gantry_move()
    r = plan_multi_move(p, method, rate_hz=20.0)
    u = r.continuous.input()
    xT = ind.final_state(p, u.breaks, u.levels)
    assert ind.relative_error(p, xT, r.continuous.duration, p.u_max) < 1e-9
    assert np.all(np.abs(u.levels) <= p.u_max)
    assert r.continuous.duration > plan_multi_time_optimal(p).duration
    assert not r.continuous.certified  # no optimality claim
    sp = r.sampled
    xK = ind.final_state(p, sp.dt * np.arange(sp.samples + 1), sp.commands)
    assert ind.relative_error(p, xK, sp.duration, p.u_max) < 1e-9
    assert np.all(np.abs(sp.commands) <= p.u_max)


def test_coupled_modes_cancelled_by_one_shaper_whatever_b_is():
    c = multi_chain([1.0, 0.8, 1.2], [60.0, 80.0], [0.0, 0.0], actuated=(0, 2), u_max=[5.0, 3.0])
    p = multi_rest_to_rest(c.model, c.u_max, [0.5])
    r = plan_multi_move(p, "zvd")
    u = r.continuous.input()
    xT = ind.final_state(p, u.breaks, u.levels)
    assert ind.relative_error(p, xT, r.continuous.duration, p.u_max) < 1e-9


def test_ei_reaches_the_rigid_targets_and_reports_its_designed_residual():
    p = gantry_move()
    r = plan_multi_move(p, "ei")
    u = r.continuous.input()
    xT = ind.final_state(p, u.breaks, u.levels)
    assert np.max(np.abs(xT[:4])) < 1e-9  # rigid bodies exactly at rest at the targets (shifted state)
    M = GANTRY.model
    w = np.asarray(M.omega)
    amp = np.hypot(xT[4::2], xT[5::2] / w)  # undamped modes
    assert np.allclose(amp, r.continuous.extra["residual_amplitude"], rtol=1e-6, atol=1e-15)


def test_shapers_need_rest_at_the_start():
    x0 = np.zeros(8)
    x0[1] = 0.2
    with pytest.raises(GoalError) as err:
        plan_multi_move(multi_state_to_rest(GANTRY.model, GANTRY.u_max, x0, [3.0, 2.0]), "zvd")
    assert err.value.parameter == "initial_state"


def test_fixed_time_every_axis_arrives_then_at_its_lowest_peak():
    p = gantry_move()
    T_star = plan_multi_time_optimal(p).duration
    r = plan_multi_move(p, "fixed_time", rate_hz=20.0, options={"arrival_time": 5.0})
    prof = r.continuous
    assert prof.duration == 5.0 and prof.certified, prof.certificate.message
    u = prof.input()
    xT = ind.final_state(p, u.breaks, u.levels)
    assert ind.relative_error(p, xT, 5.0, p.u_max) < 1e-9
    for part in prof.certificate.parts:
        assert part["role"] == "lowest_peak" and part["peak_fraction"] < 1.0
        assert part["peak_lower_bound"] >= part["peak_fraction"] * (1 - 1e-8)
    assert r.sampled.samples == 100
    with pytest.raises(InputError) as err:
        plan_multi_move(p, "fixed_time", options={"arrival_time": 0.9 * T_star})
    assert err.value.parameter == "arrival_time"


def test_min_fuel_with_per_input_weights_against_an_independent_lp():
    p = gantry_move()
    weights = [1.0, 3.0]
    r = plan_multi_move(p, "min_fuel", rate_hz=10.0, options={"move_time": 5.0}, fuel_weights=weights)
    sp = r.sampled
    assert sp.samples == 50
    xK = ind.final_state(p, sp.dt * np.arange(sp.samples + 1), sp.commands)
    assert ind.relative_error(p, xK, sp.duration, p.u_max) < 1e-9
    assert np.all(np.abs(sp.commands) <= p.u_max)
    fuel = float(np.sum(np.abs(sp.commands) @ np.array(weights)) * sp.dt)
    assert np.isclose(fuel, sp.extra["fuel"], rtol=1e-9)
    # the same LP, built here from scipy's expm and solved by interior point
    A, B, x0 = ind.reduced(p)
    from scipy.linalg import expm

    n, m = B.shape
    dt, K = sp.dt, sp.samples
    Maug = np.zeros((n + m, n + m))
    Maug[:n, :n], Maug[:n, n:] = A, B
    gam = expm(Maug * dt)[:n, n:]
    E = expm(A * dt)
    cols = [np.linalg.matrix_power(E, K - 1 - k) @ gam for k in range(K)]  # forward sample k
    Aeq = np.concatenate([np.stack([c[:, i] for c in cols], axis=1) for i in range(m)], axis=1)
    cost = np.repeat(np.array(weights) * dt, K)
    ub = np.repeat(p.u_max, K)
    res = linprog(
        np.concatenate([cost, cost]),
        A_eq=np.hstack([Aeq, -Aeq]),
        b_eq=-(expm(A * K * dt) @ x0),
        bounds=list(zip(np.zeros(2 * m * K), np.concatenate([ub, ub]))),
        method="highs-ipm",
    )
    assert res.status == 0
    assert abs(res.fun - fuel) <= 1e-6 * fuel
    # coupled inputs: a heavier weight on one input never raises its fuel (LP sensitivity:
    # (c' - c) . (x' - x) <= 0), and here lowers it
    c = multi_chain([1.0, 0.8, 1.2], [60.0, 80.0], [0.1, 0.1], actuated=(0, 2), u_max=[5.0, 5.0])
    pc = multi_rest_to_rest(c.model, c.u_max, [0.5])
    T = 1.3 * plan_multi_time_optimal(pc).duration
    used = []
    for wts in ([1.0, 1.0], [1.0, 4.0]):
        rc = plan_multi_move(pc, "min_fuel", rate_hz=50.0, options={"move_time": T}, fuel_weights=wts)
        assert rc.sampled.extra["fuel_certified"]
        used.append(float(np.sum(np.abs(rc.sampled.commands[:, 1]))))
    assert used[1] < used[0]
    with pytest.raises(InputError) as err:
        plan_multi_move(p, "min_fuel", rate_hz=10.0, options={"move_time": 1.0})
    assert err.value.parameter == "move_time"


@pytest.mark.parametrize("method", sorted(REFUSED))
def test_methods_without_a_multi_input_version_are_refused_with_the_reason(method):
    with pytest.raises(ConfigError) as err:
        plan_multi_move(gantry_move(), method)
    assert err.value.parameter == "method" and method in str(err.value) and "one input" in str(err.value)


def test_unknown_method_and_sync():
    with pytest.raises(ConfigError) as err:
        plan_multi_move(gantry_move(), "bang")
    assert err.value.parameter == "method"
    with pytest.raises(ConfigError) as err:
        plan_multi_move(gantry_move(), sync="together")
    assert err.value.parameter == "sync"


def test_summary_json_layout():
    r = plan_multi_move(gantry_move(), rate_hz=20.0)
    s = r.summary()
    for key in (
        "duration",
        "switch_times",
        "levels",
        "final_state_error",
        "certified",
        "solve_time_s",
        "sync",
        "samples",
        "commands",
    ):
        assert key in s
    assert len(s["levels"]) == len(s["switch_times"]) + 1 and all(len(row) == 2 for row in s["levels"])
    assert len(s["commands"]) == s["samples"] and all(len(row) == 2 for row in s["commands"])
    import json

    json.dumps(s)


@pytest.mark.parametrize(
    ("method", "options"),
    [("time_optimal", {}), ("zvd", {}), ("fixed_time", {"arrival_time": 2.0}), ("min_fuel", {"move_time": 2.0})],
)
def test_every_method_at_rest_and_with_one_axis_at_rest(method, options):
    at_rest = multi_rest_to_rest(GANTRY.model, GANTRY.u_max, [0.0, 0.0])
    r = plan_multi_move(at_rest, method, rate_hz=50.0, options=options)
    assert np.all(r.sampled.commands == 0.0)
    assert r.continuous is None or r.continuous.duration in (0.0, 2.0)  # fixed_time: at rest until 2 s
    one = multi_rest_to_rest(GANTRY.model, GANTRY.u_max, [0.5, 0.0])
    r = plan_multi_move(one, method, rate_hz=50.0, options=options)
    xK = ind.final_state(one, r.sampled.dt * np.arange(r.sampled.samples + 1), r.sampled.commands)
    assert ind.relative_error(one, xK, r.sampled.duration, one.u_max) < 1e-9
    assert np.max(np.abs(r.sampled.commands[:, 1])) <= 1e-12 * GANTRY.u_max[1]  # the bridge has nothing to do
