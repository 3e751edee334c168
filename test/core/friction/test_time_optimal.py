"""Coulomb friction: exact piecewise simulation and time-optimal moves (seed eqs. 2.8-2.11).

References are independent of the simulator under test: a closed-form
event-by-event solution of the rigid body with friction, and event-located
``scipy.integrate.solve_ivp`` runs with very tight tolerances (a cross-check
of the matrix-exponential method, not the reference for the planners, which
are checked with the exact simulator).
"""

import copy
import json
import math
import subprocess
import sys
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from flexmotion_ros.core import (
    ModalModel,
    MoveProblem,
    PiecewiseConstant,
    PlannerConfig,
    config_from_parameters,
    rest_to_rest,
    simulate,
    two_mass,
)
from flexmotion_ros.core.errors import FlexmotionError, SolverError
from flexmotion_ros.core.friction import profile as profile_mod
from flexmotion_ros.core.friction import zoh as zoh_mod
from flexmotion_ros.core.friction.certificate import CLAIM, FrictionStatus
from flexmotion_ros.core.friction.contact import FrictionSystem, simulate_contact, simulate_coulomb
from flexmotion_ros.core.friction.contact_model import contact_at_coordinate, rigid_contact
from flexmotion_ros.core.friction.lower_bound import rigid_friction_time
from flexmotion_ros.core.friction.pattern_search import fastest_samples
from flexmotion_ros.core.friction.profile import sampled_profile
from flexmotion_ros.core.friction.sampled_lp import FrictionLP
from flexmotion_ros.core.friction.time_optimal import plan_time_optimal_friction
from flexmotion_ros.core.friction.zoh import plan_time_optimal_friction_zoh
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.time_optimal.solver import plan_time_optimal

WB = ModalModel(b0=0.5, c=0.0, omega=[math.sqrt(2.0)], zeta=[0.0], b=[1.0])


# ------------------------------------------------------------ references
def rigid_reference(b0: float, F: float, p: float, v: float, u: PiecewiseConstant) -> np.ndarray:
    """Closed-form rigid body with Coulomb friction (c = 0), states at ``u.breaks``."""
    out = [(p, v)]
    a_f = abs(b0) * F
    for k, level in enumerate(u.levels):
        left = u.breaks[k + 1] - u.breaks[k]
        while left > 0.0:
            if v == 0.0:
                if abs(level) <= F:
                    break  # stuck for the rest of the piece
                s = math.copysign(1.0, b0 * level)
            else:
                s = math.copysign(1.0, v)
            acc = b0 * level - a_f * s
            t_stop = -v / acc if acc * s < 0.0 and v != 0.0 else math.inf
            h = min(left, t_stop)
            p += v * h + 0.5 * acc * h * h
            v = 0.0 if h == t_stop else v + acc * h
            left -= h
        out.append((p, v))
    return np.array(out)


def ivp_modal_friction(model: ModalModel, F: float, x0, u: PiecewiseConstant) -> np.ndarray:
    """Event-located solve_ivp of the modal model with friction on the rigid body, states at breaks."""
    A, B = model.A(), model.B()
    af = abs(model.b0) * F
    x = np.array(x0, float)
    out = [x.copy()]
    for k, level in enumerate(u.levels):
        t, t_end = u.breaks[k], u.breaks[k + 1]
        while t < t_end:
            if x[1] == 0.0 and abs(level) <= F:  # stuck: rigid body held, modes free

                def rhs(_, z, level=level):
                    d = A @ z + B * level
                    d[:2] = 0.0
                    return d

                sol = solve_ivp(rhs, (t, t_end), x, method="DOP853", rtol=1e-12, atol=1e-14)
                x = sol.y[:, -1]
                t = t_end
                continue
            s = math.copysign(1.0, x[1]) if x[1] != 0.0 else math.copysign(1.0, model.b0 * level)

            def rhs(_, z, level=level, s=s):
                d = A @ z + B * level
                d[1] -= af * s
                return d

            def stop(_, z, s=s):
                return z[1] * s

            stop.terminal = True
            stop.direction = -1
            sol = solve_ivp(rhs, (t, t_end), x, method="DOP853", rtol=1e-12, atol=1e-14, events=stop)
            x = sol.y[:, -1].copy()
            if sol.status == 1:  # velocity reached zero
                t = float(sol.t_events[0][0])
                x = sol.y_events[0][0].copy()
                x[1] = 0.0  # the next pass sticks or slides on, by |u| against F
            else:
                t = t_end
        out.append(x.copy())
    return np.array(out)


def ivp_two_mass_friction(m1, m2, k, d, F, x0, u: PiecewiseConstant) -> np.ndarray:
    """Physical two-mass system, friction on mass 1, stick-slip by events; states at breaks."""
    x = np.array(x0, float)  # [x1, v1, x2, v2]
    out = [x.copy()]

    def applied(z, level):  # net force on mass 1 with v1 = 0
        return level - k * (z[0] - z[2]) + d * z[3]

    for j, level in enumerate(u.levels):
        t, t_end = u.breaks[j], u.breaks[j + 1]
        while t < t_end - 1e-15:
            stuck = x[1] == 0.0 and abs(applied(x, level)) <= F
            if stuck:

                def rhs(_, z, level=level):
                    return [0.0, 0.0, z[3], (k * (z[0] - z[2]) - d * z[3]) / m2]

                def slip_p(_, z, level=level):
                    return applied(z, level) - F

                def slip_m(_, z, level=level):
                    return applied(z, level) + F

                slip_p.terminal = slip_m.terminal = True
                sol = solve_ivp(rhs, (t, t_end), x, method="DOP853", rtol=1e-12, atol=1e-14, events=[slip_p, slip_m])
            else:
                s = math.copysign(1.0, x[1]) if x[1] != 0.0 else math.copysign(1.0, applied(x, level))

                def rhs(_, z, level=level, s=s):
                    f = k * (z[0] - z[2]) + d * (z[1] - z[3])
                    return [z[1], (level - f - F * s) / m1, z[3], f / m2]

                def stop(_, z, s=s):
                    return z[1] * s

                stop.terminal = True
                stop.direction = -1
                sol = solve_ivp(rhs, (t, t_end), x, method="DOP853", rtol=1e-12, atol=1e-14, events=[stop])
            if sol.status == 1:
                idx = next(i for i, te in enumerate(sol.t_events) if te.size)
                t = float(sol.t_events[idx][0])
                x = sol.y_events[idx][0].copy()
                if not stuck:
                    x[1] = 0.0
                else:  # breaks loose: nudge into sliding in the direction of the net force
                    x[1] = 0.0
                    x_next = x.copy()
                    s = math.copysign(1.0, applied(x, level))
                    x_next[1] = s * 1e-300
                    x = x_next
            else:
                x = sol.y[:, -1].copy()
                t = t_end
        out.append(x.copy())
    return np.array(out)


def random_input(rng, n_pieces, T, u_max):
    breaks = np.sort(np.concatenate([[0.0, T], rng.uniform(0.0, T, n_pieces - 1)]))
    return PiecewiseConstant(breaks, rng.uniform(-u_max, u_max, n_pieces))


# ------------------------------------------------------------ simulation
@pytest.mark.parametrize("seed", range(6))
def test_rigid_body_matches_closed_form(seed):
    rng = np.random.default_rng(seed)
    b0 = rng.choice([-1.0, 1.0]) * rng.uniform(0.2, 3.0)
    F = rng.uniform(0.1, 0.8)
    u = random_input(rng, 12, 6.0, 1.0)
    p0, v0 = rng.normal(), rng.normal()
    model = ModalModel(b0=b0)
    got = simulate_coulomb(model, [p0, v0], u, F)
    ref = rigid_reference(b0, F, p0, v0, u)
    assert np.max(np.abs(got - ref)) < 1e-12 * (1.0 + np.max(np.abs(ref)))


@pytest.mark.parametrize("seed", range(4))
def test_modal_model_matches_event_located_ivp(seed):
    rng = np.random.default_rng(10 + seed)
    model = ModalModel(
        b0=rng.uniform(0.3, 1.5),
        c=-rng.uniform(0.0, 0.5) if seed % 2 else 0.0,
        omega=[rng.uniform(1.0, 3.0), rng.uniform(4.0, 8.0)],
        zeta=[rng.uniform(0.0, 0.05), rng.uniform(0.0, 0.05)],
        b=[rng.uniform(0.5, 1.5), -rng.uniform(0.5, 1.5)],
    )
    F = rng.uniform(0.2, 0.6)
    u = random_input(rng, 10, 5.0, 1.0)
    x0 = np.concatenate([[0.0, rng.normal()], rng.normal(size=4) * 0.1])
    got = simulate_coulomb(model, x0, u, F)
    ref = ivp_modal_friction(model, F, x0, u)
    scale = 1.0 + np.max(np.abs(ref), axis=0)
    assert np.max(np.abs(got - ref) / scale) < 1e-8


def test_sticking_holds_the_rigid_body_and_leaves_the_modes_free():
    F = 0.4
    u = PiecewiseConstant([0.0, 1.5, 3.0, 4.0], [0.3, -0.4, 0.9])  # |u| <= F, then = F, then above
    x0 = np.array([2.0, 0.0, 0.05, -0.1])
    times = np.linspace(0.0, 4.0, 41)
    got = simulate_coulomb(WB, x0, u, F, times)
    free = simulate(WB, x0, u, times)  # frictionless: the modes are the same
    stuck = times <= 3.0
    assert np.all(got[stuck, 0] == 2.0) and np.all(got[stuck, 1] == 0.0)  # exactly at rest
    assert np.max(np.abs(got[:, 2:] - free[:, 2:])) < 1e-13  # modes unaffected by rigid-body friction
    assert got[-1, 1] > 0.0  # |u| > F: it slides ...
    a = WB.b0 * (0.9 - F)  # ... with b0 (u - F) from t = 3
    assert got[-1, 1] == pytest.approx(a * 1.0, rel=1e-12)
    assert got[-1, 0] == pytest.approx(2.0 + 0.5 * a, rel=1e-12)


def test_coasting_body_stops_at_the_predicted_instant_and_stays():
    F, v0 = 0.25, 0.8
    u = PiecewiseConstant([0.0, 10.0], [0.0])
    run = FrictionSystem.for_model(WB, F).run([0.0, v0, 0.0, 0.0], u, [10.0])
    t_stop = v0 / (WB.b0 * F)
    kinds = [(k, t) for t, k, _ in run.events]
    assert kinds[0][0] == "stick" and kinds[0][1] == pytest.approx(t_stop, rel=1e-14)
    assert run.states[0][0] == pytest.approx(v0 * t_stop / 2.0, rel=1e-13)
    assert run.states[0][1] == 0.0


def test_closed_form_and_matrix_exponential_paths_agree():
    rng = np.random.default_rng(3)
    u = random_input(rng, 15, 6.0, 1.0)
    x0 = [0.0, 0.3, 0.02, 0.0]
    a = FrictionSystem.for_model(WB, 0.3, closed_form=True).run(x0, u).states
    b = FrictionSystem.for_model(WB, 0.3).run(x0, u).states
    assert np.max(np.abs(a - b)) < 1e-12


@pytest.mark.parametrize("seed", range(3))
def test_friction_inside_the_structure_sticks_with_constrained_modes(seed):
    """Friction on mass 1 of a two-mass system: the stuck mass changes the modal dynamics."""
    rng = np.random.default_rng(20 + seed)
    m1, m2, k, d = 1.0, rng.uniform(0.5, 2.0), rng.uniform(0.5, 2.0), rng.uniform(0.0, 0.1)
    built = two_mass(m1, m2, k, d)
    F = rng.uniform(0.2, 0.5)
    contact = contact_at_coordinate(built, 0, F)
    # the actuator pushes mass 1: a force there has the input's modal effect
    assert np.allclose(contact.g[1::2], built.model.B()[1::2], rtol=1e-12)
    u = random_input(rng, 8, 8.0, 1.0)
    Phi = built.modal_to_physical
    x0_phys = np.array([0.0, 0.0, 0.0, 0.0])
    run = simulate_contact(built.model.A(), built.model.B(), contact, np.zeros(4), u)
    got = np.column_stack([run.states[:, [0, 2]] @ Phi.T, run.states[:, [1, 3]] @ Phi.T])[:, [0, 2, 1, 3]]
    ref = ivp_two_mass_friction(m1, m2, k, d, F, x0_phys, u)
    assert any(kind == "stick" for _, kind, _ in run.events) or any(kind == "reversal" for _, kind, _ in run.events)
    assert np.max(np.abs(got - ref)) < 1e-7 * (1.0 + np.max(np.abs(ref)))


def test_contact_validation():
    with pytest.raises(FlexmotionError) as e:
        simulate_coulomb(WB, np.zeros(4), PiecewiseConstant([0.0, 1.0], [1.0]), -0.1)
    assert e.value.parameter == "coulomb_force"


# ------------------------------------------------------------ planner
@pytest.fixture(scope="module")
def wb_friction():
    return {F: plan_time_optimal_friction(rest_to_rest(WB, 1.0, 1.0), F) for F in (0.0, 0.1, 0.3)}


def test_friction_move_rests_at_target_in_exact_simulation(wb_friction):
    T_star = plan_time_optimal(rest_to_rest(WB, 1.0, 1.0)).duration
    durations = []
    for F, prof in wb_friction.items():
        u = prof.input()
        x = simulate_coulomb(WB, WB.rest_state(), u, F, [prof.duration, prof.duration + 5.0])
        target = WB.rest_state(1.0)
        assert np.max(np.abs(x[0] - target)) < 1e-12
        assert np.max(np.abs(x[1] - target)) < 1e-12  # and stays there with u = 0
        assert np.all(np.abs(prof.levels) == 1.0)
        assert prof.certified, prof.certificate.message
        assert prof.duration >= prof.lower_bound
        durations.append(prof.duration)
        # independent cross-check of the final state: event-located integration
        ref = ivp_modal_friction(WB, F, WB.rest_state(), u)[-1]
        assert np.max(np.abs(ref - target)) < 1e-7
    assert durations[0] == pytest.approx(T_star, abs=1e-12)
    assert durations[0] < durations[1] < durations[2]  # friction costs time here


def test_wie_bernstein_move_reverses_and_the_costate_jumps(wb_friction):
    prof = wb_friction[0.1]
    assert prof.reversals.size == 2  # the centre of mass briefly moves back mid-move
    assert 0.0 < prof.reversals[0] < prof.reversals[1] < prof.duration


def test_rigid_body_friction_optimum_is_the_closed_form():
    b0, F, gamma = 0.5, 0.3, 2.0
    prof = plan_time_optimal_friction(rest_to_rest(ModalModel(b0=b0), 1.0, gamma), F)
    a1, a2 = b0 * (1.0 - F), b0 * (1.0 + F)
    T = math.sqrt(2.0 * gamma * (a1 + a2) / (a1 * a2))
    assert prof.duration == pytest.approx(T, rel=1e-13)
    assert prof.switch_times == pytest.approx([T * a2 / (a1 + a2)], rel=1e-13)
    assert rigid_friction_time(ModalModel(b0=b0), 1.0, F, [0.0, 0.0], gamma) == pytest.approx(T, rel=1e-15)


def test_a_move_already_at_rest_reports_it_in_the_message_not_the_claim():
    """Regression: the at-rest certificate was built positionally and its note landed in ``claim``."""
    prof = plan_time_optimal_friction(rest_to_rest(WB, 1.0, 0.0, start=0.25), 0.3)
    assert prof.duration == 0.0 and prof.switch_times.size == 0 and prof.certified
    assert prof.certificate.message == "already at rest"
    assert prof.certificate.claim == CLAIM
    assert prof.to_dict()["certificate"]["message"] == "already at rest"


def test_structure_change_is_followed_on_the_three_mode_beam():
    model = ModalModel(
        b0=0.5,
        omega=[21.647844005847876, 40.0, 52.262518595055056],
        zeta=[0.010823922002923939, 0.02, 0.02613125929752753],
        b=[0.707106781186547, 1.0, -0.7071067811865477],
    )
    problem = rest_to_rest(model, 10.0, 0.5)
    prof = plan_time_optimal_friction(problem, 0.5)
    assert prof.certified, prof.certificate.message
    assert prof.switch_times.size == 9  # a new pair of switches near the end of the move
    x = simulate_coulomb(model, model.rest_state(), prof.input(), 0.5, [prof.duration])[0]
    assert np.max(np.abs(x - model.rest_state(0.5))) < 1e-12


def test_sampled_friction_move_is_exact_and_bounded(wb_friction):
    prof = wb_friction[0.3]
    problem = prof.problem
    sp = plan_time_optimal_friction_zoh(problem, 0.3, 100.0, prof)
    assert np.max(np.abs(sp.commands)) <= 1.0
    x = simulate_coulomb(WB, WB.rest_state(), sp.input(), 0.3, [sp.duration, sp.duration + 3.0])
    assert np.max(np.abs(x - WB.rest_state(1.0))) < 1e-11
    assert sp.samples >= sp.lower_bound_samples
    assert sp.samples <= math.ceil(prof.duration * 100.0) + 5
    assert np.allclose(sp.states[-1], x[0], atol=1e-12)


def test_a_spent_sampled_budget_is_a_solver_failure(monkeypatch, wb_friction):
    """Issue 18: past the sampled search's ``WORK_BUDGET`` (LP rows and columns) the planner stops with one line naming the
    budget (it hung for minutes before); nothing is returned."""
    monkeypatch.setattr(zoh_mod, "WORK_BUDGET", 0)
    prof = wb_friction[0.3]
    with pytest.raises(SolverError, match="planning budget") as info:
        plan_time_optimal_friction_zoh(prof.problem, 0.3, 100.0, prof)
    assert "\n" not in str(info.value)


def test_method_through_plan_move_and_parameter_errors():
    base = {"model.b0": 0.5, "model.omega": [math.sqrt(2.0)], "model.zeta": [0.0], "model.b": [1.0]}
    cfg = config_from_parameters({**base, "method": "time_optimal_friction", "coulomb_force": 0.2})
    res = plan_move(cfg, rest_to_rest(cfg.model, cfg.u_max, 1.0), rate_hz=50.0)
    summary = res.summary()
    assert summary["method"] == "time_optimal_friction" and summary["certified"]
    assert summary["added_time_s"] > 0.0
    json.dumps(summary)
    for bad in (1.0, 1.5, -0.1, float("nan"), "x"):
        cfg_bad = config_from_parameters({**base, "method": "time_optimal_friction", "coulomb_force": bad})
        with pytest.raises(FlexmotionError) as e:
            plan_move(cfg_bad, rest_to_rest(cfg.model, cfg.u_max, 1.0))
        assert e.value.parameter == "coulomb_force" and "[0, u_max)" in str(e.value)
    with pytest.raises(FlexmotionError) as e:
        plan_move(
            config_from_parameters({**base, "method": "time_optimal_friction"}), rest_to_rest(cfg.model, 1.0, 1.0)
        )
    assert e.value.parameter == "coulomb_force"


def test_cli_plans_the_example_config():
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "flexmotion_ros.cli.main",
            "plan",
            "--config",
            "config/friction_example.yaml",
            "--goal",
            "1.0",
            "--json",
        ],
        capture_output=True,
        text=True,
        check=False,
        cwd=__file__.rsplit("/test/", 1)[0],
    )
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert data["method"] == "time_optimal_friction" and data["coulomb_force"] == 0.2


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    w=st.floats(0.5, 3.0),
    zeta=st.floats(0.0, 0.1),
    b=st.floats(0.3, 2.0),
    gamma=st.floats(0.2, 3.0),
    frac=st.floats(0.0, 0.6),
)
def test_never_returns_a_move_that_misses_the_target(w, zeta, b, gamma, frac):
    model = ModalModel(b0=0.5, omega=[w], zeta=[zeta], b=[b])
    try:
        prof = plan_time_optimal_friction(rest_to_rest(model, 1.0, gamma), frac)
    except SolverError:
        return  # allowed: nothing is returned
    x = simulate_coulomb(model, model.rest_state(), prof.input(), frac, [prof.duration, prof.duration + 2.0])
    scale = 1.0 + gamma
    assert np.max(np.abs(x - model.rest_state(gamma))) < 1e-9 * scale
    assert prof.lower_bound is None or prof.duration >= prof.lower_bound * (1.0 - 1e-12)


# ------------------------------------------------------------- issue 18
def test_issue18_structure_change_no_longer_stalls():
    """Issue 18: "continuation from the frictionless optimum stalled at coulomb_force = 0.123681 N (the
    switch structure changes); nothing is returned".  Now a plan: the continuous move and the 100 Hz
    sequence rest at the target in the exact event-located simulation (and in an independent
    event-located ODE integration), within the bound, and the certificate says what was proved."""
    m = ModalModel(
        b0=0.27336967201641243,
        c=0.0,
        omega=(0.41991476607082023, 3.194567184025729, 5.752751792341, 51.213173874446255),
        zeta=(0.018484257053140062, 0.10486902847816988, 0.0, 0.27982379019089254),
        b=(0.3847736811881417, -0.505944946955234, -0.4246379851543105, 0.49891839486279355),
    )
    u_max, F, goal = 1.9268024392824576, 0.6088932026978997, -0.4781025580990753
    problem = MoveProblem(m, u_max, [0.0] * 10, goal)
    config = PlannerConfig(model=m, u_max=u_max, method="time_optimal_friction", options={"coulomb_force": F})
    result = plan_move(config, problem, 100.0)
    target = m.rest_state(goal)
    cont = result.continuous
    assert cont.certificate.status in set(FrictionStatus) and cont.certificate.message
    assert cont.certified == (cont.certificate.status == FrictionStatus.EXTREMAL)
    for u, T in ((cont.input(), cont.duration), (result.sampled.input(), result.sampled.duration)):
        assert np.max(np.abs(u.levels)) <= u_max
        x = simulate_coulomb(m, m.rest_state(), u, F, [T, T + 20.0])
        assert np.max(np.abs(x - target)) < 1e-9
    ref = ivp_modal_friction(m, F, m.rest_state(), cont.input())[-1]  # the continuous move, once more
    assert np.max(np.abs(ref[:2] - target[:2])) < 1e-6


@pytest.mark.parametrize("c", [-1e-7, -0.05, -0.9])
def test_damped_rigid_bound_is_the_bang_bang_move_of_the_rigid_body(c):
    """The rigid-body bound for ``c < 0`` (new with issue 18's damped cases): it is the time of the
    accelerate-then-brake move of the rigid body alone, so that move, switched where the two envelopes
    cross, must rest exactly at the goal in the event-located friction simulation (matrix exponentials)."""
    b0, u_max, F, gamma = 0.7, 1.3, 0.4, 3.0
    model = ModalModel(b0=b0, c=c)
    T = rigid_friction_time(model, u_max, F, [0.0, 0.0], gamma)
    k = -c
    a1, a2 = b0 * (u_max - F), b0 * (u_max + F)
    r = math.log1p(-a1 * math.expm1(-k * T) / (a2 + a1 * math.exp(-k * T))) / k  # brake time
    u = PiecewiseConstant.from_switches([T - r], [u_max, -u_max], T)
    x = FrictionSystem(model.A(), model.B(), rigid_contact(model, F)).run([0.0, 0.0], u, [T]).states[0]
    assert x[0] == pytest.approx(gamma, rel=1e-9)
    assert abs(x[1]) <= 1e-9 * a1 / max(k, 1.0)
    # undamped limit and monotone in the damping
    assert T >= rigid_friction_time(ModalModel(b0=b0), u_max, F, [0.0, 0.0], gamma)


#: Fuzz cases of ``bench/fuzz_friction_limited.py --seed 18`` that raised "neither the continuation from
#: the frictionless optimum nor the structure of a sampled move gave an exact move" (both ``c < 0``):
#: 195, a long move of a damped rigid body (the coarse samples are too long for the modes to be brought
#: to rest: every count has the same least peak); 492, two close slow modes and F = 0.5 u_max (no sliding
#: pattern reaches rest: the body must be held by friction on the way while the modes are steered).
DAMPED_CASES = {
    # 90: an exact bang-bang move (not a proved extremal) whose velocity pattern does not survive the
    # 100 Hz sampling ("sampled friction planner: no sequence up to 19432 samples ..."; on the old code
    # too, though not in its recorded run): the exact sampled move found on the way is streamed instead
    90: (
        ModalModel(
            b0=2.60372602617571,
            c=-0.6037686556584784,
            omega=(0.6668554566912988,),
            zeta=(0.2759154365638096,),
            b=(1.609621214815742,),
        ),
        3.39396555930163,
        1.0848179163599223,
        -435.7287906678293,
    ),
    195: (
        ModalModel(
            b0=0.7010881507642357,
            c=-0.5145535505981457,
            omega=(0.3691326599470246, 2.992410978391293, 8.614077375309595),
            zeta=(0.2918219725275136, 0.09311612122617004, 0.028614967663583867),
            b=(-0.9556713406018813, 0.2549199605547329, -1.1135557658361661),
        ),
        0.4007626013786231,
        0.035489805968980194,
        131.14923761075815,
    ),
    492: (
        ModalModel(
            b0=0.13422842892094394,
            c=-0.70400694826743,
            omega=(0.7721549463467025, 0.7923167284232879, 29.701533690589205),
            zeta=(0.26457178493966277, 0.27920761139920636, 0.0752186001428152),
            b=(0.39211715189292795, -0.9704074569056195, -0.5598962490544935),
        ),
        0.7454725539854661,
        0.36988037191729395,
        0.3668231174880086,
    ),
    # 616: a 700 s move whose end game needs the body to wait (held by friction) while three slow damped
    # modes are brought to rest; neither sliding patterns nor the stick iteration found one
    616: (
        ModalModel(
            b0=0.2246986214310774,
            c=-0.9013106002893919,
            omega=(0.8008758935650085, 1.0544778822462209, 2.7740287106729076),
            zeta=(0.2783519094292859, 0.22677499819967586, 0.27026727518256366),
            b=(0.7506085340950495, -1.7431951069171636, 1.2299365178020474),
        ),
        8.046276174214604,
        2.909473700812145,
        -788.857368190717,
    ),
}


@pytest.mark.parametrize("case", sorted(DAMPED_CASES))
def test_issue18_damped_rigid_body_cases_plan_exact_moves(case):
    """Regression (raised SolverError before): a plan whose continuous move and 100 Hz sequence rest at
    the target in the exact event-located simulation and stay there, within the bound, never faster
    than the proved rigid-body bound; the continuous move once more by an independent ODE integration."""
    m, u_max, F, goal = DAMPED_CASES[case]
    problem = MoveProblem(m, u_max, [0.0] * m.n_states, goal)
    config = PlannerConfig(model=m, u_max=u_max, method="time_optimal_friction", options={"coulomb_force": F})
    result = plan_move(config, problem, 100.0)
    cont = result.continuous
    target = m.rest_state(goal)
    assert cont.lower_bound is not None and cont.duration >= cont.lower_bound
    assert cont.certificate.status in set(FrictionStatus) and cont.certificate.message
    exact = FrictionSystem(m.A(), m.B(), rigid_contact(m, F))  # matrix exponentials, event-located
    for u, T in ((cont.input(), cont.duration), (result.sampled.input(), result.sampled.duration)):
        assert np.max(np.abs(u.levels)) <= u_max
        states = exact.run(problem.x0, u, np.concatenate([np.linspace(0.0, T, 65), [2.0 * T + 1.0]])).states
        scale = np.max(np.abs(states[:-1] - target), axis=0)
        assert np.max(np.abs(states[-2:] - target) / scale) < 1e-8  # at rest at T, and still later
    if cont.duration < 20.0:  # an independent event-located ODE integration (slow on long moves)
        ref = ivp_modal_friction(m, F, m.rest_state(), cont.input())[-1]
        assert abs(ref[0] - goal) < 1e-6 * abs(goal)


# ------------------------------------------- issue 18: planning time and the continuation's reach
def test_zoh_never_searches_past_the_exact_sampled_move_it_already_has(monkeypatch, wb_friction):
    """An uncertified continuous move comes with an exact sampled move (``alternative``): the 100 Hz search
    near the continuous move stops at that move's sample count and falls back on it (fuzz case 43 of
    seed 18 spent 14 s in windowed LPs up to 4 x the count before falling back)."""
    prof = copy.copy(wb_friction[0.3])
    problem = prof.problem
    lp = FrictionLP(problem, 0.3, 0.05)
    sol = fastest_samples(lp, lambda tau: np.ones(np.shape(tau)), 100)
    alt = sampled_profile(lp, sol, plan_time_optimal(problem), None, 0, time.perf_counter())
    assert alt is not None and alt.sample_period == 0.05
    prof.alternative = alt
    counts = []

    def no_sequence(self, K, *args, **kwargs):
        counts.append(K)
        return None

    monkeypatch.setattr(FrictionLP, "solve", no_sequence)
    monkeypatch.setattr(FrictionLP, "solve_windowed", no_sequence)
    sp = plan_time_optimal_friction_zoh(problem, 0.3, 100.0, prof)
    K_alt = round(alt.duration * 100.0)
    assert sp.samples == K_alt  # the known move, each command held five periods
    assert counts and max(counts) <= K_alt
    x = simulate_coulomb(WB, WB.rest_state(), sp.input(), 0.3, [sp.duration, sp.duration + 3.0])
    assert np.max(np.abs(x - WB.rest_state(1.0))) < 1e-11


FUZZ_40 = (
    ModalModel(
        b0=1.8450403868093213,
        c=0.0,
        omega=(0.32451620618816157, 0.5479122110962255),
        zeta=(0.26743592097649344, 0.13129812583788267),
        b=(-1.0722289039157573, 1.4307325078123587),
    ),
    3.3225983038012408,
    1.4169496116399825,
    -66.48537417526029,
)


def test_continuation_reaches_the_force_where_it_ran_out_of_evaluations():
    """Fuzz case 40 of seed 18: the continuation from the frictionless optimum ran out of its 48 exact runs
    (two-sided differences: two per Jacobian column) and the planner returned a 35.38 s sampled move; with
    one-sided columns and a shorter line search it reaches ``F``: a bang-bang move (levels +-u_max) of
    16.93 s that rests at the target in the event-located simulation with matrix exponentials."""
    m, u_max, F, goal = FUZZ_40
    problem = MoveProblem(m, u_max, [0.0] * m.n_states, goal)
    prof = plan_time_optimal_friction(problem, F, 100.0)
    assert not prof.certificate.status.sampled
    assert np.allclose(np.abs(prof.levels), u_max)
    assert prof.duration < 20.0 and prof.duration >= prof.lower_bound
    exact = FrictionSystem(m.A(), m.B(), rigid_contact(m, F))
    T = prof.duration
    states = exact.run(problem.x0, prof.input(), np.concatenate([np.linspace(0.0, T, 65), [2.0 * T]])).states
    scale = np.max(np.abs(states - m.rest_state(goal)), axis=0)
    assert np.max(np.abs(states[-2:] - m.rest_state(goal)) / scale) < 1e-9


def test_zoh_falls_back_on_the_structure_search_when_the_continued_extremal_has_no_sequence():
    """Fuzz case 362 of seed 18 (a 73 s move of a damped rigid body): the continuation reaches ``F`` at once
    and the extremal is certified, but no 100 Hz sequence near it passes the check up to 4 x its samples;
    with no exact sampled move found on the way the ZOH raised.  It now runs the sampled structure search at
    the rate and streams that exact move: at rest at the target and after, within the bound."""
    m = ModalModel(
        b0=3.4137893386325913,
        c=-0.9639452958944782,
        omega=(0.30702563085856543, 1.3404514537336292, 37.2354694594352),
        zeta=(0.1498471141085232, 0.20901955928225677, 0.2326249390516098),
        b=(1.0979924537225867, 0.15936693099269644, -0.47193330932205757),
    )
    u_max, F, goal = 0.9668119924018779, 0.04531828615843266, -218.26491923028965
    problem = MoveProblem(m, u_max, [0.0] * m.n_states, goal)
    config = PlannerConfig(model=m, u_max=u_max, method="time_optimal_friction", options={"coulomb_force": F})
    result = plan_move(config, problem, 100.0)
    sp = result.sampled
    assert np.max(np.abs(sp.commands)) <= u_max
    assert sp.duration >= result.continuous.duration
    exact = FrictionSystem(m.A(), m.B(), rigid_contact(m, F))
    T = sp.duration
    states = exact.run(problem.x0, sp.input(), np.concatenate([np.linspace(0.0, T, 65), [2.0 * T]])).states
    scale = np.max(np.abs(states - m.rest_state(goal)), axis=0)
    assert np.max(np.abs(states[-2:] - m.rest_state(goal)) / scale) < 1e-8


def _fuzz_case_85():
    """Seed-18 fuzz case 85 (one mode, F = 0.23 u_max): an ``exact_sampled`` move in about 0.1 s."""
    m = ModalModel(
        b0=0.2475398635644658, c=0.0, omega=(17.08367498337336,), zeta=(0.23092339986398053,), b=(-1.1568104821418557,)
    )
    u_max = 1.9917117784675535
    return MoveProblem(m, u_max, [0.0] * 4, 0.00020271199499823713), 0.22537098471164416 * u_max


def test_exact_sampled_check_is_one_run_of_the_move(monkeypatch):
    """The exact check of a sampled move ran the whole move twice (end state, then 129 points of its
    error scale on a grid that made every segment a new matrix exponential): one run now, same verdict."""
    from flexmotion_ros.core.friction import contact as contact_mod

    problem, F = _fuzz_case_85()
    runs = []
    real = contact_mod.FrictionSystem.run

    def counted(self, x0, u, times=None, lock_after=math.inf, **kwargs):
        runs.append(u.duration)
        return real(self, x0, u, times, lock_after, **kwargs)

    monkeypatch.setattr(contact_mod.FrictionSystem, "run", counted)
    prof = plan_time_optimal_friction(problem, F, 100.0)
    assert prof.certificate.status.sampled
    runs.clear()
    checked = profile_mod.check_sampled(prof_lp(prof), np.asarray(prof.levels, float))
    assert checked is not None
    assert len(runs) == 1
    x = simulate_coulomb(problem.model, problem.x0, prof.input(), F, [prof.duration, 2.0 * prof.duration + 1.0])
    assert np.max(np.abs(x - problem.model.rest_state(problem.target))) < 1e-12


def prof_lp(prof):
    return FrictionLP(prof.problem, prof.coulomb_force, prof.sample_period)


def test_zoh_of_an_exact_sampled_move_needs_no_direction_run(monkeypatch):
    """An ``exact_sampled`` move on whole command periods is its own sequence: the ZOH checks it and is
    done; the exact run that reads the move's directions (for the LPs near it) is not made."""
    problem, F = _fuzz_case_85()
    prof = plan_time_optimal_friction(problem, F, 100.0)
    assert prof.certificate.status.sampled

    def refuse(*_a, **_k):
        raise AssertionError("directions read although no LP needs them")

    monkeypatch.setattr(zoh_mod, "_directions", refuse)
    sp = plan_time_optimal_friction_zoh(problem, F, 100.0, prof)
    assert sp.samples * 0.01 == pytest.approx(prof.duration)
    x = simulate_coulomb(problem.model, problem.x0, sp.input(), F, [sp.duration, sp.duration + 1.0])
    assert np.max(np.abs(x - problem.model.rest_state(problem.target))) < 1e-12


def test_a_move_held_on_the_way_is_tried_before_coarser_samples():
    """Seed-18 fuzz case 99 (one mode, c = 0, F = 0.38 u_max, a 0.19 mm move; at least 0.053 s, proved).  No
    sliding sequence at the first sample period; before, the planner went to 4 x coarser samples and
    returned a sliding move of 5.4 s.  Now the move held by friction on the way at the first period is tried
    first: 0.16 s (16 commands at 100 Hz), exact in the event-located simulation, its pattern certified."""
    from flexmotion_ros.core.friction.certificate import FrictionStatus

    m = ModalModel(
        b0=0.34679121849582395, c=0.0, omega=(1.753589115602974,), zeta=(0.23997508298296338,), b=(0.9698103249298977,)
    )
    u_max = 0.9428903438982117
    problem, F = MoveProblem(m, u_max, [0.0] * m.n_states, 0.000192726173971487), 0.3808752856060291 * u_max
    prof = plan_time_optimal_friction(problem, F, 100.0)
    assert prof.duration <= 0.2  # was 5.4 s
    assert prof.lower_bound is not None and prof.duration >= prof.lower_bound
    assert prof.certificate.status is FrictionStatus.SAMPLED_PATTERN
    assert np.max(np.abs(prof.levels)) <= u_max
    xf = m.rest_state(problem.target)
    x = simulate_coulomb(m, problem.x0, prof.input(), F, [prof.duration, 2.0 * prof.duration + 1.0])
    full = simulate_coulomb(m, problem.x0, prof.input(), F, np.linspace(0.0, prof.duration, 200))
    scale = np.max(np.abs(full - xf), axis=0) + 1e-300
    assert np.max(np.abs(x - xf) / scale) < 1e-8
