"""The Pontryagin certificate refuses what is not the optimum (core.time_optimal.certificate).

The lean path returns a profile only if ``certify`` says ``OPTIMAL``; these
tests hold the certificate to refusing wrong candidates: the certified
optimum with one switch time moved (re-simulated exactly, the same co-state),
with a switch added or removed, or a level flipped.  Each perturbed
candidate is refused with the reason the perturbation makes; the
unperturbed one, re-certified the same way, passes (so the refusals are the
perturbation's, not the test's set-up).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings

from flexmotion_ros.core import plan_time_optimal
from flexmotion_ros.core.results import CertificateStatus
from flexmotion_ros.core.simulation.exact import PiecewiseConstant, simulate
from flexmotion_ros.core.simulation.prepared import prepare
from flexmotion_ros.core.time_optimal.certificate import certify
from flexmotion_ros.core.tolerances import SWITCH_TIME_RTOL

from .test_lean import small_problems
from .test_solver_properties import SETTINGS, describe
from .test_structure_guess import bench_move


def recertify(problem, profile, switch_times, levels):
    """Certify ``(switch_times, levels)`` on ``[0, T]`` with the optimum's co-state and exact states."""
    system = prepare(problem).response
    T = profile.duration
    u = PiecewiseConstant.from_switches(np.asarray(switch_times, float), np.asarray(levels, float), T)
    states = simulate((system.A(), system.B()), problem.shifted_initial(), u)
    nu = -np.asarray(profile.certificate.costate_final, float)
    return certify(system, nu, T, problem.u_max, np.asarray(switch_times, float), np.asarray(levels, float), states)


def moved(profile, k: int, rel: float) -> np.ndarray:
    """The switch times with switch ``k`` moved by ``rel`` of its shorter neighbouring interval.

    At least by ``100 SWITCH_TIME_RTOL T``: the certificate resolves switch
    times to ``SWITCH_TIME_RTOL T`` (a switch moved by less is the same
    switch to it; 1e-6 of a 1.7 ms interval of a 5 s move is 1.7e-9 s, below
    its 5e-9 s).
    """
    t = np.concatenate([[0.0], profile.switch_times, [profile.duration]])
    room = min(t[k + 1] - t[k], t[k + 2] - t[k + 1])
    out = profile.switch_times.copy()
    out[k] += np.sign(rel) * max(abs(rel) * room, 100.0 * SWITCH_TIME_RTOL * profile.duration)
    return out


BENCH = [
    pytest.param(bench_move(1, 1.0), id="beam-1-mode-1s"),
    pytest.param(bench_move(2, 0.25), id="beam-2-modes-0.25s"),
    pytest.param(bench_move(3, 1.0), id="beam-3-modes-1s"),
    pytest.param(bench_move(3, 5.0), id="beam-3-modes-5s"),
]


@pytest.mark.parametrize("problem", BENCH)
@pytest.mark.parametrize("rel", [1e-6, -1e-3, 0.2])
def test_a_moved_switch_time_is_refused(problem, rel):
    profile = plan_time_optimal(problem)
    assert profile.certificate.status is CertificateStatus.OPTIMAL
    same = recertify(problem, profile, profile.switch_times, profile.levels)
    assert same.status is CertificateStatus.OPTIMAL, same.message  # the set-up passes unperturbed
    for k in range(profile.switch_times.size):
        cert = recertify(problem, profile, moved(profile, k, rel), profile.levels)
        assert cert.status is not CertificateStatus.OPTIMAL, (k, rel)
        assert not cert.passed
        assert "not zero at a switch" in cert.message or "not switches" in cert.message, cert.message


@pytest.mark.parametrize("problem", BENCH)
def test_a_dropped_or_an_added_switch_is_refused(problem):
    profile = plan_time_optimal(problem)
    sw, lv, T = profile.switch_times, profile.levels, profile.duration
    # the last switch dropped: the last two intervals merged at the earlier level
    cert = recertify(problem, profile, sw[:-1], lv[:-1])
    assert not cert.passed and cert.status is CertificateStatus.FAILED, cert.message
    # a narrow pulse added in the middle of the longest interval
    k = int(np.argmax(np.diff(np.concatenate([[0.0], sw, [T]]))))
    a = (sw[k - 1] if k else 0.0) + 0.4 * (np.diff(np.concatenate([[0.0], sw, [T]]))[k])
    pulse = np.sort(np.concatenate([sw, [a, a + 1e-3 * T]]))
    levels = np.concatenate([lv[: k + 1], [-lv[k]], lv[k:]])
    cert = recertify(problem, profile, pulse, levels)
    assert not cert.passed and cert.status is CertificateStatus.FAILED, cert.message
    # one level flipped
    flipped = lv.copy()
    flipped[0] = -flipped[0]
    cert = recertify(problem, profile, sw, flipped)
    assert not cert.passed and "levels do not follow" in cert.message, cert.message


@settings(max_examples=15, **SETTINGS)
@given(small_problems())
def test_on_random_models_a_moved_switch_is_refused(problem):
    """Random 1-3-mode moves: the certified optimum passes re-certification, every switch moved by 1e-4 fails."""
    profile = plan_time_optimal(problem)
    note = describe(problem)
    if profile.certificate.status is not CertificateStatus.OPTIMAL or profile.switch_times.size == 0:
        return  # nothing to perturb (a rigid or gap-certified answer)
    same = recertify(problem, profile, profile.switch_times, profile.levels)
    assert same.status is CertificateStatus.OPTIMAL, (same.message, note)
    for k in range(profile.switch_times.size):
        cert = recertify(problem, profile, moved(profile, k, 1e-4), profile.levels)
        assert cert.status is not CertificateStatus.OPTIMAL, (k, cert.message, note)
