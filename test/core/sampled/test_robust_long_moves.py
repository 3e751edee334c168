"""robust_time_optimal without a continuous robust move: a move too long to search is refused by its physics.

Fuzz seed 15 cases 257 and 775 (``bench/fuzz_cases.py --method robust_time_optimal``): the
continuous robust solver spent its work budget, and the sampled one refused naming only its
30,000-sample cap.  Both moves last longer than 300 s (the nominal time optimum, a proved lower
bound); the refusal now says so: the move's duration, its samples at the rate and the fastest
mode's half periods over it.
"""

import pytest

from flexmotion_ros.core import ModalModel
from flexmotion_ros.core.errors import SolverError
from flexmotion_ros.core.model.boundary import MoveProblem
from flexmotion_ros.core.sampled import robust as sampled_robust
from flexmotion_ros.core.simulation.prepared import prepare

# a damped rigid body (c = -0.55: top speed b0 u_max / |c|, 14.9 units/s) and a 56 rad/s mode
# (the shape of case 257); 23,500 units take over 1,500 s
LONG = MoveProblem(
    ModalModel(b0=0.858352771931907, c=-0.5525611025993602, omega=(55.99723342266528,), zeta=(0.29,), b=(1.57,)),
    9.58533724439333,
    [0.0] * 4,
    -23531.587150331296,
)


def test_a_move_past_the_search_is_refused_by_its_duration(monkeypatch):
    calls = []
    monkeypatch.setattr(sampled_robust, "bracket_samples", lambda *a: calls.append(a))
    with pytest.raises(SolverError, match=r"lasts at least 1580 s .*158000 samples at 100 Hz.*half periods"):
        sampled_robust.plan_robust_time_optimal_zoh(prepare(LONG), None, 1, 100.0, lower_duration=1580.0)
    assert not calls  # refused up front: no linear program


def test_the_message_is_one_line_with_the_physics():
    text = sampled_robust.too_long_without_continuous((1.0, 56.0), 400.0, 100.0)
    assert "\n" not in text
    assert "400 s" in text and "40000 samples at 100 Hz" in text and "300 s" in text
