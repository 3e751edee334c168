"""Fixed arrival time on the fuzz cases of issue 15 that refused or repeated full solves.

Cases are ``bench/fuzz.py`` seed 15 (``arrival_time = 1.5 T_rigid + 2 pi / omega_1``).
Each answer is checked by an independent matrix-exponential propagation.
"""

import numpy as np
from scipy.linalg import expm

from flexmotion_ros.core import ModalModel
from flexmotion_ros.core.model.boundary import MoveProblem
from flexmotion_ros.core.time_optimal import fixed_time as fixed_time_module
from flexmotion_ros.core.time_optimal import fixed_time_bound
from flexmotion_ros.core.time_optimal.fixed_time import plan_fixed_time

# fuzz case 308: a damped rigid body (c = -0.73), three damped modes up to 41 rad/s
CASE_308 = MoveProblem(
    ModalModel(
        b0=0.32977512033416856,
        c=-0.7269789304759836,
        omega=(0.3885724754487565, 13.11575337705462, 41.343437456926225),
        zeta=(0.1076872243608046, 0.25469100656596305, 0.29787590361781824),
        b=(-1.446419158172112, 1.1201653803344989, 1.3681187543812499),
    ),
    0.21702225163098915,
    [0.0] * 8,
    -12.630159808672287,
)
ARRIVAL_308 = 211.47226844108818
# fuzz case 5: a 42 rad/s mode on a 105-167 s move; the switch structure changes on the way
CASE_5 = MoveProblem(
    ModalModel(
        b0=0.12992078421112643,
        c=0.0,
        omega=(0.50321229986878, 41.849429410265415),
        zeta=(0.07378698476457203, 0.0159258001385847),
        b=(-1.4496945632219609, -1.8419256297881814),
    ),
    2.9389120897170047,
    [0.0] * 6,
    -1014.1433264160019,
)
ARRIVAL_5 = 167.09641151615685


def _check_by_expm(problem: MoveProblem, prof, arrival: float) -> None:
    """Arrives at rest at ``arrival`` within the bound, by expm of the augmented matrix per piece."""
    assert prof.duration == arrival
    assert np.all(np.abs(prof.levels) <= problem.u_max)
    A, B = problem.model.A(), problem.model.B()
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n], M[:n, n] = A, B
    target = problem.model.rest_state(problem.target)
    x = np.append(np.asarray(problem.x0, float), 0.0)
    breaks = np.concatenate([[0.0], prof.switch_times, [arrival]])
    peak = np.abs(x[:n] - target)
    for h, level in zip(np.diff(breaks), prof.levels):
        x[n] = level
        x = expm(M * h) @ x
        peak = np.maximum(peak, np.abs(x[:n] - target))
    assert np.max(np.abs(x[:n] - target) / np.maximum(peak, 1e-300)) <= 1e-8


def test_a_valid_request_is_planned_and_certified():
    """Before: "fixed-time planner missed the target" (the root-find's structure polished, unchecked)."""
    prof = plan_fixed_time(CASE_308, ARRIVAL_308)
    assert prof.certified
    assert prof.extra["bound_used"] < CASE_308.u_max
    _check_by_expm(CASE_308, prof, ARRIVAL_308)


def test_the_bound_search_does_not_repeat_full_solves(monkeypatch):
    """Warm-started regula falsi, each near structure tried at the arrival: 18 full solves before."""
    calls = []
    original = fixed_time_module.plan_time_optimal

    def counted(*args, **kwargs):
        calls.append(kwargs.get("warm_start") is not None)
        return original(*args, **kwargs)

    monkeypatch.setattr(fixed_time_module, "plan_time_optimal", counted)
    monkeypatch.setattr(fixed_time_bound, "plan_time_optimal", counted)  # the bound search's solves
    prof = plan_fixed_time(CASE_5, ARRIVAL_5)
    assert prof.certified
    _check_by_expm(CASE_5, prof, ARRIVAL_5)
    assert len(calls) <= 12
