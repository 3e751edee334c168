"""A refusal after the full solver's work budget names what the user can act on (issue 15's tail).

Fuzz case 2265 (seed 15; 8 modes, from rest, a 0.3 mm move) is refused by
the continuous time-optimal planner after ~1200 exact co-state evaluations.
On 9dfd8b4 the refusal said only that ("did not converge within its work
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
from flexmotion_ros.core.time_optimal.fallbacks import refusal_reason
from flexmotion_ros.core.time_optimal.rigid_body import rigid_time
from flexmotion_ros.core.time_optimal.solver import plan_time_optimal

MODEL_2265 = ModalModel(
    b0=0.48671944992126076,
    c=0.0,
    omega=(1.7442406864914983, 2.5791677402049, 3.8885119103720047, 4.466531103206854, 5.694135473266457,
           9.399874661823452, 13.988046919420835, 16.799305929005087),
    zeta=(0.17953406655040569, 0.007953325766739693, 0.06142447911742502, 0.2515274792009776, 0.2422184897425083,
          0.2893717210427957, 0.20649500027589676, 0.04801992405288181),
    b=(1.3297090357071004, -1.9867981977660054, -1.6069501565097561, -1.7728292833859822, -1.1073370382530676,
       1.687969692623838, -0.7984247724238002, 0.7277473129677975),
)  # fmt: skip
U_MAX_2265 = 0.19942873040251285
TARGET_2265 = 0.00029749821034569674
#: bench/fuzz.py's arrival time for fixed_time: 1.5 times the rigid bound plus the slowest period, s.
ARRIVAL_2265 = 3.7683316560130042


def _problem():
    return state_to_rest(MODEL_2265, U_MAX_2265, np.zeros(18), TARGET_2265)


def test_a_refusal_after_the_work_budget_names_the_bound_and_a_method_that_plans():
    problem = _problem()
    T_rigid = rigid_time(problem.model, problem.u_max, problem.shifted_initial(), problem.include_position)
    try:
        profile = plan_time_optimal(problem)
    except SolverError as exc:
        text = str(exc)
        assert "work budget" in text
        # why: a 0.11 s rigid move against modes of 0.37-3.6 s periods (on 4a85f36 the refusal did not say)
        assert "short against every mode" in text and "0.374 s period" in text
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
        model=MODEL_2265, u_max=U_MAX_2265, method="fixed_time", options={"arrival_time": ARRIVAL_2265}
    )
    result = plan_move(config, problem, rate)
    s = result.sampled
    u = np.asarray(s.commands, float)
    assert np.all(np.abs(u) <= U_MAX_2265)
    X = expm_pieces(problem, np.full(u.size, s.dt), u)  # own expm propagation
    target = MODEL_2265.rest_state(TARGET_2265)
    dev = X - target
    scale = np.maximum(np.max(np.abs(dev), axis=0), 1e-300)
    assert float(np.max(np.abs(dev[-1]) / scale)) <= 1e-8


MODEL_9257 = ModalModel(
    b0=2.6432298694523357,
    c=-0.8466068029866766,
    omega=(1.1425653223956036, 1.3369119855231455, 1.667995398320832, 1.9476644509509904, 2.211957264222012,
           4.321877737021347, 5.642433759040515, 18.94187424315124),
    zeta=(0.19838887106482386, 0.23497624062841863, 0.006445424234572295, 0.16265466583362406, 0.1825991321590089,
          0.22192330324770074, 0.023573561790424635, 0.2760723738519438),
    b=(0.4277413265680142, -0.6241913164134398, 1.5132174213436846, -1.6073919980053863, -0.16754164513429604,
       -1.2069057054503873, 1.9794554153482002, -0.22761894989032916),
)  # fmt: skip


def test_a_refusal_for_a_missed_target_names_the_bound_and_a_method_that_plans():
    """Fuzz case 9257 (8 modes, from rest): within the budget, but every structure found misses the target."""
    problem = state_to_rest(MODEL_9257, 3.3282974630115865, np.zeros(18), 0.026188786159263067)
    T_rigid = rigid_time(problem.model, problem.u_max, problem.shifted_initial(), problem.include_position)
    try:
        profile = plan_time_optimal(problem)
    except SolverError as exc:
        text = str(exc)
        assert "missed the target" in text
        assert "short against every mode" in text  # 0.109 s rigid, the fastest mode's period 0.332 s
        assert f"at least {T_rigid:.6g} s" in text
        assert "fixed_time" in text
        assert text.endswith("or model fewer modes")  # said once, at the end
        return
    assert profile.certified, profile.certificate.message
    assert profile.duration >= T_rigid * (1.0 - 1e-12)


def test_only_a_move_short_against_every_mode_is_called_so():
    # fuzz case 3894 (8 modes, moving start): a 213 s rigid move, refused after the work budget for other reasons
    assert "short against every mode" not in refusal_reason(213.4, 0.115)
    assert "short against every mode" not in refusal_reason(0.11, 0.0)  # a rigid body: no mode
    text = refusal_reason(0.1107, 0.3740)
    assert text.startswith("the move is short against every mode") and text.endswith("or model fewer modes")
