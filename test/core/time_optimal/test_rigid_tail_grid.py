"""The smoothed warm start's grid on a long move of a damped rigid body (``c < 0``; issue 15's tail).

``smoothed_dual.graded_grid`` spaced the rigid body's terms ``e^{c tau}`` by ``1 / (8 |c|)`` over the
whole move, long after they had decayed: on a long cruise (fuzz seed 15, case 1476: 8 modes, a
2,285 s move, ``c = -0.89``) the rigid tail was most of the grid, the graded grid no shorter than half
the uniform one, and the warm start sampled 27,536 points per smoothed solve (0.3 s of the 0.33 s
plan).  Past ``tau = SMOOTH_DECAY / |c|`` the rigid part of ``S`` is a constant to rounding: the grid
there needs no more points than a rung-out mode's stretch.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from reference_solutions import bang_bang_final_error as _error

from flexmotion_ros.core import ModalModel, MoveProblem
from flexmotion_ros.core.simulation.modal_response import ModalResponse
from flexmotion_ros.core.time_optimal.smoothed_dual import SMOOTH_DECAY, graded_grid
from flexmotion_ros.core.time_optimal.solver import plan_time_optimal

CASE_1476 = (
    ModalModel(
        b0=0.17209962460978365,
        c=-0.8893578700066656,
        omega=(0.3094881733299056, 0.6443425616757277, 1.0656415953841631, 1.318933817077685, 3.276423094738827,
               3.767767206724623, 10.300398334300217, 19.580386665345134),
        zeta=(0.09995156438112253, 0.2825267168283219, 0.28242109699961765, 0.08233041522826333,
              0.10152471599156317, 0.23959085133801872, 0.22833913958455937, 0.249886305231089),
        b=(1.6296082843981456, 0.7155029221935305, 0.3318043434660772, 1.194190946504807, -1.3806471627259247,
           0.5822209530392644, 1.418697467983781, 1.1023619774588465),
    ),
    0.11976083145150399,
    52.71401652953469,
)  # fmt: skip
#: Its certified optimum on b4affa1 (fast path), s.
T_1476 = 2285.2019697522524


def test_a_long_cruise_of_a_damped_rigid_body_samples_only_where_something_rings(spy):
    model, u_max, target = CASE_1476
    problem = MoveProblem(model, u_max, np.zeros(model.n_states), target)
    sampled = spy(ModalResponse, "expm_B", lambda self, tau: np.size(tau))
    profile = plan_time_optimal(problem)
    assert profile.certified, profile.certificate.message
    assert _error(problem, profile) <= 1e-9
    assert abs(profile.duration - T_1476) <= 1e-12 * T_1476  # the same optimum
    assert 0 < sum(sampled) < 10_000  # 111,601 on b4affa1: the rigid tail at 1 / (8 |c|) over all 2,285 s


@settings(max_examples=40, deadline=None)
@given(
    c=st.floats(-1.0, -0.05),
    zeta=st.floats(0.02, 0.3),
    omega=st.floats(0.5, 60.0),
    stretch=st.floats(1.5, 50.0),
)
def test_the_graded_grid_past_every_decay_does_not_grow_with_the_move(c, zeta, omega, stretch):
    system = ModalResponse(ModalModel(b0=1.0, c=c, omega=(omega,), zeta=(zeta,), b=(1.0,)))
    decayed = SMOOTH_DECAY / min(-c, zeta * omega)  # past it, e^{c tau} and the mode are below rounding
    T = 1.01 * decayed
    short, long = graded_grid(system, T, 2.0), graded_grid(system, stretch * T, 2.0)
    assert short is not None and long is not None
    assert long[0] == 0.0 and long[-1] == stretch * T and np.all(np.diff(long) > 0.0)
    assert long.size == short.size  # the same stretches; the last one longer, not denser
