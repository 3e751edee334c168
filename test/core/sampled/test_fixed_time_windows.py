"""The fixed-time sampled planner's windowed least-peak LPs: bounded work on long moves (issue 15).

Fuzz case 665 (``bench/fuzz.py`` seed 15, 100 Hz): a 7-mode model from a moving
start, ``arrival_time`` 5,217 s, i.e. 521,684 samples.  The windows' 1e-9
duality gap was below HiGHS's accuracy there, so they grew to the full LP (10
LPs, the last over every sample: 32 s CPU).  Every plan here is checked by an
independent propagation (``scipy.linalg.expm`` of the augmented matrix).
"""

import numpy as np
import pytest
from scipy.linalg import expm

from flexmotion_ros.core import ModalModel
from flexmotion_ros.core.config import PlannerConfig
from flexmotion_ros.core.errors import SolverError
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.model.boundary import MoveProblem, state_to_rest
from flexmotion_ros.core.sampled import fixed_time as sampled_fixed_time

RATE = 100.0
MODEL_665 = ModalModel(
    b0=0.6651560059741095,
    c=0.0,
    omega=(
        0.3309852541069143,
        0.36571500186340905,
        0.45765870571671613,
        0.7595753500665434,
        1.3377265302409176,
        2.7330471404722743,
        8.727302235828564,
    ),
    zeta=(
        0.020536137697616853,
        0.219693151526132,
        0.11526758000893851,
        0.12539713106044809,
        0.07350946143243095,
        0.057636147094583,
        0.20438769248671385,
    ),
    b=(
        1.2577966496286694,
        1.33607551592632,
        1.763917074806955,
        1.3032585793733822,
        1.0306163565312492,
        -1.0806669725271203,
        0.20958434394680686,
    ),
)
X0_665 = [
    0.0,
    -4552.998984536621,
    -32087.914717865457,
    -1866.3388910963426,
    -18629.347706037486,
    789.4579673001457,
    345.24873554287814,
    4991.472517086505,
    -2594.9141781989406,
    -2422.0659811160926,
    -326.8235502085417,
    1438.4527763163876,
    49.73285825722393,
    830.8205123941303,
    -0.8295973581029493,
    -33.48842102547791,
]
U_MAX_665 = 4.7614282416104885
ARRIVAL_665 = 5216.844928775106
#: The old windows grew to 21,812 free samples and on to all 521,684; the new ones stop at 1,539.
FREE_BUDGET = 20_000


def case_665() -> MoveProblem:
    return state_to_rest(MODEL_665, U_MAX_665, np.asarray(X0_665), -17433.12787424562)


def final_state_by_expm(problem: MoveProblem, u: np.ndarray, dt: float, block: int = 1000) -> np.ndarray:
    """State after the samples (forward order): own ``expm`` of the augmented matrix, in blocks of samples."""
    A, B = problem.model.A(), problem.model.B()
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n], M[:n, n] = A, B
    E = expm(M * dt)
    Phi, Gam = E[:n, :n], E[:n, n]
    H = np.empty((n, block))  # H[:, j] = Phi^(block-1-j) Gam
    H[:, block - 1] = Gam
    for j in range(block - 2, -1, -1):
        H[:, j] = Phi @ H[:, j + 1]
    Phi_block = np.linalg.matrix_power(Phi, block)
    x = np.asarray(problem.x0, float)
    full = u.size - u.size % block
    for k in range(0, full, block):
        x = Phi_block @ x + H @ u[k : k + block]
    for uk in u[full:]:
        x = Phi @ x + Gam * uk
    return x


def assert_exact(problem: MoveProblem, sampled) -> None:
    assert np.max(np.abs(sampled.commands)) <= problem.u_max
    xf = final_state_by_expm(problem, sampled.commands, sampled.dt)
    target = problem.model.rest_state(problem.target)
    excursion = np.max(np.abs(sampled.states - target), axis=0)
    assert np.all(np.abs(xf - target) <= 1e-8 * np.maximum(excursion, 1e-300))


@pytest.fixture
def budgeted_lp(monkeypatch):
    """``solve_peak_lp`` in the fixed-time planner, failing the test past :data:`FREE_BUDGET` free samples."""
    real = sampled_fixed_time.solve_peak_lp
    sizes: list[int] = []

    def counted(G, w, signs, free):
        sizes.append(int(np.count_nonzero(free)))
        assert sizes[-1] <= FREE_BUDGET, f"a least-peak LP over {sizes[-1]} free samples of {free.size}"
        return real(G, w, signs, free)

    monkeypatch.setattr(sampled_fixed_time, "solve_peak_lp", counted)
    return sizes


def test_fuzz_665_plans_from_small_windows_with_its_least_peak_proved(budgeted_lp):
    problem = case_665()
    config = PlannerConfig(model=MODEL_665, u_max=U_MAX_665, method="fixed_time", options={"arrival_time": ARRIVAL_665})
    result = plan_move(config, problem, RATE)
    s = result.sampled
    assert s.samples == round(ARRIVAL_665 * RATE) == 521_684
    assert_exact(problem, s)
    assert 1 <= len(budgeted_lp) <= 4 and max(budgeted_lp) < 2_000
    # least peak proved to the LP's accuracy: the weak-duality bound is within 1e-6 of the peak sent
    lower, peak = s.extra["least_peak_lower_bound"], s.extra["peak_command"]
    assert lower <= peak * (1.0 + 1e-12) and lower >= peak * (1.0 - 1e-6)
    assert peak < 0.67 * U_MAX_665  # arriving later than T* needs less than u_max


def test_past_the_work_bound_the_best_window_is_returned_with_its_lower_bound(monkeypatch):
    monkeypatch.setattr(sampled_fixed_time, "MAX_FREE_SAMPLES", 1_000)  # stops after the 619-sample window
    problem = case_665()
    config = PlannerConfig(model=MODEL_665, u_max=U_MAX_665, method="fixed_time", options={"arrival_time": ARRIVAL_665})
    s = plan_move(config, problem, RATE).sampled
    assert_exact(problem, s)
    lower, peak = s.extra["least_peak_lower_bound"], s.extra["peak_command"]
    assert 0.0 < lower <= peak * (1.0 + 1e-12) <= U_MAX_665


def test_the_lp_alone_refuses_past_its_work_bound_naming_it(monkeypatch):
    monkeypatch.setattr(sampled_fixed_time, "MAX_FREE_SAMPLES", 400)
    model = ModalModel(b0=1.0, c=0.0, omega=(3.0,), zeta=(0.05,), b=(1.0,))
    problem = MoveProblem(model, 2.0, [0.0] * 4, 1.0)
    with pytest.raises(SolverError, match="work bound of 400"):
        sampled_fixed_time.plan_fixed_time_lp(problem, 5.0, RATE)
    assert sampled_fixed_time.plan_fixed_time_lp(problem, 3.0, RATE).samples == 300  # under the bound: plans
