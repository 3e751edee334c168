"""A blip of switches the certificate cannot resolve is not certified; the planner finds the optimum without it.

Found by ``test_warm_start`` (cold vs warm-started replans from a state on a
nominal optimum): the cold planner answered with the optimum's switches plus a
blip near the end, LONGER than a feasible profile, yet certified "ok" with a
sign margin of 1e-9..1e-13 (before this fix, measured):

* ``seed82`` (lean path): 7 switches instead of 5, the last two 9e-6 and 3e-6 s
  before ``T``; 1.2e-4 (relative) longer; margin 1.3e-9;
* ``seed245`` (full solver): 6 switches instead of 3, a cluster within
  1.6e-4 s of ``T``; 1.5e-4 longer; margin 2.4e-13;
* ``seed42`` (1 mode, lean): 3 switches instead of 2, the last 3.3e-8 s
  before ``T``; 6.3e-8 longer; margin 2.2e-8;
* ``seed24`` (full solver): a switch at ``t = 1.1e-15`` s (an interval below
  what the times resolve), margin 2.6e-15.

Pontryagin's conditions are sufficient for these linear systems, so a truly
certified extremal cannot be longer than a feasible profile: the certificate
took a sign test near the end as proof although the final-state error could
hide a shorter move there (``certificate.end_gap``).  The expected optimum
here is the warm start's (exact-checked, margin 5e-3..0.3).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import null_space

from flexmotion_ros.core import ModalModel, plan_time_optimal, state_to_rest
from flexmotion_ros.core.results import CertificateStatus
from flexmotion_ros.core.simulation.exact import PiecewiseConstant, simulate
from flexmotion_ros.core.simulation.prepared import prepare
from flexmotion_ros.core.time_optimal.certificate import certify
from flexmotion_ros.core.tolerances import FINAL_STATE_RTOL

CASES = [
    pytest.param(
        ModalModel(
            b0=-1.0871872224233787,
            c=-21.06769986619367,
            omega=(15.370824097887672, 26.010122393233065, 102.51704986787355),
            zeta=(0.0, 0.0, 0.0),
            b=(-7.553423405869417, -0.4080151197438815, 8.023125525749988),
        ),
        0.14384582638379045,
        [
            3.393767781660758e-06,
            0.003037420733601662,
            -0.00011796776164621817,
            0.02120992796333208,
            -1.1771140474160136e-05,
            0.0013949380679328287,
            -0.0001159400378208945,
            0.03222847729404836,
        ],
        1.733489786239688e-05,
        0.10655518639813548,
        5,
        id="seed82",
    ),
    pytest.param(
        ModalModel(
            b0=-0.18671573780591064,
            c=-1.878564048984007,
            omega=(2.596288194070193, 3.6012590605378, 4.991987967868903),
            zeta=(0.0, 0.0, 0.0),
            b=(0.9738107533940485, 0.34323198804936095, -0.2951979348161408),
        ),
        0.20333080977395215,
        [
            0.007840766821469372,
            0.005538557953167349,
            -0.005798618773223491,
            0.030703583293358684,
            6.226508947372957e-05,
            0.005516596744909796,
            -0.002496299880075016,
            -0.015539606116500326,
        ],
        0.014790523792160929,
        1.324579968134877,
        3,
        id="seed245",
    ),
    pytest.param(
        ModalModel(
            b0=-3.3287363915578387,
            c=0.0,
            omega=(2.2640089232390777,),
            zeta=(0.20921040871780916,),
            b=(-0.15429601005519727,),
        ),
        0.18039615030067863,
        [-0.068467320860686, -0.013637837657715729, -0.0016816078117689876, 0.004765438110547839],
        -0.07418125090209529,
        1.0493891344379382,
        2,
        id="seed42",
    ),
    pytest.param(
        ModalModel(
            b0=4.372547428025101,
            c=0.0,
            omega=(1.9385449961415255, 5.322229861011162),
            zeta=(0.16926375222907522, 0.17090619315252056),
            b=(5.600580738988844, 3.054573230369429),
        ),
        0.6604671387721048,
        [
            41.08321247942151,
            4.959860978580226,
            -2.428389876459769,
            -0.5157642671573974,
            -0.08950771049584011,
            -0.036114130844476316,
        ],
        45.44112448402998,
        1.9492587919925568,
        2,
        id="seed24",
    ),
]


@pytest.mark.parametrize(("model", "u_max", "x0", "target", "T_opt", "n_switches"), CASES)
def test_the_cold_planner_answers_with_the_optimum_not_a_blip(model, u_max, x0, target, T_opt, n_switches):
    profile = plan_time_optimal(state_to_rest(model, u_max, np.array(x0), target))
    cert = profile.certificate
    assert cert.status is CertificateStatus.OPTIMAL and cert.message == "ok", cert.message
    assert profile.switch_times.size == n_switches, (profile.switch_times, profile.duration)
    assert abs(profile.duration - T_opt) <= 1e-9 * T_opt, (profile.duration, T_opt)
    assert profile.final_state_error_relative <= FINAL_STATE_RTOL
    widths = np.diff(np.concatenate([[0.0], profile.switch_times, [profile.duration]]))
    assert np.min(widths) > 1e-6 * profile.duration  # no interval the times cannot resolve
    assert cert.min_margin > 1e-4


def test_the_certificate_does_not_pass_the_old_blip():
    # seed42's old cold answer: the optimum's 2 switches plus one 3.3e-8 s before T, 6.3e-8 (relative)
    # longer than the optimum; with 1 mode (4 states) and 3 switches its co-state is unique (up to scale):
    # S = 0 at the 3 switches.  The old certificate passed it ("ok", margin 2.2e-8).
    model, u_max, x0, target = CASES[2].values[:4]
    problem = state_to_rest(model, u_max, np.array(x0), target)
    T = 1.0493892007011083
    switch_times = np.array([0.27036366154027447, 0.7837026610446518, 1.0493891675695237])
    levels = u_max * np.array([-1.0, 1.0, -1.0, 1.0])
    move = prepare(problem)
    system = move.response
    eye = np.eye(system.n)
    rows = np.stack([system.switching(eye[i], T - switch_times) for i in range(system.n)], axis=1)
    nu = null_space(rows)[:, 0]
    if np.sign(system.switching(nu, np.array([T - 0.5 * switch_times[0]]))[0]) != np.sign(levels[0]):
        nu = -nu
    u = PiecewiseConstant.from_switches(switch_times, levels, T)
    states = simulate((system.A(), system.B()), problem.shifted_initial(), u)
    assert np.max(np.abs(states[-1])) <= 1e-9  # it does reach the target: only the proof is at stake
    cert = certify(system, nu, T, u_max, switch_times, levels, states)
    assert cert.status is not CertificateStatus.OPTIMAL, cert.message
    assert not cert.passed or cert.lower_bound <= 1.0493891344379382  # never a bound above the true optimum
