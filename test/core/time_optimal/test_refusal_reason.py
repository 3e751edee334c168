"""A refusal after the full solver's work budget names what the user can act on (issue 15's tail).

Fuzz case 721 (seed 15; 8 modes, a moving start) is refused by the
continuous time-optimal planner after ~1200 exact co-state evaluations.  On
9dfd8b4 the refusal said only that ("did not converge within its work
budget ... no switch structure it found reaches the target"); it now also
states the proved lower bound (the rigid body's minimum time), the smoothed
problems' estimate of the optimum, and a method that plans such a move:
``fixed_time`` at a sample rate (linear programs, no continuous optimum),
which this test runs.
"""

from __future__ import annotations

import numpy as np
import pytest
from reference_solutions import expm_pieces

from flexmotion_ros.core import ModalModel
from flexmotion_ros.core.config import PlannerConfig
from flexmotion_ros.core.errors import SolverError
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.model.boundary import state_to_rest
from flexmotion_ros.core.time_optimal.rigid_body import rigid_time
from flexmotion_ros.core.time_optimal.solver import plan_time_optimal

MODEL_721 = ModalModel(
    b0=0.1549485004082035,
    c=-0.2808625017546501,
    omega=(1.4396936862370857, 2.551441646627411, 3.4791596872792514, 5.023028735410522, 6.308125283393046,
           7.813409048666002, 50.080827258561705, 58.3068405281527),
    zeta=(0.1494681773152575, 0.06553607257465843, 0.19273315233186208, 0.120021219750253, 0.2656406140306579,
          0.11189598468103625, 0.010049770349716103, 0.2743012562151086),
    b=(1.7130347804444166, 1.9951326728351926, -1.4990762655449608, -1.2136055169994155, 0.1719167185780175,
       0.2871846687617243, 1.4665398962001712, 1.2655976608238848),
)  # fmt: skip
U_MAX_721 = 0.4553807113451472
X0_721 = [0.0, 8.098633164688038e-05, -0.000657966060735998, 0.0008506872289862525, 0.00013271922882193525,
          -0.0001213600225779204, 3.4467222314741906e-05, 0.00013947943591365974, -2.483090621908013e-05,
          -0.0001496221502326426, 1.703874202821389e-06, 1.8010404926405764e-06, -1.327037558338439e-06,
          -3.7634794596438336e-05, -5.085336815186024e-08, -1.1548054682669344e-05, -3.0881343553426073e-07,
          1.5522083348863433e-05]  # fmt: skip
TARGET_721 = -7.865416368449286e-05


def _problem():
    return state_to_rest(MODEL_721, U_MAX_721, np.array(X0_721), TARGET_721)


def test_a_refusal_after_the_work_budget_names_the_bound_and_a_method_that_plans():
    problem = _problem()
    T_rigid = rigid_time(problem.model, problem.u_max, problem.shifted_initial(), problem.include_position)
    try:
        profile = plan_time_optimal(problem)
    except SolverError as exc:
        text = str(exc)
        assert "work budget" in text
        assert f"at least {T_rigid:.6g} s" in text  # the proved lower bound
        assert "fixed_time" in text  # what plans it
        return
    # the planner may one day find it: then it must be right
    assert profile.certified, profile.certificate.message
    assert profile.duration >= T_rigid * (1.0 - 1e-12)


@pytest.mark.parametrize("rate", [100.0])
def test_the_method_the_refusal_names_plans_the_move(rate):
    problem = _problem()
    config = PlannerConfig(
        model=MODEL_721, u_max=U_MAX_721, method="fixed_time", options={"arrival_time": 4.466164724567655}
    )
    result = plan_move(config, problem, rate)
    s = result.sampled
    u = np.asarray(s.commands, float)
    assert np.all(np.abs(u) <= U_MAX_721)
    X = expm_pieces(problem, np.full(u.size, s.dt), u)  # own expm propagation
    target = MODEL_721.rest_state(TARGET_721)
    dev = X - target
    scale = np.maximum(np.max(np.abs(dev), axis=0), 1e-300)
    assert float(np.max(np.abs(dev[-1]) / scale)) <= 1e-8
