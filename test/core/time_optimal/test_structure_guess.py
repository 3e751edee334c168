"""The guess-Newton-certify fast path of ``plan_time_optimal`` (core.structure_guess).

It must be taken on simple moves (that is what makes the planner fast), and
it must give the same certified optimum as the full solver, to the
certificate's precision (the two converge from different starts, so the
last bits differ: durations and switch times agree to 1e-9 relative to
``T``), whenever it is taken, or its guess is wrong, or it is sabotaged.
The full solver is run by switching the fast path off
(``time_optimal.FAST_PATH``).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from flexmotion_ros.core import (
    ModalModel,
    chain,
    motion_to_rest,
    plan_time_optimal,
    rest_to_rest,
)
from flexmotion_ros.core.time_optimal import assembly, costate_solver, structure_guess
from flexmotion_ros.core.time_optimal import solver as time_optimal

WB = ModalModel(b0=0.5, c=0.0, omega=[np.sqrt(2.0)], zeta=[0.0], b=[1.0])
DAMPED = ModalModel(b0=1.0, c=-0.3, omega=[3.0, 7.0], zeta=[0.1, 0.05], b=[0.8, -0.5])


def beam(n_modes: int) -> ModalModel:
    """The benchmark's lumped flexible link (bench/planner_latency.py)."""
    return chain([0.5] * (n_modes + 1), [400.0] * n_modes, [0.4] * n_modes, force_on=0).model


def bench_move(n_modes: int, rigid_time: float):
    """bench/planner_latency.py's move: the distance a rigid body covers in ``rigid_time`` (10 N)."""
    model = beam(n_modes)
    return rest_to_rest(model, 10.0, abs(model.b0) * 10.0 * rigid_time**2 / 4.0)


def full_solver(problem, monkeypatch):
    with monkeypatch.context() as m:
        m.setattr(time_optimal, "FAST_PATH", False)
        return plan_time_optimal(problem)


#: Relative (to ``T``) agreement of two certified optima: durations and switch
#: times (a 4-mode undamped motion-to-rest differed by 6.9e-10 T, both certified).
SAME_RTOL = 1e-9


def assert_same_optimum(fast, full):
    assert fast.certified and full.certified, (fast.certificate.message, full.certificate.message)
    assert fast.certificate.message == "ok"
    tol = SAME_RTOL * full.duration
    assert abs(fast.duration - full.duration) <= tol
    assert fast.switch_times.shape == full.switch_times.shape
    assert np.max(np.abs(fast.switch_times - full.switch_times), initial=0.0) <= tol
    assert np.array_equal(fast.levels, full.levels)
    assert fast.final_state_error_relative <= time_optimal.FINAL_STATE_RTOL


SIMPLE = [
    pytest.param(rest_to_rest(WB, 1.0, 1.0), id="wie-bernstein"),
    pytest.param(rest_to_rest(WB, 1.0, 1e-3), id="wie-bernstein-tiny-move"),
    pytest.param(rest_to_rest(WB, 1.0, 10.0), id="wie-bernstein-blip-at-mid-move"),
    pytest.param(rest_to_rest(beam(1), 10.0, 2.5), id="beam-1-mode"),
    pytest.param(rest_to_rest(beam(2), 10.0, 1.667), id="beam-2-modes"),
    pytest.param(rest_to_rest(beam(3), 10.0, 1.25), id="beam-3-modes"),
    pytest.param(rest_to_rest(DAMPED, 2.0, 30.0), id="damped-2-modes-7-switches"),
    pytest.param(motion_to_rest(DAMPED, 2.0, 1.5), id="damped-motion-to-rest"),
]


@pytest.mark.parametrize("problem", SIMPLE)
def test_fast_path_is_taken_and_gives_the_full_solvers_optimum(problem, monkeypatch):
    fast = plan_time_optimal(problem)
    assert fast.extra["solver_path"] == "fast"
    full = full_solver(problem, monkeypatch)
    assert full.extra["solver_path"] == "full"
    assert_same_optimum(fast, full)


def test_a_wrong_structure_guess_is_corrected():
    """3-mode beam, long move: the smoothed co-state has 7 sign changes, the optimum 9.

    The first converged extremal is rejected by the certificate (extra sign
    changes), the structure is corrected from its proved zeros, and only
    then is a candidate accepted.
    """
    p = plan_time_optimal(rest_to_rest(beam(3), 10.0, 31.25))
    assert p.extra["solver_path"] == "fast"
    assert p.extra["fast_path_candidates"] >= 2
    assert p.switch_times.size == 9


@pytest.mark.parametrize(
    ("problem", "candidates"),
    [
        # the smoothed co-state rounds off two very narrow blips (pairs of
        # switches 1e-4 s apart): a Newton failure drops one pair, and the
        # certificate's zeros put both back, one correction at a time; the
        # corrected structures have as many switches as the first guess
        # (13), which must not be mistaken for a cycle
        pytest.param(bench_move(5, 1.0), 3, id="beam-5-modes-narrow-blips"),
        # the first guess misplaces a blip and adds spurious pairs: only the
        # finer-smoothing second guess leads to the optimum (19 switches)
        pytest.param(bench_move(8, 5.0), 1, id="beam-8-modes-second-guess"),
    ],
)
def test_hard_benchmark_moves_take_the_fast_path(problem, candidates, monkeypatch):
    """bench/planner_latency.py: 5 modes, 0.833 m (1 s rigid) and 8 modes, 13.9 m (5 s rigid)."""
    fast = plan_time_optimal(problem)
    assert fast.extra["solver_path"] == "fast"
    assert fast.extra["fast_path_candidates"] >= candidates
    full = full_solver(problem, monkeypatch)
    assert full.extra["solver_path"] == "full"
    assert_same_optimum(fast, full)


def test_without_the_second_guess_the_full_solver_runs(monkeypatch):
    """The 8-mode move needs the finer-smoothing guess (else this test is vacuous)."""
    monkeypatch.setattr(time_optimal, "FINE_SMOOTHING", 0.0)
    p = plan_time_optimal(bench_move(8, 5.0))
    assert p.extra["solver_path"] == "full"
    assert p.certified


@pytest.mark.parametrize(
    "problem",
    [
        pytest.param(rest_to_rest(WB, 1.0, 1.0), id="wie-bernstein"),
        pytest.param(rest_to_rest(beam(2), 10.0, 41.67), id="beam-2-modes-long"),
        pytest.param(rest_to_rest(DAMPED, 2.0, 0.01), id="damped-small-move"),
    ],
)
@pytest.mark.parametrize(
    "bad_guess",
    [
        pytest.param(lambda sh, nuh, T: (np.empty(0), 1.0), id="no-switch"),
        pytest.param(lambda sh, nuh, T: (np.array([0.5 * T]), -1.0), id="one-switch-wrong-sign"),
        pytest.param(lambda sh, nuh, T: (np.linspace(0.1, 0.9, 11) * T, 1.0), id="eleven-switches"),
    ],
)
def test_a_wrong_guess_still_returns_the_certified_optimum(problem, bad_guess, monkeypatch):
    full = full_solver(problem, monkeypatch)
    monkeypatch.setattr(structure_guess, "guess_structure", bad_guess)
    p = plan_time_optimal(problem)
    # a wrong guess is corrected or rejected by the certificate, never a crash
    assert "fast_path_error" not in p.extra, p.extra["fast_path_error"]
    assert p.certified, p.certificate.message
    tol = SAME_RTOL * full.duration
    assert abs(p.duration - full.duration) <= tol
    assert np.max(np.abs(p.switch_times - full.switch_times), initial=0.0) <= tol


@pytest.mark.parametrize(
    ("module", "name"),
    [
        pytest.param(time_optimal, "newton_from_guess", id="newton_from_guess"),
        pytest.param(structure_guess, "guess_structure", id="guess_structure"),
        pytest.param(structure_guess, "refine_switches", id="refine_switches"),
    ],
)
def test_a_failing_fast_path_falls_back_to_the_full_solver(module, name, monkeypatch):
    """A bug in the fast path costs time, not the answer, and is recorded in ``extra``."""
    problem = rest_to_rest(beam(2), 10.0, 1.667)
    full = full_solver(problem, monkeypatch)
    assert "fast_path_error" not in full.extra

    def broken(*args, **kwargs):
        raise FloatingPointError("sabotaged")

    monkeypatch.setattr(module, name, broken)
    # the lean path has its own guess and Newton (test_lean.py sabotages those): this is the fast path's
    monkeypatch.setattr(time_optimal, "LEAN_PATH", False)
    p = plan_time_optimal(problem)
    assert p.extra["solver_path"] == "full"
    assert p.extra["fast_path_error"] == repr(FloatingPointError("sabotaged"))
    assert p.duration == full.duration
    assert np.array_equal(p.switch_times, full.switch_times)
    assert np.array_equal(p.levels, full.levels)
    assert p.certified


def test_a_working_fast_path_records_no_error():
    p = plan_time_optimal(rest_to_rest(beam(2), 10.0, 1.667))
    assert p.extra["solver_path"] == "fast"
    assert p.extra["fast_path_candidates"] >= 1
    assert "fast_path_error" not in p.extra
    assert p.to_dict()["solver_path"] == "fast"


def test_an_uncertified_candidate_is_never_returned_by_the_fast_path(monkeypatch):
    """A candidate whose certificate fails is rejected even if it hits the target."""
    problem = rest_to_rest(beam(1), 10.0, 2.5)
    full = full_solver(problem, monkeypatch)
    real = assembly.certify

    def failing(*args, **kwargs):
        return dataclasses.replace(real(*args, **kwargs), passed=False, message="sabotaged")

    calls = []

    def spy(*args, **kwargs):
        calls.append(1)
        # the fast path's candidates fail; the full solver's (after the fast path gave up) pass
        return failing(*args, **kwargs) if plan_state["fast"] else real(*args, **kwargs)

    plan_state = {"fast": True}
    real_solve = time_optimal.solve_costate

    def solve(*args, **kwargs):
        plan_state["fast"] = False
        return real_solve(*args, **kwargs)

    monkeypatch.setattr(assembly, "certify", spy)
    monkeypatch.setattr(time_optimal, "solve_costate", solve)
    p = plan_time_optimal(problem)
    assert len(calls) >= 2  # the fast path's candidate was certified (and rejected)
    assert p.extra["solver_path"] == "full"
    assert p.certified and abs(p.duration - full.duration) <= SAME_RTOL * full.duration


def test_the_fast_path_gives_up_beyond_max_switches(monkeypatch):
    """Wie-Bernstein's optimum has 3 switches: with a limit of 2 the fast path declines."""
    problem = rest_to_rest(WB, 1.0, 1.0)
    calls = []
    real = structure_guess.refine_switches

    def spy(sh, roots, *args, **kwargs):
        calls.append(roots.size)
        return real(sh, roots, *args, **kwargs)

    monkeypatch.setattr(structure_guess, "refine_switches", spy)
    monkeypatch.setattr(time_optimal, "MAX_SWITCHES", 2)
    monkeypatch.setattr(costate_solver, "MAX_SWITCHES", 2)
    p = plan_time_optimal(problem)
    assert p.extra["solver_path"] == "full"
    assert "fast_path_error" not in p.extra
    assert all(size <= 2 for size in calls)  # no Newton run on a structure over the limit
    assert p.certified and p.switch_times.size == 3
    monkeypatch.setattr(time_optimal, "MAX_SWITCHES", 3)
    monkeypatch.setattr(costate_solver, "MAX_SWITCHES", 3)
    assert plan_time_optimal(problem).extra["solver_path"] == "fast"
