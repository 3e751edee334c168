"""Issue 15's tail, third pass: root isolation whose work follows the modes still ringing.

Case 1310 of ``bench/fuzz.py`` (seed 15; 4 modes, a moving start stopped by
a weak actuator): the optimum has 259 switches over 311 s, set by a
2.57 rad/s mode that barely decays (``zeta`` = 0.0014), while the grid of
every exact co-state evaluation was spaced for the 16.9 rad/s mode
(``zeta`` = 0.29, rung out after 7 s) over the whole move: 12,849 points,
90 evaluations, the slowest N <= 4 plan of the fuzz set (0.44 s CPU).  The
root isolation's proof holds on any grid (its derivative bounds are local),
so :func:`~flexmotion_ros.core.time_optimal.switching.root_grid` grades the
spacing by the modes still ringing: ~2,300 points, the same roots, the same
certified optimum.

The certificate matched each proved zero to its nearest switch by a linear
scan per zero: quadratic in the switches (67,000 comparisons for 1310);
``certificate._nearest`` bisects, with the same choice (the first of equals).
"""

from __future__ import annotations

import numpy as np
from reference_solutions import bang_bang_final_error as _error

from flexmotion_ros.core import ModalModel, MoveProblem
from flexmotion_ros.core.simulation.modal_response import ModalResponse
from flexmotion_ros.core.time_optimal import solver, switching
from flexmotion_ros.core.time_optimal.certificate import _nearest
from flexmotion_ros.core.time_optimal.solver import plan_time_optimal
from flexmotion_ros.core.time_optimal.switching import isolate_roots, root_grid, sample_grid

CASE_1310 = (
    ModalModel(
        b0=1.944454706404683,
        c=0.0,
        omega=(1.540172732388395, 2.1227381228992948, 2.5724880484703605, 16.929877757058076),
        zeta=(0.03829105045708, 0.14460716114406244, 0.001372279343228311, 0.28606051514605685),
        b=(-0.7292425196300645, 0.327579664641902, -1.0830300013828125, 1.0901312706095703),
    ),
    0.2780299992906589,
    [0.0, 22.425313891165036, -57.13786460980659, -12.233906117689708, -5.229472932264401, -34.49816444169121,
     35.8538229972625, 43.08526759358572, 0.8001808033155842, -4.8649417886225805],
    197.79516249109668,
)  # fmt: skip
T_1310 = 311.3609250605216


def test_a_chattering_stop_isolates_roots_on_the_modes_still_ringing(monkeypatch, spy):
    model, u_max, x0, target = CASE_1310
    problem = MoveProblem(model, u_max, np.asarray(x0, dtype=float), target)
    sampled = spy(
        switching, "isolate_roots", lambda system, nu, T, grid=None, *a, **kw: -1 if grid is None else np.size(grid)
    )
    # the full solver alone: since wip/tail3 the fast path answers this stop (its root isolation is not counted here)
    monkeypatch.setattr(solver, "FAST_PATH", False)
    profile = plan_time_optimal(problem)
    assert profile.certified, profile.certificate.message
    assert _error(problem, profile) <= 1e-9
    assert profile.switch_times.size == 259
    assert abs(profile.duration - T_1310) <= 1e-12 * T_1310  # the same optimum
    # 90 exact evaluations of 12,849 points each (plus the certificate's) on 140fca2
    assert 0 < sum(sampled) < 500_000


def test_the_graded_root_grid_finds_the_same_roots_as_the_uniform_one():
    model, u_max, x0, target = CASE_1310
    system = ModalResponse(model)
    T = T_1310
    graded, uniform = root_grid(system, T), sample_grid(system, T)
    assert graded.size < 0.3 * uniform.size
    assert graded[0] == 0.0 and graded[-1] == T and np.all(np.diff(graded) > 0.0)
    assert root_grid(system, T) is graded  # memoised: the switching function's basis is cached by identity
    rng = np.random.default_rng(1310)
    for _ in range(3):  # co-states whose slow, lightly damped mode rings all along: hundreds of zeros
        nu = rng.normal(size=system.n) * np.array([1e-3, 1e-2, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.1, 0.1])
        a = isolate_roots(system, nu, T, graded)
        b = isolate_roots(system, nu, T, uniform)
        assert a.unproved == 0 and b.unproved == 0
        assert a.sign0 == b.sign0 and a.roots.size == b.roots.size > 50
        assert np.max(np.abs(a.roots - b.roots)) <= 1e-9 * T


def test_a_grid_with_nothing_to_grade_is_the_uniform_one():
    undamped = ModalModel(b0=1.0, c=0.0, omega=(1.0, 20.0), zeta=(0.0, 0.0), b=(1.0, 1.0))
    system = ModalResponse(undamped)
    assert root_grid(system, 300.0) is sample_grid(system, 300.0)


def test_zeros_are_matched_to_the_nearest_switch_the_first_of_equals():
    rng = np.random.default_rng(15)
    for _ in range(3000):
        switches = np.sort(np.round(rng.uniform(0.0, 5.0, rng.integers(0, 8)) * 2.0) / 2.0)  # repeats, ties
        zeros = np.round(rng.uniform(-1.0, 6.0, rng.integers(0, 8)) * 4.0) / 4.0
        scan = [min(range(switches.size), key=lambda j: abs(switches[j] - z)) if switches.size else -1 for z in zeros]
        assert _nearest(switches, zeros).tolist() == scan
