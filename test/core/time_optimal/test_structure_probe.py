"""Issue 15's tail (tail6): the full solver's first exact solve stops at the first structure that converges.

When the fast path finds nothing, the full solver solves the exact inner problem at the smoothed duration
and runs the switch-time Newton from the structure it ends on.  On fuzz cases 205 (8 modes, a moving start)
and 1706 (6 modes, a 5,841-unit move) that solve oscillated between neighbouring structures for 23 and 17
exact evaluations (about 1.5 ms each) although the switch-time Newton converges, to the certified
optimum, from the structure of its first iterate.  Now each new structure of its iterates is tried as it
shows (``costate_solver._StructureProbe``), and the solve stops at the first extremal found.
"""

from __future__ import annotations

import numpy as np
import pytest
from reference_solutions import bang_bang_final_error

from flexmotion_ros.core import ModalModel
from flexmotion_ros.core.model.boundary import state_to_rest
from flexmotion_ros.core.results import SolverPath
from flexmotion_ros.core.time_optimal import costate_solver
from flexmotion_ros.core.time_optimal.solver import plan_time_optimal

# bench/fuzz.py, seed 15
CASE_205 = state_to_rest(
    ModalModel(
        b0=0.10511830362678591,
        c=-0.7955410669493436,
        omega=(1.565438574188611, 1.9144397961470812, 2.630989861364528, 4.8097391746684615, 8.659765144290827,
               24.827250540417484, 26.37563548851161, 49.52628460192681),
        zeta=(0.24330968464456204, 0.08588749422197692, 0.06118267954399877, 0.21631359819662396,
              0.16245562185490373, 0.10309043105817223, 0.06674586763604255, 0.25165772059411434),
        b=(-1.7381876185114224, -0.8116675505366739, -0.6597473126760146, 0.13305541817177718, 1.5718638301780798,
           -1.7476433612785547, 1.9914249506746076, 0.16118857168634448),
    ),
    0.11819457441540945,
    np.array([0.0, 1.3633782673836665, -0.8909555317292271, -21.4194252878188, 1.2763270283001944,
              4.1656505365244225, -1.9164221305753146, 0.35721856017240733, -0.007194052663039867,
              0.03214345194410847, 0.08521511358090443, -1.6577897970899127, 0.04202908648148558,
              -0.16183171092088214, 0.0037486500390505376, 1.095968766190732, -0.0006324830790867318,
              -0.04403160545570998]),
    -0.8722590592994935,
)  # fmt: skip
CASE_1706 = state_to_rest(
    ModalModel(
        b0=0.7823101822057049,
        c=-0.1700127107749474,
        omega=(0.4913825518962311, 1.0617000314100487, 1.242137310616079, 13.436221542142924, 18.164193212307676,
               20.62621201247432),
        zeta=(0.25361295013661905, 0.23775761152131702, 0.0774560355987754, 0.004026701392631571,
              0.2296418017239692, 0.26702158412460636),
        b=(-0.18819957998925801, -1.9618628792090478, 1.9350525189468246, -0.058022085678444454,
           -0.8877763974539196, 0.9484110402394745),
    ),
    6.4674607582999295,
    np.zeros(14),
    5841.216581371268,
)  # fmt: skip
#: (problem, switches of the optimum, exact evaluations on 0f97951 (the full solver's first solve, to its end)).
CASES = {"205": (CASE_205, 21, 23), "1706": (CASE_1706, 17, 17)}


@pytest.mark.parametrize("name", sorted(CASES))
def test_first_exact_solve_stops_at_a_converging_structure(name, monkeypatch):
    problem, switches, old_evaluations = CASES[name]
    profile = plan_time_optimal(problem)
    assert profile.extra["solver_path"] is SolverPath.FULL  # the fast path does not answer these
    assert profile.certified, profile.certificate.message
    assert profile.switch_times.size == switches
    assert profile.iterations <= 3 < old_evaluations  # exact co-state evaluations
    assert bang_bang_final_error(problem, profile) <= 1e-9  # own expm propagation
    assert np.all(np.abs(profile.levels) <= problem.u_max)
    # the same optimum as the solve run to its end (no probe)
    monkeypatch.setattr(costate_solver, "PROBE_BELOW", 0.0)
    before = plan_time_optimal(problem)
    assert before.iterations == old_evaluations
    assert before.certified
    assert abs(profile.duration - before.duration) <= 1e-12 * before.duration
    assert np.allclose(profile.switch_times, before.switch_times, rtol=0.0, atol=1e-9 * before.duration)
    np.testing.assert_array_equal(profile.levels, before.levels)
