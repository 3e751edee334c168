"""Fewest samples under velocity, deflection and slew limits, against independent computations.

References: the exact matrix-exponential simulation (``core.simulation``) at
every sample and on a fine sub-sampling of every interval; a second LP
formulation (every state a variable, ``scipy.linalg.expm`` step matrices)
for the feasibility of ``K - 1`` and ``K`` samples.
"""

import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy import sparse
from scipy.optimize import linprog

from flexmotion_ros.cli.main import main as cli_main
from flexmotion_ros.core import (
    ModalModel,
    MoveProblem,
    PiecewiseConstant,
    PlannerConfig,
    config_from_parameters,
    motion_to_rest,
    plan_time_optimal_zoh,
    rest_to_rest,
    simulate,
    simulate_samples,
    state_to_rest,
)
from flexmotion_ros.core.constraints import accept as accept_mod
from flexmotion_ros.core.constraints import level as limit_level
from flexmotion_ros.core.constraints import lp as limit_lp
from flexmotion_ros.core.constraints import planner as limits_mod
from flexmotion_ros.core.constraints import proof as limit_proof
from flexmotion_ros.core.constraints.limits import Limits, deflection_peaks
from flexmotion_ros.core.constraints.planner import plan_limited_zoh
from flexmotion_ros.core.constraints.segments import Segments
from flexmotion_ros.core.constraints.structure import map_runs, solution_runs
from flexmotion_ros.core.errors import FlexmotionError, GoalError, SolverError
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.simulation.exact import step_matrices

WB = ModalModel(b0=0.5, c=0.0, omega=[math.sqrt(2.0)], zeta=[0.0], b=[1.0])
TWO = ModalModel(b0=1.0, c=-0.2, omega=[2.0, 5.0], zeta=[0.02, 0.05], b=[0.8, -0.5])
SUB = 40  # sub-samples per interval for the between-sample check


# ------------------------------------------------------------ references
def feasible_state_space(problem, K, dt, limits, slack=1e-9, sub=1):
    """Second formulation: every state a variable, expm step matrices; limits loosened by ``slack``.

    Deflection limits at the samples and, with ``sub > 1``, at ``sub - 1`` points
    inside every interval (still a relaxation of the continuous-time limit).
    """
    model = problem.model
    A, B = model.A(), model.B()
    n = A.shape[0]
    Phi, Gam = step_matrices(A, B, dt)
    inner = [step_matrices(A, B, dt * j / sub) for j in range(1, sub)]
    x0 = problem.x0
    xf = model.rest_state(problem.target if problem.target is not None else 0.0)
    nv = K + n * K  # u_0..u_{K-1}, x_1..x_K
    Aeq = sparse.lil_matrix((n * K, nv))  # sparse: thousands of samples in the regression tests
    beq = np.zeros(n * K)
    for k in range(K):
        r = slice(n * k, n * k + n)
        Aeq[r, K + n * k : K + n * k + n] = np.eye(n)
        Aeq[r, k] = -Gam
        if k == 0:
            beq[r] = Phi @ x0
        else:
            Aeq[r, K + n * (k - 1) : K + n * k] = -Phi
    lo = np.full(nv, -np.inf)
    hi = np.full(nv, np.inf)
    lo[:K], hi[:K] = -problem.u_max, problem.u_max
    loose = 1.0 + slack
    for k in range(K):
        base = K + n * k
        if limits.velocity_max is not None:
            lo[base + 1], hi[base + 1] = -limits.velocity_max * loose, limits.velocity_max * loose
        for i, qm in enumerate(limits.deflection_max or ()):
            if math.isfinite(qm):
                lo[base + 2 + 2 * i], hi[base + 2 + 2 * i] = -qm * loose, qm * loose
    final = slice(K + n * (K - 1), K + n * K)
    lo[final] = hi[final] = xf
    if problem.target is None:  # position free
        lo[K + n * (K - 1)], hi[K + n * (K - 1)] = -np.inf, np.inf
    rows, rhs = [], []
    if limits.slew_rate is not None:
        s = limits.slew_rate * dt * loose
        for k in range(K + 1):  # u_{-1} = u_K = 0
            r = np.zeros(nv)
            if k < K:
                r[k] = 1.0
            if k > 0:
                r[k - 1] = -1.0
            rows += [r, -r]
            rhs += [s, s]
    for i, qm in enumerate(limits.deflection_max or ()):
        if not math.isfinite(qm):
            continue
        j = 2 + 2 * i
        for k in range(K):
            for Ph, Gm in inner:  # q(k dt + h) = (Ph x_k + Gm u_k)_j
                r = np.zeros(nv)
                r[k] = Gm[j]
                const = 0.0
                if k == 0:
                    const = Ph[j] @ x0
                else:
                    r[K + n * (k - 1) : K + n * k] = Ph[j]
                rows += [r, -r]
                rhs += [qm * loose - const, qm * loose + const]
    A_ub = sparse.csr_matrix(np.array(rows)) if rows else None
    b_ub = np.array(rhs) if rows else None
    # the interior-point method: HiGHS's dual simplex can stall on this dense, barely
    # infeasible LP (minutes at 268 samples, against 0.1 s)
    kw = dict(A_ub=A_ub, b_ub=b_ub, A_eq=Aeq.tocsr(), b_eq=beq, bounds=list(zip(lo, hi)))
    res = linprog(np.zeros(nv), method="highs-ipm", **kw)
    if res.status not in (0, 2):
        res = linprog(np.zeros(nv), method="highs", **kw)
    assert res.status in (0, 2), res.message
    return res.status == 0


def fine_states(problem, commands, dt, sub=SUB):
    """Exact states on a fine grid inside every sample interval (matrix exponentials)."""
    u = PiecewiseConstant.from_samples(commands, dt)
    times = np.linspace(0.0, commands.size * dt, commands.size * sub + 1)
    return simulate(problem.model, problem.x0, u, times=times)


def check_every_limit(problem, result, limits):
    s = result.sampled
    dt = s.dt
    u = s.commands
    states = simulate_samples(problem.model, problem.x0, u, dt)
    target = problem.model.rest_state(problem.target if problem.target is not None else 0.0)
    dev = (states[-1] - target)[0 if problem.target is not None else 1 :]
    assert np.max(np.abs(dev)) <= 1e-9 * max(1.0, abs(problem.target or 0.0))
    assert np.max(np.abs(u)) <= problem.u_max
    fine = fine_states(problem, u, dt)
    if limits.velocity_max is not None:
        assert np.max(np.abs(states[:, 1])) <= limits.velocity_max
        assert np.max(np.abs(fine[:, 1])) <= limits.velocity_max * (1 + 1e-12)
    for i, qm in enumerate(limits.deflection_max or ()):
        assert np.max(np.abs(states[:, 2 + 2 * i])) <= qm
        assert np.max(np.abs(fine[:, 2 + 2 * i])) <= qm * (1 + 1e-12)
    if limits.slew_rate is not None:
        steps = np.abs(np.diff(np.concatenate([[0.0], u, [0.0]])))
        assert np.max(steps) <= limits.slew_rate * dt


# ------------------------------------------------------------------ cases
CASES = [
    ("velocity", rest_to_rest(WB, 1.0, 1.0), Limits(velocity_max=0.35)),
    ("deflection", rest_to_rest(WB, 1.0, 1.0), Limits(deflection_max=(0.2,))),
    ("slew", rest_to_rest(WB, 1.0, 1.0), Limits(slew_rate=4.0)),
    ("all", rest_to_rest(WB, 1.0, 1.0), Limits(0.35, (0.2,), 4.0)),
    ("two-mode", rest_to_rest(TWO, 2.0, 1.0), Limits(0.6, (0.05, math.inf), 30.0)),
    ("motion-to-rest", motion_to_rest(TWO, 2.0, 0.9), Limits(None, (0.05, 0.02), 30.0)),
]


@pytest.mark.parametrize("name, problem, limits", CASES, ids=[c[0] for c in CASES])
def test_limits_hold_everywhere_and_fewest_proved(name, problem, limits):
    rate = 10.0
    dt = 1.0 / rate
    unlimited = plan_time_optimal_zoh(problem, rate)
    r = plan_limited_zoh(problem, rate, limits, unlimited)
    check_every_limit(problem, r, limits)
    K = r.sampled.samples
    assert K >= unlimited.samples and r.added_time_s == pytest.approx((K - unlimited.samples) * dt)
    assert r.minimal and r.lower_bound_samples == K
    # independently: K - 1 samples infeasible even at the samples only, K and K + 1 feasible
    assert not feasible_state_space(problem, K - 1, dt, limits)
    assert feasible_state_space(problem, K, dt, limits)
    assert feasible_state_space(problem, K + 1, dt, limits)  # monotone: hold zero one more sample


@pytest.mark.parametrize("name, limits", [(c[0], c[2]) for c in CASES[:4]], ids=[c[0] for c in CASES[:4]])
def test_coarse_levels_windows_and_lifted_proofs(name, limits):
    """At 50 Hz (213 unlimited samples) the search runs a coarser level first, then
    windowed LPs; the fewest count is proved and K - 1 is independently infeasible."""
    problem = rest_to_rest(WB, 1.0, 1.0)
    rate = 50.0
    dt = 1.0 / rate
    r = plan_limited_zoh(problem, rate, limits, plan_time_optimal_zoh(problem, rate))
    assert len(r.extra["levels_hz"]) >= 2
    check_every_limit(problem, r, limits)
    K = r.sampled.samples
    assert r.minimal and r.lower_bound_samples == K
    assert r.extra["lower_bound_proof"].startswith((limit_proof.PROOF_DUAL, limit_proof.PROOF_HIGHS))
    assert not feasible_state_space(problem, K - 1, dt, limits)
    assert feasible_state_space(problem, K, dt, limits)


@pytest.mark.parametrize("ipm_samples, method", [(300, "dual simplex"), (0, "interior point")])
def test_last_resort_proof_is_the_full_feasibility_lp(monkeypatch, ipm_samples, method):
    """With every dual bound refused, the proof falls to HiGHS's verdict on the full LP, confirmed by
    the independent state-space formulation; the proof names both."""
    monkeypatch.setattr(limit_level, "proves_infeasible", lambda bound: False)
    monkeypatch.setattr(limit_lp, "IPM_SAMPLES", ipm_samples)
    problem = rest_to_rest(WB, 1.0, 1.0)
    rate = 50.0
    limits = Limits(deflection_max=(0.2,))
    r = plan_limited_zoh(problem, rate, limits, plan_time_optimal_zoh(problem, rate))
    K = r.sampled.samples
    assert r.minimal
    assert r.extra["lower_bound_proof"] == (
        f"{limit_proof.PROOF_HIGHS} ({method}, confirmed by an independent state-space LP (highs-ipm))"
    )
    assert not feasible_state_space(problem, K - 1, 1.0 / rate, limits)


def test_an_unconfirmed_infeasible_verdict_proves_nothing(monkeypatch):
    """If the independent formulation does not confirm HiGHS's "infeasible", K - 1 is not claimed
    impossible: the plan is returned, not proved fewest, and says so."""
    monkeypatch.setattr(limit_level, "proves_infeasible", lambda bound: False)
    monkeypatch.setattr(limit_level, "independent_feasible", lambda *a, **k: (None, "no verdict"))
    problem = rest_to_rest(WB, 1.0, 1.0)
    rate = 50.0
    limits = Limits(deflection_max=(0.2,))
    r = plan_limited_zoh(problem, rate, limits, plan_time_optimal_zoh(problem, rate))
    check_every_limit(problem, r, limits)
    assert not r.minimal and r.lower_bound_samples < r.sampled.samples
    assert r.extra["lower_bound_proof"] == limit_proof.PROOF_UNLIMITED


def test_an_undecided_lp_is_never_read_as_infeasible(monkeypatch):
    """HiGHS "Status 0: Not Set" on every method at one count: the search steps past it and the
    plan is still found; nothing is claimed about that count."""
    real = limit_lp.LimitLP._solve_once
    seen = {}

    def flaky(self, K, seg, mode, *args):
        if self.dt == 1.0 / 50.0 and mode == "scaled" and not seen.get(K):
            seen[K] = True
            raise limit_lp.LPUndecided(f"linear program at {K} samples undecided (HiGHS Status 0: Not Set)")
        return real(self, K, seg, mode, *args)

    monkeypatch.setattr(limit_lp.LimitLP, "_solve_once", flaky)
    problem = rest_to_rest(WB, 1.0, 1.0)
    limits = Limits(velocity_max=0.35)
    r = plan_limited_zoh(problem, 50.0, limits, plan_time_optimal_zoh(problem, 50.0))
    check_every_limit(problem, r, limits)
    assert seen


def test_a_coarse_level_that_cannot_steer_a_mode_is_skipped():
    """omega dt = 2 pi at the internal 10 Hz level of a 40 Hz plan: that level cannot reach
    the target; the planner skips it instead of failing (the user asked for 40 Hz)."""
    w2 = 2.0 * math.pi * 10.0
    model = ModalModel(b0=0.5, c=0.0, omega=[math.sqrt(2.0), w2], zeta=[0.0, 0.0], b=[1.0, 0.05])
    x0 = model.rest_state(0.0)
    x0[4] = 1e-4
    problem = state_to_rest(model, 1.0, x0, 1.0)
    limits = Limits(velocity_max=0.35)
    r = plan_limited_zoh(problem, 40.0, limits, plan_time_optimal_zoh(problem, 40.0))
    check_every_limit(problem, r, limits)
    assert r.minimal and r.extra["skipped_levels_hz"] == [10.0] and 10.0 not in r.extra["levels_hz"]
    assert r.extra["levels_hz"][-1] == 40.0


@pytest.mark.parametrize("rate, frac", [(4.0, 0.5), (4.0, 0.7), (5.0, 0.5)])
def test_deflection_between_samples_coarse_rate(rate, frac):
    """omega dt ~ 1.5: the deflection peaks between samples; cuts keep it within the limit."""
    model = ModalModel(b0=1.0, omega=[6.0], zeta=[0.0], b=[1.0])
    problem = rest_to_rest(model, 1.0, 1.0)
    unlimited = plan_time_optimal_zoh(problem, rate)
    limits = Limits(deflection_max=(frac * float(np.max(np.abs(unlimited.states[:, 2]))),))
    r = plan_limited_zoh(problem, rate, limits, unlimited)
    check_every_limit(problem, r, limits)
    assert r.cuts > 0  # the sampled-only solution would overshoot between samples
    assert r.peaks["deflection"][0] > r.peaks["deflection_at_samples"][0]
    K = r.sampled.samples
    assert feasible_state_space(problem, K, 1.0 / rate, limits, sub=1)
    assert not feasible_state_space(problem, r.lower_bound_samples - 1, 1.0 / rate, limits, sub=1) or not (
        feasible_state_space(problem, r.lower_bound_samples - 1, 1.0 / rate, limits, sub=50)
    )
    if r.minimal:  # a finer relaxation of the continuous limit confirms K - 1 is impossible
        assert not feasible_state_space(problem, K - 1, 1.0 / rate, limits, sub=50)


def test_each_limit_costs_time_and_together_at_least_the_worst():
    problem = rest_to_rest(WB, 1.0, 1.0)
    rate = 10.0
    unlimited = plan_time_optimal_zoh(problem, rate)
    both = Limits(0.35, (0.2,), 4.0)
    added = {n: plan_limited_zoh(problem, rate, both.only(n), unlimited).added_time_s for n in both.active}
    total = plan_limited_zoh(problem, rate, both, unlimited).added_time_s
    assert all(a > 0.0 for a in added.values())
    assert total >= max(added.values()) - 1e-12


def test_inactive_limits_cost_nothing():
    problem = rest_to_rest(WB, 1.0, 1.0)
    unlimited = plan_time_optimal_zoh(problem, 10.0)
    peak_v = float(np.max(np.abs(unlimited.states[:, 1])))
    r = plan_limited_zoh(problem, 10.0, Limits(velocity_max=2.0 * peak_v, slew_rate=1e6), unlimited)
    assert r.sampled.samples == unlimited.samples and r.added_time_s == 0.0 and r.minimal


def test_deflection_peaks_match_fine_simulation():
    rng = np.random.default_rng(3)
    dt = 0.3  # long intervals: several extrema inside some of them
    for _ in range(5):
        u = rng.uniform(-1.0, 1.0, 12)
        x0 = TWO.rest_state()
        x0[2:] = rng.normal(0.0, 0.1, 4)
        states = simulate_samples(TWO, x0, u, dt)
        peak, _ = deflection_peaks(TWO, states, u, dt)
        problem = type("P", (), {"model": TWO, "x0": x0})
        fine = fine_states(problem, u, dt, sub=3000).reshape(-1, TWO.n_states)
        for k in range(u.size):
            seg = fine[k * 3000 : (k + 1) * 3000 + 1, 2::2]
            np.testing.assert_allclose(peak[k], np.max(np.abs(seg), axis=0), rtol=1e-6, atol=1e-12)
            assert np.all(peak[k] >= np.max(np.abs(seg), axis=0) * (1 - 1e-12))


# ------------------------------------------------------------ bad input
@pytest.mark.parametrize(
    "limits, name",
    [
        (Limits(velocity_max=-1.0), "limits.velocity_max"),
        (Limits(velocity_max=math.nan), "limits.velocity_max"),
        (Limits(slew_rate=0.0), "limits.slew_rate"),
        (Limits(deflection_max=(0.1, 0.2)), "limits.deflection_max"),
        (Limits(deflection_max=(-0.1,)), "limits.deflection_max[0]"),
    ],
)
def test_bad_limits_are_named(limits, name):
    with pytest.raises(FlexmotionError) as info:
        plan_limited_zoh(rest_to_rest(WB, 1.0, 1.0), 10.0, limits)
    assert info.value.parameter == name
    assert "got" in str(info.value)


def test_initial_state_outside_limit_is_rejected():
    with pytest.raises(GoalError, match="velocity_max"):
        plan_limited_zoh(motion_to_rest(WB, 1.0, 0.5), 10.0, Limits(velocity_max=0.3))


# ------------------------------------------------------------- properties
@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    w=st.floats(1.0, 4.0),
    z=st.floats(0.0, 0.08),
    b=st.floats(0.4, 1.2),
    gamma=st.floats(0.3, 1.5),
    v_frac=st.floats(0.5, 1.2),
    q_frac=st.floats(0.4, 1.2),
    slew=st.one_of(st.none(), st.floats(3.0, 20.0)),
)
def test_property_random_models_and_limits(w, z, b, gamma, v_frac, q_frac, slew):
    model = ModalModel(b0=1.0, omega=[w], zeta=[z], b=[b])
    problem = rest_to_rest(model, 1.0, gamma)
    rate = 8.0
    unlimited = plan_time_optimal_zoh(problem, rate)
    peak_v = float(np.max(np.abs(unlimited.states[:, 1])))
    peak_q = float(np.max(np.abs(unlimited.states[:, 2])))
    limits = Limits(v_frac * peak_v, (q_frac * peak_q,), slew)
    r = plan_limited_zoh(problem, rate, limits, unlimited)
    check_every_limit(problem, r, limits)
    # the planner's proofs include its cuts (deflection between samples): check them against a
    # relaxation of the continuous-time limit with 50 points per interval
    sub = 50 if r.cuts else 1
    assert not feasible_state_space(problem, r.lower_bound_samples - 1, 1.0 / rate, limits, sub=sub)
    if not r.minimal:
        assert r.lower_bound_samples < r.sampled.samples


# --------------------------------------------------------- method and CLI
def params(**extra):
    p = {
        "model.b0": 0.5,
        "model.omega": [math.sqrt(2.0)],
        "model.zeta": [0.0],
        "model.b": [1.0],
        "u_max": 1.0,
        "rate_hz": 10.0,
        "method": "limited",
    }
    p.update(extra)
    return p


def test_method_reports_added_time_per_limit():
    config = config_from_parameters(
        params(
            **{
                "limits.velocity_max": 0.35,
                "limits.deflection_max": [0.2],
                "limits.slew_rate": 4.0,
                "limits.report_each": True,
            }
        )
    )
    r = plan_move(config, rest_to_rest(config.model, 1.0, 1.0))  # no rate: the config's
    assert r.sampled.dt == pytest.approx(0.1) and "config.rate_hz" in r.info["rate_source"]
    assert set(r.info["added_time_by_limit_s"]) == {"velocity_max", "deflection_max", "slew_rate"}
    assert r.info["limited_minimal"] and r.summary()["method"] == "limited"


@pytest.mark.parametrize(
    "extra, name",
    [
        ({"limits.velocity_max": "fast"}, "limits.velocity_max"),
        ({"limits.deflection_max": [0.1, 0.1]}, "limits.deflection_max"),
        ({"limits.velocity": 1.0}, "limits.velocity"),
        ({"limits.report_each": "yes"}, "limits.report_each"),
    ],
)
def test_method_rejects_bad_options(extra, name):
    config = config_from_parameters(params(**extra))
    with pytest.raises(FlexmotionError) as info:
        plan_move(config, rest_to_rest(config.model, 1.0, 1.0))
    assert info.value.parameter == name


def test_cli_plan_limited(tmp_path, capsys):
    cfg = tmp_path / "p.yaml"
    cfg.write_text(
        "/**:\n  ros__parameters:\n    model: {b0: 0.5, c: 0.0, omega: [1.4142135623730951], zeta: [0.0], b: [1.0]}\n"
        "    u_max: 1.0\n    rate_hz: 10.0\n    method: limited\n    limits: {velocity_max: 0.35, slew_rate: 4.0}\n"
    )
    assert cli_main(["plan", "--config", str(cfg), "--goal", "1.0", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["method"] == "limited" and out["minimal"] and out["added_time_s"] > 0.0
    assert max(abs(v) for v in out["commands"]) <= 1.0
    assert cli_main(["plan", "--config", str(cfg), "--goal", "1.0", "--rate", "20"]) == 0
    assert "proved fewest" in capsys.readouterr().out
    cfg.write_text(cfg.read_text().replace("velocity_max: 0.35", "velocity_max: -1.0"))
    assert cli_main(["plan", "--config", str(cfg), "--goal", "1.0"]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and "limits.velocity_max" in captured.err


# ------------------------------------------------------------- issue 18
def test_issue18_false_infeasibility_verdict_is_gone():
    """Issue 18: the planner answered at once "no move within 854.1 s ... relax them" while an LP finds
    a 3,996-sample sequence.  (The secant on a flat t(K) jumped past the cap and the cap was read as
    "infeasible".)  Now: a plan, exact, within the limit, with K - 1 independently infeasible."""
    m = ModalModel(
        b0=0.11930123416053794,
        c=-0.9330000767975295,
        omega=(0.48405123695700303,),
        zeta=(0.0,),
        b=(-1.7198625344677871,),
    )
    u_max, v_max, rate = 2.361837356171406, 0.09474491637297387, 100.0
    problem = MoveProblem(m, u_max, [0.0, 0.0, 0.0, 0.0], -3.2277313633213436)
    config = PlannerConfig(model=m, u_max=u_max, method="limited", options={"limits.velocity_max": v_max})
    result = plan_move(config, problem, rate)
    limits = Limits(velocity_max=v_max)
    check_every_limit(problem, result, limits)
    K = result.sampled.samples
    assert K <= 3996
    assert feasible_state_space(problem, K, 1.0 / rate, limits)
    if result.sampled.minimal:
        assert not feasible_state_space(problem, K - 1, 1.0 / rate, limits)


def test_no_sequence_passing_the_checks_claims_nothing(monkeypatch):
    """Every count's sequence fails the exact checks: a SolverError that says the limits are not proved
    impossible (it said "relax the limits")."""
    monkeypatch.setattr(limits_mod, "accept", lambda level, K: None)
    problem = rest_to_rest(WB, 1.0, 1.0)
    with pytest.raises(SolverError, match="exact limit checks.*not proved impossible"):
        plan_limited_zoh(problem, 10.0, Limits(velocity_max=0.35))


def test_long_damped_move_arrives_exactly():
    """Fuzz case 151 (seed 18): a 93 s move of a damped rigid body (c = -0.23) with two modes 5 % apart.
    The arrival correction's least squares rounded relative to one state column 1e12 times the others:
    1.3e-9 final-state error, refused ("misses the target"; before that, no plan within the budget).
    Now each arrival equation is normalised: a plan, exact, within the limit."""
    m = ModalModel(
        b0=0.8556491346854,
        c=-0.2338665978886646,
        omega=(0.6083236199109882, 0.63701141698677, 13.479365278338069, 35.124076020761365),
        zeta=(0.05063420113830525, 0.1048320215454662, 0.037552156564034274, 0.29435509474432764),
        b=(-0.38833098404556043, 1.7216795109368483, 1.7111336368227488, 1.6824866806542151),
    )
    u_max, v_max, goal = 4.243276719611286, 13.029147033019365, -1121.4881575117977
    problem = MoveProblem(m, u_max, [0.0] * m.n_states, goal)
    config = PlannerConfig(model=m, u_max=u_max, method="limited", options={"limits.velocity_max": v_max})
    result = plan_move(config, problem, 100.0)
    check_every_limit(problem, result, Limits(velocity_max=v_max))
    assert result.sampled.final_state_error_relative < 1e-12


def test_badly_scaled_arrival_rows_get_a_verdict():
    """Fuzz case 28 (seed 18): a 265 s move of a damped rigid body, two modes 40 % apart: "HiGHS gave no
    verdict at 3 sample counts" (one arrival row 1e12 times the others; HiGHS's tolerances are
    absolute).  Now the rows are normalised: a plan, exact, within the limit; a claimed fewest count is
    checked by the independent state-space LP."""
    m = ModalModel(
        b0=0.1380565468473009,
        c=-0.46144127653335243,
        omega=(0.4905040860494634, 0.6862065419410069, 5.2852468037356655, 55.412242688386854),
        zeta=(0.027761447224889633, 0.1494031940840644, 0.0974433059551008, 0.22680268612968493),
        b=(1.3827724132867911, -0.2054694783495512, 0.32576812132024635, -0.4942858830202297),
    )
    u_max, v_max, goal = 0.8395705666294575, 0.11450737490058648, 64.99040184468467
    problem = MoveProblem(m, u_max, [0.0] * m.n_states, goal)
    config = PlannerConfig(model=m, u_max=u_max, method="limited", options={"limits.velocity_max": v_max})
    result = plan_move(config, problem, 100.0)
    u = result.sampled.commands  # 57,176 samples: checked at the samples (the fine check takes 11 s); under
    # a constant command the rigid body's velocity is monotone between samples
    states = simulate_samples(m, problem.x0, u, 0.01)
    assert np.max(np.abs(states[-1] - m.rest_state(goal))) <= 1e-9 * abs(goal)
    assert np.max(np.abs(u)) <= u_max
    assert np.max(np.abs(states[:, 1])) <= v_max
    assert result.sampled.samples * 0.01 >= abs(goal) / v_max  # the limit alone needs this long
    if result.sampled.minimal:
        assert not feasible_state_space(problem, result.sampled.samples - 1, 0.01, Limits(velocity_max=v_max))


def test_limits_broken_at_once_are_proved_impossible():
    """A mode swinging too hard to be held within its deflection limit whatever the command: the
    verdict names the proof; the independent LP agrees at several horizons."""
    x0 = WB.rest_state(0.0)
    x0[3] = 3.0  # q' = 3: with u = -u_max the deflection still reaches -0.5 + (0.25 + 4.5) ** 0.5 = 1.68
    problem = state_to_rest(WB, 1.0, x0, 1.0)
    limits = Limits(deflection_max=(1.0,))
    with pytest.raises(GoalError, match="proved") as info:
        plan_limited_zoh(problem, 10.0, limits)
    assert info.value.parameter == "limits.deflection_max"
    for K in (20, 80, 320):
        assert not feasible_state_space(problem, K, 0.1, limits)


def test_nothing_found_and_nothing_proved_is_not_called_impossible(monkeypatch):
    """A cap reached without a proof is a solver failure that says so, never "relax the limits"."""
    monkeypatch.setattr(limits_mod, "MAX_FACTOR", 1)
    monkeypatch.setattr(limits_mod, "SOFT_FACTOR", 1)
    monkeypatch.setattr(limits_mod, "FULL_SAMPLES", 10**6)  # one level
    problem = rest_to_rest(WB, 1.0, 1.0)  # 0.1 m/s needs 10 s: far beyond 43 + 20 samples at 10 Hz
    unlimited = plan_time_optimal_zoh(problem, 10.0)
    monkeypatch.setattr(limits_mod, "CAP_EXTRA", 20)
    with pytest.raises(SolverError, match="not proved impossible") as info:
        plan_limited_zoh(problem, 10.0, Limits(velocity_max=0.1), unlimited)
    assert not isinstance(info.value, GoalError)


def test_a_spent_planning_budget_claims_nothing(monkeypatch):
    """Issue 18: past ``TIME_BUDGET_S`` the search stops with a SolverError that names the budget and
    says the limits are not proved impossible (never "relax them"), through ``plan_move`` too."""
    monkeypatch.setattr(limits_mod, "TIME_BUDGET_S", 0.0)
    problem = rest_to_rest(WB, 1.0, 1.0)  # 0.1 m/s binds: the search must run
    config = PlannerConfig(model=WB, u_max=1.0, method="limited", options={"limits.velocity_max": 0.1})
    with pytest.raises(SolverError, match="planning budget.*not proved impossible") as info:
        plan_move(config, problem, 10.0)
    assert "\n" not in str(info.value)


def test_windows_do_not_free_a_chattering_limit_arc():
    """The next level's windows come from the smoothest sequence, in window LPs too.

    Riding a deflection limit, an LP vertex chatters between two levels; taken as the
    reference structure, every chattering stretch was freed at the next level, four times
    longer (bench/fuel_limits.py's 2 m move: 936 free samples at 1 kHz, seconds per LP).
    At 250 Hz the final window LP had 381 free samples before, 261 now; the plan is
    still exact, within every limit, and proved fewest (checked independently).
    """
    problem = rest_to_rest(WB, 1.0, 2.0)
    rate = 250.0
    dt = 1.0 / rate
    unlimited = plan_time_optimal_zoh(problem, rate)
    peak_q = float(np.max(np.abs(unlimited.states[:, 2])))
    limits = Limits(deflection_max=(0.6 * peak_q,))
    r = plan_limited_zoh(problem, rate, limits, unlimited)
    assert r.extra["levels_hz"] == [15.625, 62.5, 250.0]
    assert r.extra["free_samples"] < 300
    check_every_limit(problem, r, limits)
    K = r.sampled.samples
    assert r.minimal and r.lower_bound_samples == K
    assert not feasible_state_space(problem, K - 1, dt, limits)


def _bench_limits(problem, rate):
    """bench/fuel_limits.py's all-three limits: 0.8 x the unlimited velocity peak, 0.6 x its deflection peak, 10 N/s."""
    unlimited = plan_time_optimal_zoh(problem, rate)
    peak_v = float(np.max(np.abs(unlimited.states[:, 1])))
    peak_q = float(np.max(np.abs(unlimited.states[:, 2])))
    return unlimited, Limits(0.8 * peak_v, (0.6 * peak_q,), 10.0)


def test_accepted_lp_in_the_levels_own_windows():
    """The accepted smooth LP is solved in the final level's own windows, not the first probe's wider ones.

    The bench's all-three move at 500 Hz: the first probe at ``K`` has 592 free samples (windows mapped
    from 125 Hz); the accepted LP on main had them too, now 284 (the windows of the ``K - 1`` probe).
    The count, its proof and the exactness are unchanged (2798 samples on main as now).
    """
    problem = rest_to_rest(WB, 1.0, 2.0)
    rate = 500.0
    unlimited, limits = _bench_limits(problem, rate)
    r = plan_limited_zoh(problem, rate, limits, unlimited)
    assert r.extra["accepted_free_samples"] < 0.6 * r.extra["free_samples"]
    assert r.sampled.samples == 2798
    assert r.minimal and r.lower_bound_samples == 2798
    assert r.extra["lower_bound_proof"] == "weak-duality bound"
    check_every_limit(problem, r, limits)


def test_accepted_lp_falls_back_to_the_probes_windows(monkeypatch):
    """Own windows in which the smooth LP has no solution leave the plan to the probe's windows, as before."""
    problem = rest_to_rest(WB, 1.0, 2.0)
    rate = 250.0
    unlimited, limits = _bench_limits(problem, rate)
    before = plan_limited_zoh(problem, rate, limits, unlimited)
    tried = []

    def one_run(level, K):  # every sample but the ends at one level: the target cannot be reached
        tried.append(K)
        return Segments.from_runs(K, [(1, K - 1, 0.0)])

    monkeypatch.setattr(accept_mod, "narrow_segments", one_run)
    r = plan_limited_zoh(problem, rate, limits, unlimited)
    assert tried == [before.sampled.samples]
    assert r.sampled.samples == before.sampled.samples and r.minimal == before.minimal
    assert r.extra["accepted_free_samples"] == r.extra["free_samples"]
    np.testing.assert_array_equal(r.sampled.commands, before.sampled.commands)
    check_every_limit(problem, r, limits)


@pytest.mark.parametrize("guess", ["none", "own"])
def test_scaled_lp_leaves_out_rows_far_from_their_limit(monkeypatch, guess):
    """A scaled window LP includes the knot and command rows only where a reference solution came near the
    limit (:data:`.lp.LAZY_KEEP`); every row it left out and the solution violates is added and the LP
    solved again.  Same ``t`` as with every row, fewer rows, and every limit within ``t`` at every sample
    on the exact simulation -- from a reference that predicts no row at all, and from the LP's own optimum.
    """
    problem = rest_to_rest(WB, 1.0, 2.0)
    rate = 62.5
    dt = 1.0 / rate
    _unlimited, limits = _bench_limits(problem, rate)
    K = 349
    every = limit_lp.LimitLP(problem, dt, limits)
    opt = every.solve(K)  # every sample free: every row
    seg = map_runs(solution_runs(opt, every.um, every.slew), K, K, 4)
    assert seg.n_free < K
    sizes = []
    real = limit_lp.solve_lp

    def spy(**kw):
        sizes.append(kw["A_ub"].shape[0])
        return real(**kw)

    monkeypatch.setattr(limit_lp, "solve_lp", spy)
    monkeypatch.setattr(limit_lp, "LAZY_KEEP", -1.0)  # every row
    full = every.solve(K, seg)
    n_full = sizes[-1]
    monkeypatch.setattr(limit_lp, "LAZY_KEEP", 0.5)
    lp = limit_lp.LimitLP(problem, dt, limits)
    lp.profile = every.profile if guess == "own" else (K, K * dt, np.zeros(K), [np.zeros(K + 1) for _ in lp.blocks])
    sizes.clear()
    sol = lp.solve(K, seg)
    assert sizes[0] < 0.8 * n_full
    if guess == "none":
        assert len(sizes) >= 2  # the rows it violated were added
    else:
        assert max(sizes) < 0.8 * n_full
    assert sol.t == pytest.approx(full.t, rel=1e-9, abs=0.0)
    u = sol.u
    assert np.max(np.abs(u)) <= problem.u_max * sol.t * (1 + 1e-9)
    states = simulate_samples(problem.model, problem.x0, u, dt)
    tol = sol.t * (1 + 1e-7)
    assert np.max(np.abs(states[:, 1])) <= limits.velocity_max * tol
    assert np.max(np.abs(states[:, 2])) <= limits.deflection_max[0] * tol
    steps = np.abs(np.diff(np.concatenate([[0.0], u, [0.0]])))
    assert np.max(steps) <= limits.slew_rate * dt * tol


def test_no_verdict_with_rows_left_out_is_decided_with_every_row(monkeypatch):
    """A scaled LP without a verdict when rows are left out is solved again with every row: the
    plan is the one found without leaving rows out, and no count is stepped past."""
    problem = rest_to_rest(WB, 1.0, 2.0)
    rate = 62.5
    unlimited, limits = _bench_limits(problem, rate)
    monkeypatch.setattr(limit_lp, "LAZY_KEEP", -1.0)  # every row included: the plan as before
    every_row = plan_limited_zoh(problem, rate, limits, unlimited)
    monkeypatch.setattr(limit_lp, "LAZY_KEEP", 0.5)
    real = limit_lp.LimitLP._solve_once
    refused = []

    def no_verdict_when_lazy(self, K, seg, mode, extra, t_fix=None, warm=None, lazy=None, point=None):
        if lazy is not None:
            refused.append(K)
            raise limit_lp.LPUndecided(f"linear program at {K} samples undecided (HiGHS: Unknown)")
        return real(self, K, seg, mode, extra, t_fix, warm, lazy, point)

    monkeypatch.setattr(limit_lp.LimitLP, "_solve_once", no_verdict_when_lazy)
    r = plan_limited_zoh(problem, rate, limits, unlimited)
    assert refused
    assert r.sampled.samples == every_row.sampled.samples
    assert r.minimal == every_row.minimal and r.lower_bound_samples == every_row.lower_bound_samples
    np.testing.assert_array_equal(r.sampled.commands, every_row.sampled.commands)
    check_every_limit(problem, r, limits)
