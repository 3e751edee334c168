"""The lean variant of the fast path (core.time_optimal.lean) gives the general solver's certified optimum.

The lean path is a speed-up only: whatever it returns went through the same
exact matrix-exponential final-state check and Pontryagin certificate as
every other path (``assembly.assemble``), and it must be the same optimum as
the solver without it (``time_optimal.LEAN_PATH = False``: the fast path,
then the full solver): duration and switch times to 1e-9 of ``T``, levels
equal.  Where it finds nothing, the planner goes on unchanged.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import event, example, given, settings
from hypothesis import strategies as st

from flexmotion_ros.core import ModalModel, motion_to_rest, plan_time_optimal, rest_to_rest, state_to_rest
from flexmotion_ros.core.simulation.modal_response import ModalResponse
from flexmotion_ros.core.time_optimal import assembly, lean, structure_guess
from flexmotion_ros.core.time_optimal import solver as time_optimal

from .test_solver_properties import (
    MIN_SEPARATION,
    SETTINGS,
    check_continuous,
    describe,
    log_uniform,
    natural_velocity,
    signs,
    units,
)
from .test_structure_guess import assert_same_optimum, bench_move

WB = ModalModel(b0=0.5, c=0.0, omega=(math.sqrt(2.0),), zeta=(0.0,), b=(1.0,))


def general_solver(problem, monkeypatch):
    """The planner without the lean path (the fast path, then the full solver)."""
    with monkeypatch.context() as m:
        m.setattr(time_optimal, "LEAN_PATH", False)
        return plan_time_optimal(problem)


def took_lean(profile) -> bool:
    return profile.extra.get("fast_path_stage") == "lean"


# ------------------------------------------------------------- property
@st.composite
def small_models(draw):
    """1-3 modes, as the planner's property tests draw them (omega 0.3..30 rad/s, zeta 0..0.3, friction or not)."""
    n = draw(st.integers(1, 3))
    w = [draw(log_uniform(0.3, 30.0))]
    for _ in range(n - 1):
        w.append(w[-1] * draw(st.floats(MIN_SEPARATION, 4.0)))
    undamped = draw(st.booleans())
    zeta = [0.0 if undamped else draw(st.floats(0.0, 0.3, allow_subnormal=False)) for _ in w]
    b = [draw(signs) * draw(log_uniform(0.1, 10.0)) for _ in w]
    b0 = draw(signs) * draw(log_uniform(0.1, 10.0))
    c = -w[0] * draw(log_uniform(1e-2, 3.0)) if draw(st.booleans()) else 0.0
    return ModalModel(b0=b0, c=c, omega=tuple(w), zeta=tuple(zeta), b=tuple(b))


@st.composite
def small_problems(draw):
    """Rest to rest, motion to rest or any state to rest, moves 1e-3..1e3 of the natural scale."""
    model = draw(small_models())
    u_max = draw(log_uniform(0.1, 10.0))
    size = draw(log_uniform(1e-3, 1e3))
    kind = draw(st.sampled_from(["rest", "motion", "state"]))
    if kind == "rest":
        return rest_to_rest(model, u_max, draw(signs) * model.natural_distance(u_max) * size)
    if kind == "motion":
        return motion_to_rest(model, u_max, draw(signs) * natural_velocity(model, u_max) * size)
    x0 = np.zeros(model.n_states)
    x0[1] = draw(units) * natural_velocity(model, u_max) * size
    for i, (w, b) in enumerate(zip(model.omega, model.b)):
        static = abs(b) * u_max / w**2
        x0[2 + 2 * i] = draw(units) * static * size
        x0[3 + 2 * i] = draw(units) * static * w * size
    if not np.any(x0):
        x0[1] = natural_velocity(model, u_max) * size
    target = draw(units) * model.natural_distance(u_max) * size
    return state_to_rest(model, u_max, x0, target)


@settings(max_examples=30, **SETTINGS)
@given(small_problems())
@example(  # the independent gap's Brent stalled on a cell's zero at rounding level (local seed 27)
    rest_to_rest(
        ModalModel(
            b0=-3.2982570602919163,
            c=0.0,
            omega=(0.29999999999999993, 0.6899999999999998),
            zeta=(0.0, 0.0),
            b=(-1.8465416709342615, -1.2341276516626916),
        ),
        1.0,
        36.647300621038205,
    )
)
def test_lean_path_and_general_solver_give_the_same_certified_optimum(problem):
    saved = time_optimal.LEAN_PATH
    try:
        time_optimal.LEAN_PATH = True
        with_lean = plan_time_optimal(problem)
        time_optimal.LEAN_PATH = False
        general = plan_time_optimal(problem)
    finally:
        time_optimal.LEAN_PATH = saved
    event(f"lean path taken: {took_lean(with_lean)}")
    note = describe(problem)
    assert "fast_path_error" not in with_lean.extra, (with_lean.extra["fast_path_error"], note)
    check_continuous(problem, with_lean)  # independent expm check, signs, proved optimality
    assert general.certified, note
    assert_same_optimum(with_lean, general)


# ------------------------------------------------------------- examples
@pytest.mark.parametrize(
    "problem",
    [
        pytest.param(rest_to_rest(WB, 1.0, 1.0), id="wie-bernstein"),
        pytest.param(bench_move(1, 1.0), id="beam-1-mode-1s"),
        pytest.param(bench_move(2, 0.25), id="beam-2-modes-0.25s"),
        pytest.param(bench_move(2, 5.0), id="beam-2-modes-5s"),
        pytest.param(bench_move(3, 1.0), id="beam-3-modes-1s"),
        pytest.param(bench_move(3, 5.0), id="beam-3-modes-5s"),
        pytest.param(motion_to_rest(WB, 1.0, 1.5), id="wie-bernstein-motion-to-rest"),
    ],
)
def test_lean_path_is_taken_on_the_benchmark_moves(problem, monkeypatch):
    profile = plan_time_optimal(problem)
    assert took_lean(profile), profile.extra
    assert profile.certificate.status is time_optimal.CertificateStatus.OPTIMAL
    assert_same_optimum(profile, general_solver(problem, monkeypatch))


def test_a_candidate_that_misses_the_target_is_not_returned(monkeypatch):
    """A lean Newton result off by 1e-6 in T fails the exact final-state check: the fast path answers."""
    problem = bench_move(2, 1.0)
    general = general_solver(problem, monkeypatch)
    real = lean.refine

    def off(*args, **kw):
        ok, tau, nuh, T, r = real(*args, **kw)
        return ok, tau, nuh, T * (1.0 + 1e-6), r

    monkeypatch.setattr(time_optimal, "lean_refine", off)
    profile = plan_time_optimal(problem)
    assert not took_lean(profile)
    assert_same_optimum(profile, general)


def test_an_uncertified_candidate_is_not_returned(monkeypatch):
    """With every certificate failing, the lean path returns nothing (only the full solver answers, uncertified)."""
    problem = bench_move(1, 1.0)
    real = assembly.certify
    calls = []

    def failing(*args, **kw):
        cert = real(*args, **kw)
        calls.append(cert)
        return type(cert)(**{**cert.__dict__, "passed": False, "sign_consistent": False, "message": "sabotaged"})

    monkeypatch.setattr(assembly, "certify", failing)
    profile = plan_time_optimal(problem)
    assert calls[0].message == "ok"  # the lean path's first candidate was the optimum ...
    assert not took_lean(profile)  # ... yet, its certificate failing, the lean path returned nothing
    assert profile.extra["solver_path"] == time_optimal.SolverPath.FULL
    assert not profile.certified


def test_a_crash_in_the_lean_path_falls_back_and_is_recorded(monkeypatch):
    problem = bench_move(2, 1.0)
    general = general_solver(problem, monkeypatch)

    def broken(*args, **kw):
        raise ZeroDivisionError("bug")

    monkeypatch.setattr(time_optimal, "smoothed_guess", broken)
    profile = plan_time_optimal(problem)
    assert not took_lean(profile)
    assert "ZeroDivisionError" in profile.extra["fast_path_error"]
    assert_same_optimum(profile, general)


def test_long_moves_are_left_to_the_fast_path():
    """Beyond MAX_POINTS grid points the lean path does not start."""
    model = ModalModel(b0=1.0, omega=(60.0,), zeta=(0.0,), b=(1.0,))
    problem = rest_to_rest(model, 0.1, 2e3)
    lm = lean.LeanMove(ModalResponse(model, True), problem.shifted_initial(), 0.1, 1.0)
    T_rigid = 2.0 * math.sqrt(2e3 / 0.1)
    assert lm.grid_points(T_rigid) > lean.MAX_POINTS
    profile = plan_time_optimal(problem)
    assert not took_lean(profile) and profile.certified


def test_models_with_more_modes_are_left_to_the_fast_path():
    problem = bench_move(lean.MAX_MODES + 1, 0.25)
    profile = plan_time_optimal(problem)
    assert problem.model.n_modes > lean.MAX_MODES
    assert not took_lean(profile) and profile.extra["solver_path"] == time_optimal.SolverPath.FAST


def test_more_switches_than_the_dense_limit_are_refused_at_once():
    lm = lean.LeanMove(ModalResponse(WB, True), np.array([-1.0, 0.0, 0.0, 0.0]), 1.0, 4.0)
    roots = np.linspace(0.01, 3.9, lean.DENSE_UP_TO + 2)
    ok, tau, _, T, r = lean.refine(lm, roots, 1.0, np.ones(4), 4.0)
    assert not ok and r == math.inf and tau is roots and T == 4.0 and lm.evaluations == 0


# ------------------------------------------------------------- structure guess
def test_near_zero_thresholds_are_the_time_optimal():
    assert (lean.NEAR_ZERO, lean.VERY_NEAR_ZERO) == (structure_guess.NEAR_ZERO, structure_guess.VERY_NEAR_ZERO)


def test_structure_from_samples_finds_sign_changes_and_near_zero_pairs():
    tau = np.linspace(0.0, 4.0, 401)
    # two sign changes (at 1 and 3) and a dip to 1e-4 of the maximum at 2 (a blip the smoothing rounded off)
    S = (tau - 1.0) * (tau - 3.0) * ((tau - 2.0) ** 2 + 1e-4)
    roots, sign0 = lean.structure_from_samples(tau, S, 4)
    assert sign0 == 1.0
    assert roots.size == 4
    np.testing.assert_allclose(roots[[0, 3]], [1.0, 3.0], atol=1e-3)
    h = 0.25 * (tau[1] - tau[0])
    np.testing.assert_allclose(roots[1:3], [2.0 - h, 2.0 + h], atol=1e-12)


def test_structure_from_samples_without_sign_changes_or_dips():
    tau = np.linspace(0.0, 1.0, 11)
    roots, sign0 = lean.structure_from_samples(tau, -(1.0 + tau), 2)
    assert roots.size == 0 and sign0 == -1.0
    roots, sign0 = lean.structure_from_samples(tau, np.zeros(11), 2)
    assert roots.size == 0 and sign0 == 1.0


def _refine_runs(problem, monkeypatch):
    """The plan, and each top-level lean Newton run: ``(switches in, evaluations, switches out, ok)``."""
    runs = []
    real = lean.refine

    def recording(lm, roots, sign0, nuh, T, *args, **kwargs):
        before = lm.evaluations
        ok, tau, nuh_r, T_r, rn = real(lm, roots, sign0, nuh, T, *args, **kwargs)
        runs.append((roots.size, lm.evaluations - before, tau.size, bool(ok)))
        return ok, tau, nuh_r, T_r, rn

    monkeypatch.setattr(time_optimal, "lean_refine", recording)
    return plan_time_optimal(problem), runs


def test_a_closing_blip_is_merged_instead_of_halved(monkeypatch):
    """3 modes, 1 m: the guess has a pair that closes; Newton halved its gap 25 times (to 1.7e-12 T), now merges it."""
    problem = bench_move(3, 1.0)
    profile, runs = _refine_runs(problem, monkeypatch)
    assert took_lean(profile) and profile.certificate.status is time_optimal.CertificateStatus.OPTIMAL
    assert runs[0][0] == 9 and runs[0][2] == 7 and runs[0][3], runs
    assert runs[0][1] <= 15, runs  # was 26 evaluations
    monkeypatch.undo()
    assert_same_optimum(profile, general_solver(problem, monkeypatch))


def test_a_pair_that_full_steps_carry_past_itself_is_merged(monkeypatch):
    """3 modes, 5 s: the certificate's zeros give 11 switches, a pair of which full steps kept crossing.

    Halved steps crawled 44 evaluations and failed (then the structure edit's 9-switch run converged in 4);
    merged after :data:`~.switch_newton.MERGE_AFTER` blocked steps, the same run converges.
    """
    problem = bench_move(3, 5.0)
    profile, runs = _refine_runs(problem, monkeypatch)
    assert took_lean(profile) and profile.certificate.status is time_optimal.CertificateStatus.OPTIMAL
    assert all(ok for *_, ok in runs), runs
    assert sum(e for _, e, _, _ in runs) <= 25, runs  # was 5 + 44 + 4
    monkeypatch.undo()
    assert_same_optimum(profile, general_solver(problem, monkeypatch))
