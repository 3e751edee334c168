"""Methods other than time_optimal on the fuzz cases of issue 15: a plan or a physical refusal, never a solver's.

Cases are ``bench/fuzz.py`` seed 15 at 100 Hz.  Every plan is checked here by an
independent propagation (``scipy.linalg.expm`` of the augmented matrix), not the
package's simulation.
"""

import numpy as np
import pytest
from scipy.linalg import expm

from flexmotion_ros.core import ModalModel
from flexmotion_ros.core.config import PlannerConfig
from flexmotion_ros.core.errors import InputError, SolverError
from flexmotion_ros.core.methods import fixed_time as fixed_time_method
from flexmotion_ros.core.methods import robust as robust_method
from flexmotion_ros.core.methods import shaped
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.model.boundary import MoveProblem
from flexmotion_ros.core.sampled import robust as sampled_robust
from flexmotion_ros.core.time_optimal.rigid_body import rigid_time
from flexmotion_ros.core.time_optimal.robust import RobustModalResponse

RATE = 100.0
# a 3-mode beam-like model at rest, a 1-unit move
BEAM = MoveProblem(
    ModalModel(b0=1.0, c=0.0, omega=(3.0, 9.0, 21.0), zeta=(0.02, 0.05, 0.1), b=(1.0, -0.7, 0.4)),
    2.0,
    [0.0] * 8,
    1.0,
)


def final_state_by_expm(problem: MoveProblem, u: np.ndarray, dt: float) -> np.ndarray:
    """State after the samples (forward order), one expm of the augmented matrix."""
    A, B = problem.model.A(), problem.model.B()
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n], M[:n, n] = A, B
    E = expm(M * dt)
    x = np.asarray(problem.x0, float)
    for uk in u:
        x = E[:n, :n] @ x + E[:n, n] * uk
    return x


def assert_sampled_plan_exact(problem: MoveProblem, result) -> None:
    s = result.sampled
    assert s is not None and s.samples > 0
    assert np.max(np.abs(s.commands)) <= problem.u_max * (1.0 + 1e-12)
    xf = final_state_by_expm(problem, s.commands, s.dt)
    target = np.zeros_like(xf)
    target[0] = problem.target
    excursion = np.max(np.abs(s.states - s.states[-1]), axis=0)
    assert np.all(np.abs(xf - target) <= 1e-8 * np.maximum(excursion, 1e-300) + 1e-300)


@pytest.mark.parametrize("method", ["zv", "ei"])
def test_a_shaper_plans_when_the_time_optimal_planner_refuses(method, monkeypatch):
    """Fuzz case 561 (8 modes): ``zv`` was refused with the time-optimal planner's work-budget
    message, though a shaped move needs ``T*`` only for its figures; the rigid-body bound stands in."""

    def refuse(move, *args, **kwargs):
        raise SolverError("time-optimal planner did not converge within its work budget")

    monkeypatch.setattr(shaped, "plan_time_optimal", refuse)
    config = PlannerConfig(model=BEAM.model, u_max=BEAM.u_max, method=method, options={})
    result = plan_move(config, BEAM, RATE)
    assert_sampled_plan_exact(BEAM, result)
    T_rigid = rigid_time(BEAM.model, BEAM.u_max, BEAM.shifted_initial(), BEAM.include_position)
    assert result.info["time_optimal_duration"] == pytest.approx(T_rigid, rel=1e-12)
    assert "rigid-body minimum time" in result.info["time_optimal_note"]
    assert result.sampled.lower_bound_samples >= 1


def augmented_final_state(problem: MoveProblem, u: np.ndarray, dt: float, order: int) -> tuple[np.ndarray, np.ndarray]:
    """Final augmented state (nominal and frequency derivatives) by expm, and its largest excursion per state."""
    system = RobustModalResponse(problem.model, order, problem.include_position)
    A, B = system.A(), system.B()
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n], M[:n, n] = A, B
    E = expm(M * dt)
    x = system.augment(problem.shifted_initial())
    peak = np.abs(x)
    for uk in u:
        x = E[:n, :n] @ x + E[:n, n] * uk
        peak = np.maximum(peak, np.abs(x))
    return x, peak


def test_robust_plans_sampled_when_the_continuous_robust_solver_finds_nothing(monkeypatch):
    """Fuzz cases 216, 721, 937 (6-8 modes, 100 Hz): the continuous robust solver missed the target
    ("relative augmented final-state error 1.0") and the method refused; at a rate the sampled robust
    move comes from the linear programs alone, the robust constraints exact."""

    def miss(*args, **kwargs):
        raise SolverError("robust time-optimal planner missed the target: relative augmented final-state error 1")

    monkeypatch.setattr(robust_method, "plan_robust_time_optimal", miss)
    config = PlannerConfig(model=BEAM.model, u_max=BEAM.u_max, method="robust_time_optimal", options={})
    result = plan_move(config, BEAM, RATE)
    assert_sampled_plan_exact(BEAM, result)
    s = result.sampled
    xa, peak = augmented_final_state(BEAM, s.commands, s.dt, 1)
    assert np.all(np.abs(xa) <= 1e-8 * np.maximum(peak, 1e-300) + 1e-300)
    assert "no continuous robust move" in result.info["continuous_note"]
    # the count: no fewer than the nominal time-optimum's, and proved fewest when the LPs prove it
    assert s.samples * s.dt >= result.info["time_optimal_duration"]
    assert s.lower_bound_samples <= s.samples
    # without a rate there is nothing to fall back on: the refusal stays
    with pytest.raises(SolverError, match="missed the target"):
        plan_move(config, BEAM, None)


def test_fixed_time_plans_sampled_when_the_time_optimal_planner_refuses(monkeypatch):
    """Fuzz case 775 (7 modes, moving start, 100 Hz): fixed_time was refused with the time-optimal
    planner's work-budget message; at a rate the least-peak LP at the requested sample needs no ``T*``."""

    def refuse(move, *args, **kwargs):
        raise SolverError("time-optimal planner did not converge within its work budget")

    monkeypatch.setattr(fixed_time_method, "plan_time_optimal", refuse)
    T_rigid = rigid_time(BEAM.model, BEAM.u_max, BEAM.shifted_initial(), BEAM.include_position)
    arrival = 3.0 * T_rigid + 2.0
    config = PlannerConfig(model=BEAM.model, u_max=BEAM.u_max, method="fixed_time", options={"arrival_time": arrival})
    result = plan_move(config, BEAM, RATE)
    assert_sampled_plan_exact(BEAM, result)
    assert result.sampled.samples == round(arrival * RATE)
    assert "no continuous fixed-time move" in result.info["continuous_note"]
    # an arrival the bound cannot make: refused naming arrival_time and the peak it would need
    early = PlannerConfig(
        model=BEAM.model, u_max=BEAM.u_max, method="fixed_time", options={"arrival_time": 1.05 * T_rigid}
    )
    with pytest.raises(InputError, match="arrival_time.*too early"):
        plan_move(early, BEAM, RATE)
    # without a rate there is nothing to fall back on: the refusal stays
    with pytest.raises(SolverError, match="work budget"):
        plan_move(config, BEAM, None)


def test_robust_sampled_only_search_is_bounded(monkeypatch):
    """Fuzz case 775 (7 modes, moving start): without a continuous robust move the full LPs ran at
    89,000-179,000 samples (7-11 s CPU each), past the fuzz's 30 s guard; past the bracket's cap the
    method refuses with the duration and count it would need instead."""

    def miss(*args, **kwargs):
        raise SolverError("robust time-optimal planner missed the target: relative augmented final-state error 1")

    monkeypatch.setattr(robust_method, "plan_robust_time_optimal", miss)
    monkeypatch.setattr(sampled_robust, "MAX_BRACKET_SAMPLES", 100)  # BEAM needs 296 samples at 100 Hz
    config = PlannerConfig(model=BEAM.model, u_max=BEAM.u_max, method="robust_time_optimal", options={})
    with pytest.raises(
        SolverError, match=r"lasts at least .* samples at 100 Hz, .*\(100 samples\) the sampled robust planner"
    ):
        plan_move(config, BEAM, RATE)
