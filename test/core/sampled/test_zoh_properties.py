"""Property tests of the exact zero-order-hold optimum (``core.zoh.plan_time_optimal_zoh``).

For random models and moves (rest-to-rest, motion-to-rest, state-to-rest) at
low rates (5-50 Hz, so that the number of samples ``K`` stays small), checked
here independently of the planner:

* ``|u_k| <= u_max`` exactly (no tolerance);
* exact at the sample instants: OUR matrix-exponential simulation
  (:func:`core.simulation.simulate_samples`) reaches the target at sample ``K``
  (each state relative to its excursion) and matches the reported states;
* fewest samples: a full linear program over all ``K - 1`` samples
  (``min t  s.t.  sum_m g_m u_m = w, |u_m| <= t``, scipy HiGHS, matrices from
  scipy's expm) needs a peak above ``u_max``, proved by the weak-duality bound
  of its dual vector;
* ``K dt >= T*`` (a sampled input is an admissible continuous one).

Models: as in ``test_solver_properties`` (up to 4 modes, separation 5 %),
with every mode below 0.9 of the Nyquist frequency of the drawn rate
(``omega_d dt < 0.9 pi``; at ``omega_d dt = k pi`` the sampled system loses
controllability).  If a long move would need more than ``K_MAX`` samples at
the drawn rate, the rate is lowered (not below the Nyquist limit): the LP
check stays fast and the problem is the same up to a time scaling.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from reference_solutions import deviation_from_target
from scipy.linalg import expm
from scipy.optimize import linprog

from flexmotion_ros.core import (
    ModalModel,
    MoveProblem,
    SolverError,
    motion_to_rest,
    plan_time_optimal,
    plan_time_optimal_zoh,
    rest_to_rest,
    simulate_samples,
    state_to_rest,
)

from ..time_optimal.test_solver_properties import (
    FINAL_RTOL,
    SETTINGS,
    WB,
    describe,
    log_uniform,
    models,
    natural_velocity,
    negligible,
    safe_note,
    signs,
    units,
)

K_MAX = 500
NYQUIST_FRACTION = 0.9


# --------------------------------------------------------- independent LP
def discrete_system(problem: MoveProblem, dt: float):
    """``Phi = e^{A dt}``, ``Gamma = int_0^dt e^{A s} B ds`` and the shifted initial state."""
    A, B = problem.model.A(), problem.model.B()
    x0 = problem.x0.copy()
    if problem.target is None:
        A, B, x0 = A[1:, 1:], B[1:], x0[1:]
    else:
        x0[0] -= problem.target
    n = A.shape[0]
    aug = np.zeros((n + 1, n + 1))
    aug[:n, :n] = A
    aug[:n, n] = B
    E = expm(aug * dt)
    return E[:n, :n], E[:n, n], x0


def infeasibility_bound(problem: MoveProblem, dt: float, M: int, u_max: float) -> float:
    """A proof that ``M`` samples with ``|u_k| <= u_max`` cannot reach the target.

    Phase-1 linear program over all ``M`` samples (scipy HiGHS)::

        min sum(s+ + s-)  s.t.  sum_m g_m u_m + s+ - s- = w,  |u_m| <= u_max,  s+-, >= 0

    Its dual vector ``nu`` gives the weak-duality bound ``|nu^T w| / sum_m |nu^T g_m|``:
    every sequence reaching the target has a peak at least this large.  Returns the
    bound (``> u_max`` proves infeasibility; ``inf`` when ``M = 0``); 0 if the LP is feasible.
    """
    Phi, Gam, x0 = discrete_system(problem, dt)
    n = x0.size
    if M == 0:
        return math.inf if np.any(x0) else 0.0
    G = np.empty((M, n))  # g_m = Phi^m Gamma, m = samples to go
    g = Gam.copy()
    for m in range(M):
        G[m] = g
        g = Phi @ g
    w = -np.linalg.matrix_power(Phi, M) @ x0
    scale = np.abs(x0) + u_max * np.sum(np.abs(G), axis=0)
    scale = np.where(scale > 0.0, scale, 1.0)
    Gs, ws = G / scale, w / scale
    I = np.eye(n)
    phase1 = dict(
        c=np.concatenate([np.zeros(M), np.ones(2 * n)]),
        A_eq=np.hstack([Gs.T, I, -I]),
        b_eq=ws,
        bounds=[(-u_max, u_max)] * M + [(0.0, None)] * (2 * n),
    )
    res = linprog(**phase1, method="highs")
    if res.status == 4:  # HiGHS's simplex lost its way numerically (status 15): its interior point decides
        res = linprog(**phase1, method="highs-ipm")
    assert res.status == 0, res.message
    if res.fun <= 1e-13:
        return 0.0
    nu = np.asarray(res.eqlin.marginals, float)
    denom = float(np.sum(np.abs(Gs @ nu)))
    # weak duality: for ANY nu, |nu^T w| = |sum nu^T g_m u_m| <= max|u_m| sum |nu^T g_m|
    return abs(float(nu @ ws)) / denom if denom > 0 else math.inf


# -------------------------------------------------------------- strategies
@st.composite
def zoh_cases(draw, kind: str):
    rate = draw(st.floats(5.0, 50.0))
    cap = NYQUIST_FRACTION * math.pi * rate
    model = draw(models(omega_lo=0.3, omega_hi=min(30.0, cap), omega_cap=cap))
    u_max = draw(log_uniform(0.1, 10.0))
    size = draw(log_uniform(1e-3, 1e3))
    if kind == "rest":
        problem = rest_to_rest(model, u_max, draw(signs) * model.natural_distance(u_max) * size)
    elif kind == "motion":
        problem = motion_to_rest(model, u_max, draw(signs) * natural_velocity(model, u_max) * size)
    else:
        x0 = np.zeros(model.n_states)
        x0[0] = draw(units) * model.natural_distance(u_max) * size
        x0[1] = draw(units) * natural_velocity(model, u_max) * size
        for i, (w, b) in enumerate(zip(model.omega, model.b)):
            x0[2 + 2 * i] = draw(units) * abs(b) * u_max / w**2 * size
            x0[3 + 2 * i] = draw(units) * abs(b) * u_max / w * size
        target = None if draw(st.booleans()) else draw(units) * model.natural_distance(u_max) * size
        if not np.any(x0) and not target:
            x0[1] = natural_velocity(model, u_max) * size
        problem = state_to_rest(model, u_max, x0, target)
    return problem, rate


def plan_and_check_zoh(problem: MoveProblem, rate: float, k_max: int | None = K_MAX):
    safe_note(describe(problem))
    try:
        continuous = plan_time_optimal(problem)
    except SolverError as exc:
        pytest.fail(f"continuous planner: SolverError: {exc}\n{describe(problem)}")
    T = continuous.duration
    wd_max = float(np.max(problem.model.omega_d)) if problem.model.n_modes else 0.0
    if k_max is not None and T * rate > k_max:  # keep K small: lower the rate, never below the Nyquist limit
        rate = max(k_max / T, wd_max / (NYQUIST_FRACTION * math.pi))
    safe_note(f"rate_hz={rate!r}")
    dt = 1.0 / rate
    try:
        sp = plan_time_optimal_zoh(problem, rate, continuous)
    except SolverError as exc:
        pytest.fail(f"sampled planner: SolverError: {exc}\n{describe(problem)}; rate_hz={rate!r}")
    cmds = np.asarray(sp.commands, float)
    K = cmds.size
    um = problem.u_max
    if negligible(problem):
        assert K == 0
        return sp
    assert K == sp.samples and sp.duration == pytest.approx(K * dt, rel=1e-15)
    assert np.all(np.abs(cmds) <= um), f"|u_k| = {np.max(np.abs(cmds))!r} > u_max = {um!r}"
    # exact at the sample instants, by our own simulation
    X = simulate_samples(problem.model, problem.x0, cmds, dt)
    dev, scale = deviation_from_target(problem, X)
    rel = float(np.max(np.abs(dev[-1]) / scale))
    assert rel <= FINAL_RTOL, f"own simulation: relative final-state error {rel:.3e} at sample {K}"
    states = np.asarray(sp.states, float)
    assert states.shape == X.shape
    sdev = states - X
    if problem.target is None:
        sdev = sdev[:, 1:]
    assert np.max(np.abs(sdev) / scale) <= 1e-9, "reported states differ from the exact simulation"
    # no faster than the continuous optimum
    assert K * dt >= T * (1.0 - 1e-12), f"K dt = {K * dt!r} < T* = {T!r}"
    # fewest samples: K - 1 samples need a peak above u_max (proved by the LP dual)
    bound = infeasibility_bound(problem, dt, K - 1, um)
    assert bound > um * (1.0 + 1e-10), f"{K - 1} samples may suffice: dual bound {bound!r}, u_max {um!r}"
    assert sp.minimal, "planner did not prove its sample count minimal"
    assert sp.lower_bound_samples <= K
    return sp


# -------------------------------------------------------------- properties
@settings(max_examples=25, **SETTINGS)
@given(zoh_cases("rest"))
@example((rest_to_rest(WB, 1.0, 1.0), 10.0))
@example((rest_to_rest(WB, 1.0, 1e-3 * WB.natural_distance(1.0)), 50.0))
@example((rest_to_rest(ModalModel(b0=1.0), 1.0, 1.0), 50.0))  # T* = 2 s on the sample grid: 100 samples suffice
# the independent LP of K - 1 = 214 samples: HiGHS's simplex ends with status 15 (unknown); its interior point proves it
@example(
    (
        rest_to_rest(
            ModalModel(
                b0=1.101998506951004,
                c=0.0,
                omega=(4.3460320903027085, 14.186400673945036, 54.380995385082514),
                zeta=(0.16065148405744925, 0.11033496300576927, 0.1727944946305627),
                b=(-0.990976914431793, 3.886742849174284, 8.696279880716805),
            ),
            1.0,
            -32.19475489381012,
        ),
        19.233342723985402,
    )
)
def test_zoh_rest_to_rest(case):
    plan_and_check_zoh(*case)


@settings(max_examples=20, **SETTINGS)
@given(zoh_cases("motion"))
@example((motion_to_rest(WB, 1.0, 1.0), 20.0))
def test_zoh_motion_to_rest(case):
    plan_and_check_zoh(*case)


@settings(max_examples=20, **SETTINGS)
@given(zoh_cases("state"))
@example((state_to_rest(WB, 1.0, [0.2, -0.3, 0.1, 0.05], 1.0), 25.0))
def test_zoh_state_to_rest(case):
    plan_and_check_zoh(*case)


def test_infeasibility_helper_on_the_double_integrator():
    """The independent LP against a hand-checkable case: x'' = u from rest at -1 to rest at 0, dt = 1.

    One sample cannot; two reach it only with u = (1, -1) (peak 1); three with peak 1/2
    (u = 1/2, 0, -1/2).
    """
    problem = rest_to_rest(ModalModel(b0=1.0), 1.0, 1.0)
    assert infeasibility_bound(problem, 1.0, 0, 1.0) == math.inf
    assert infeasibility_bound(problem, 1.0, 1, 100.0) > 100.0
    assert infeasibility_bound(problem, 1.0, 2, 1.0) == 0.0
    assert infeasibility_bound(problem, 1.0, 2, 0.999) == pytest.approx(1.0, rel=1e-9)
    assert infeasibility_bound(problem, 1.0, 3, 0.5) == 0.0
    assert infeasibility_bound(problem, 1.0, 3, 0.49) == pytest.approx(0.5, rel=1e-9)


def test_wie_bernstein_at_1khz_is_the_fewest_samples():
    """The README's figure: 4218 samples at 1 kHz, and 4217 proved infeasible here."""
    problem = rest_to_rest(WB, 1.0, 1.0)
    sp = plan_and_check_zoh(problem, 1000.0, k_max=None)
    assert sp.samples == 4218
