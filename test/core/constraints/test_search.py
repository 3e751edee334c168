"""The limited planner's sample-count search: no wasted probes, no repeated row rounds.

The search may only change the order and size of its LPs, never a claim: the
plans below are checked exact and within every limit by the helpers of
``test_planner`` (independent matrix-exponential simulation and a second LP
formulation for ``K - 1``).
"""

import math

import numpy as np
import pytest

from flexmotion_ros.core import ModalModel, MoveProblem, plan_time_optimal_zoh, rest_to_rest
from flexmotion_ros.core.constraints import dual as limit_dual
from flexmotion_ros.core.constraints import lp as limit_lp
from flexmotion_ros.core.constraints import warm as limit_warm
from flexmotion_ros.core.constraints.level import Level
from flexmotion_ros.core.constraints.limits import Limits
from flexmotion_ros.core.constraints.planner import plan_limited_zoh
from flexmotion_ros.core.constraints.structure import map_runs, solution_runs
from flexmotion_ros.core.results import ProofKind

from .test_planner import check_every_limit, feasible_state_space

WB = ModalModel(b0=0.5, c=0.0, omega=[math.sqrt(2.0)], zeta=[0.0], b=[1.0])


def test_fewest_steps_down_from_a_feasible_guess_instead_of_bisecting():
    """A feasible first probe (the guess extrapolated from the coarser levels, usually within a
    sample of the answer) is followed by the count just below it, not by the midpoint towards the
    unlimited count (at 1 kHz hundreds of samples below: one wasted LP of a few hundred free
    samples, 0.2 s, per limit on the bench's 2 m move).  On the old search the second probe was 5314."""
    problem = rest_to_rest(WB, 1.0, 2.0)
    level = Level(problem, 1000.0, Limits(velocity_max=0.5), K_cap=10**6, lp=object())
    answer = 5596
    probed = []

    def probe(K):
        probed.append(K)
        level.t[K] = 0.9999 if K >= answer else 1.0004
        return level.t[K]

    level.probe = probe
    assert level.fewest(answer, 5033) == answer
    assert probed == [answer, answer - 1]
    # a guess a few samples high still ends on the first feasible count (doubling steps, then bisection)
    probed.clear()
    level.t.clear()
    assert level.fewest(answer + 5, 5033) == answer
    assert all(k >= answer - 8 for k in probed)


def test_rows_inside_runs_are_seeded_across_counts_and_levels():
    """Riding a deflection limit, every sample of a run needs its limit row; found one LP round at a
    time for every new count, they cost one extra LP per probe.  Seeded from the nearest solved count
    (or the coarser level's rows) the 250 Hz plan takes 14 LPs (18 before); it is the same plan:
    exact, within every limit, proved fewest, and ``K - 1`` independently infeasible."""
    problem = rest_to_rest(WB, 1.0, 2.0)
    rate = 250.0
    unlimited = plan_time_optimal_zoh(problem, rate)
    peak_q = float(np.max(np.abs(unlimited.states[:, 2])))
    limits = Limits(deflection_max=(0.6 * peak_q,))
    r = plan_limited_zoh(problem, rate, limits, unlimited)
    assert r.lp_solves <= 15
    check_every_limit(problem, r, limits)
    K = r.sampled.samples
    assert r.minimal and r.lower_bound_samples == K
    assert not feasible_state_space(problem, K - 1, 1.0 / rate, limits)


def _bench_limits(problem, rate):
    """The bench's limits (``bench/fuel_limits.py``): 0.8 x the unlimited peak velocity, 0.6 x its peak
    deflection, 10 N/s."""
    unlimited = plan_time_optimal_zoh(problem, rate)
    peak_v = float(np.max(np.abs(unlimited.states[:, 1])))
    peak_q = float(np.max(np.abs(unlimited.states[:, 2])))
    return unlimited, Limits(0.8 * peak_v, (0.6 * peak_q,), 10.0)


def _warm_against_cold(monkeypatch, key):
    """Wrap ``solve_lp``: every LP given ``key`` (a start basis or point) is solved again cold; the list
    returned fills with ``(warm status, warm optimum, cold status, cold optimum)`` per such LP."""
    real = limit_lp.solve_lp
    warm = []

    def solve_lp(**kw):
        res = real(**kw)
        if kw.get(key) is not None:
            cold = real(**{**kw, key: None})
            warm.append((res.status, res.objective, cold.status, cold.objective))
        return res

    monkeypatch.setattr(limit_lp, "solve_lp", solve_lp)
    return warm


def test_row_rounds_start_from_the_previous_rounds_basis(monkeypatch):
    """A row round is the same LP with rows inside runs added: it starts from the previous optimum's
    basis (the new rows' slacks basic) and gives the cold solve's verdict and optimum.  On the old
    search every round was a cold solve (the bench's 1 kHz all-three move: 0.25-0.34 s each, three
    rounds).  The plan is exact, within every limit, and ``K - 1`` independently infeasible."""
    problem = rest_to_rest(WB, 1.0, 1.0)
    rate = 50.0
    unlimited, limits = _bench_limits(problem, rate)
    warm = _warm_against_cold(monkeypatch, "start_basis")
    r = plan_limited_zoh(problem, rate, limits, unlimited)
    assert warm
    for status, objective, cold_status, cold_objective in warm:
        assert status is cold_status
        assert objective == pytest.approx(cold_objective, rel=1e-9, abs=1e-12)
    check_every_limit(problem, r, limits)
    K = r.sampled.samples
    assert r.minimal and r.lower_bound_samples == K
    assert not feasible_state_space(problem, K - 1, 1.0 / rate, limits)


def test_the_lift_stops_at_the_first_bound_that_proves(monkeypatch):
    """Lifting window multipliers repeats its sparse solve with negative multipliers pinned at zero;
    once a round's bound proves ``K - 1`` infeasible, more rounds cannot change the verdict.  The
    50 Hz slew-limited move took 3 rounds (3 LU factorisations of about 4 K unknowns), now 1; the
    proof and the plan are the same, and ``K - 1`` is independently infeasible."""
    problem = rest_to_rest(WB, 1.0, 1.0)
    rate = 50.0
    unlimited, limits = _bench_limits(problem, rate)
    limits = limits.only("slew_rate")
    real = limit_dual._least_squares
    calls = []

    def least_squares(*a, **k):
        calls.append(1)
        return real(*a, **k)

    monkeypatch.setattr(limit_dual, "_least_squares", least_squares)
    r = plan_limited_zoh(problem, rate, limits, unlimited)
    assert r.extra["lower_bound_proof"] == ProofKind.DUAL
    assert len(calls) == 1
    check_every_limit(problem, r, limits)
    K = r.sampled.samples
    assert r.minimal and r.lower_bound_samples == K
    assert not feasible_state_space(problem, K - 1, 1.0 / rate, limits)


def test_bench_move_at_1khz_with_all_three_limits_needs_no_wide_lp():
    """The bench's 2 m move at 1 kHz under all three limits (issue 15): the final rate's windows come
    from the last coarse level's answer (the fewest feasible count), and the window LP at ``K - 1``
    lifts to a weak-duality proof by itself.  Taken from that level's ``K - 1``, as before, the windows
    needed the wider fallback LP (1,048 free samples, 1.7 s of the 5.2 s plan) and the 250 Hz
    reference LP had 564 free samples.  Same count, same proof, exact and within every limit."""
    problem = rest_to_rest(WB, 1.0, 2.0)
    rate = 1000.0
    unlimited, limits = _bench_limits(problem, rate)
    free = []
    real = limit_lp.LimitLP.assemble

    def assemble(self, K, seg, mode, extra, *args):
        free.append(seg.n_free)
        return real(self, K, seg, mode, extra, *args)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(limit_lp.LimitLP, "assemble", assemble)
        r = plan_limited_zoh(problem, rate, limits, unlimited)
    assert r.sampled.samples == 5596
    assert r.minimal and r.lower_bound_samples == 5596
    assert r.extra["lower_bound_proof"] == ProofKind.DUAL
    assert max(free) < 700
    check_every_limit(problem, r, limits)


def test_the_predicted_count_is_accepted_without_its_own_probe():
    """At the final rate the count extrapolated from the coarser levels is not probed by itself: ``K - 1``
    is probed in the windows mapped from the coarser level (its ``t`` above 1, and ``K``'s predicted
    below 1 from the coarser level's slope), proved by its lifted bound, and the smooth LP at ``K`` in
    the windows of ``K - 1``'s solution is the plan.  Before, the final rate solved a scaled LP at ``K``
    (592 free samples here), another at ``K - 1`` and the smooth LP at ``K``: one LP of a few hundred
    free samples more.  The smooth LP frees 2 samples either side of ``K - 1``'s runs (166 free samples
    here, 290 with the probes' 4).  Same count, same proof (a weak-duality bound, itself a
    certificate), exact and within every limit."""
    problem = rest_to_rest(WB, 1.0, 2.0)
    rate = 500.0
    unlimited, limits = _bench_limits(problem, rate)
    solved = []
    real = limit_lp.LimitLP.solve

    def solve(self, K, seg=None, mode="scaled", t_fix=None, start=None):
        if self.dt == 1.0 / rate:
            solved.append((K, mode))
        return real(self, K, seg, mode, t_fix, start)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(limit_lp.LimitLP, "solve", solve)
        r = plan_limited_zoh(problem, rate, limits, unlimited)
    K = r.sampled.samples
    assert K == 2798 and r.minimal and r.lower_bound_samples == K
    assert r.extra["lower_bound_proof"] == ProofKind.DUAL
    assert solved == [(K - 1, "scaled"), (K, "smooth")]
    assert r.extra["accepted_free_samples"] < 0.35 * r.extra["free_samples"]
    check_every_limit(problem, r, limits)


@pytest.mark.parametrize(
    "model, u_max, goal, v_max, K",
    [
        # seed-18 fuzz case 7: proved fewest (4448 samples, beyond the full LP's 3000), unproved on main
        (
            dict(
                b0=0.16842870118248662,
                c=0.0,
                omega=(0.31616055154620315, 1.3492316106148314),
                zeta=(0.19630570728730692, 0.09662993145950094),
                b=(0.2932579922068591, -0.1415477610749102),
            ),
            0.49934178911913596,
            -16.616967412229663,
            0.4783426956248247,
            4448,
        ),
        # case 11: proved on main by the full feasibility LP and its independent confirmation (0.7 s), now 0.25 s
        (
            dict(
                b0=0.14157823060148156,
                c=0.0,
                omega=(0.4015992887186895, 9.410446795419377),
                zeta=(0.19929502297018856, 0.2735458585792935),
                b=(-0.4076438146828142, 1.9643095455658757),
            ),
            9.019374831401256,
            -73.57031439048997,
            5.830228789442861,
            1976,
        ),
    ],
)
def test_a_lift_without_the_window_pull_proves_more(model, u_max, goal, v_max, K):
    """When the lifted bound does not prove ``K - 1``, the lift is repeated without pulling the multipliers
    of the window LP's rows towards the window's own (a restriction: its runs share one level): on the
    seed-18 fuzz (100 Hz, velocity limit) this proves counts the full feasibility LP proved before, or
    that were left unproved.  The plan is the same; the proof is a weak-duality bound (a certificate
    evaluated over every sample)."""
    m = ModalModel(**model)
    problem = MoveProblem(m, u_max, [0.0] * m.n_states, goal)
    limits = Limits(velocity_max=v_max)
    r = plan_limited_zoh(problem, 100.0, limits)
    assert r.sampled.samples == K
    assert r.minimal and r.lower_bound_samples == K
    assert r.extra["lower_bound_proof"] == ProofKind.DUAL
    check_every_limit(problem, r, limits)


def test_a_coarse_reference_that_meets_no_sequence_costs_a_feasibility_lp_not_the_smooth_lp():
    """The bench's all-three limits at 250 Hz: the 15.6 Hz level's reference (the smoothest sequence within
    1e-6 of its ``t``, mid-interval rows included) has no solution, and the vertex's runs are handed on.  The
    feasibility LP with the same rows (``mode="reach"``) says so in about half the smooth LP's time; the
    old search solved the smooth LP there.  Its verdict is the smooth LP's (the same feasible set: checked
    here on every reference), and the handoff level (62.5 Hz) still solves only the smooth LP (at 1 kHz its
    reference is feasible, and the feasibility LP would cost as much as the smooth one).  Same count, same proof, exact and within every limit."""
    problem = rest_to_rest(WB, 1.0, 2.0)
    rate = 250.0
    unlimited, limits = _bench_limits(problem, rate)
    real = limit_lp.LimitLP.solve
    solved = []

    def solve(self, K, seg=None, mode="scaled", t_fix=None, start=None):
        out = real(self, K, seg, mode, t_fix, start)
        if mode in ("smooth", "reach") and t_fix is not None:  # the references (accepted LPs: t_fix None)
            other = real(self, K, seg, "reach" if mode == "smooth" else "smooth", t_fix)  # (cold)
            assert (out is None) == (other is None)
            solved.append((round(1.0 / self.dt, 3), mode, out is None))
        return out

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(limit_lp.LimitLP, "solve", solve)
        r = plan_limited_zoh(problem, rate, limits, unlimited)
    assert solved == [(15.625, "reach", True), (62.5, "smooth", True)]
    K = r.sampled.samples
    assert r.minimal and r.lower_bound_samples == K
    assert r.extra["lower_bound_proof"] == ProofKind.DUAL
    check_every_limit(problem, r, limits)


def test_the_reference_lps_start_from_the_probes_point(monkeypatch):
    """A coarse level's reference (the smooth LP, and the feasibility question ``mode="reach"`` before it)
    is an LP over the same columns as the scaled probe at the same count and segments: it starts from the
    probe's point (HiGHS builds its basis around it), never from nothing; the accepted LP starts from a
    point built from the probe's commands (:func:`.warm.point_from_commands`).  Each warm verdict and optimum
    is the cold solve's; the bench's 250 Hz reference took 3,021 simplex iterations cold and 1,224 warm
    (0.20 -> 0.12 s CPU).  On the old planner no LP had a start point.  The plan is exact, within
    every limit, and ``K - 1`` independently infeasible."""
    problem = rest_to_rest(WB, 1.0, 1.0)
    rate = 50.0
    unlimited, limits = _bench_limits(problem, rate)
    warm = _warm_against_cold(monkeypatch, "start_point")

    real_solve = limit_lp.LimitLP.solve
    smooth = []

    def solve(self, K, seg=None, mode="scaled", t_fix=None, start=None):
        if mode != "scaled":
            smooth.append((round(1.0 / self.dt, 6), mode, t_fix is None, start is not None))
        return real_solve(self, K, seg, mode, t_fix, start)

    monkeypatch.setattr(limit_lp.LimitLP, "solve", solve)
    r = plan_limited_zoh(problem, rate, limits, unlimited)
    assert warm
    # the accepted LP (t_fix None) at the final rate too, from another count's or other windows' commands
    assert any(hz == rate and accepted for hz, _, accepted, _ in smooth)
    assert all(started for *_, started in smooth), smooth
    for status, objective, cold_status, cold_objective in warm:
        assert status is cold_status
        if status is limit_lp.LpStatus.OPTIMAL:
            assert objective == pytest.approx(cold_objective, rel=1e-7, abs=1e-9)
    check_every_limit(problem, r, limits)
    K = r.sampled.samples
    assert r.minimal and r.lower_bound_samples == K
    assert not feasible_state_space(problem, K - 1, 1.0 / rate, limits)


@pytest.mark.parametrize("which", ["deflection_max", "velocity_max", "slew_rate", None])
def test_a_point_from_commands_meets_the_lps_rows(which):
    """The accepted LP at the final rate starts from a point built from another solution's commands (other
    windows, another count): its chain states come from the chain equalities.  Built from the LP's own
    optimum it is that optimum again: every equality and inequality row met to rounding (checked on the
    assembled matrices), the objective the LP's.  A point off by a chain equation would start HiGHS
    from nonsense."""
    problem = rest_to_rest(WB, 1.0, 1.0)
    rate = 50.0
    unlimited, limits = _bench_limits(problem, rate)
    if which is not None:
        limits = limits.only(which)
    K = plan_limited_zoh(problem, rate, limits, unlimited).sampled.samples + 2
    lp = limit_lp.LimitLP(problem, 1.0 / rate, limits)
    sol = lp.solve(K)
    seg = map_runs(solution_runs(sol, lp.um, lp.slew), K, K, 2)
    assert 0 < seg.n_free < K
    smooth = lp.solve(K, seg, mode="smooth")
    assert smooth is not None
    a = lp.assemble(K, seg, "smooth", lp.run_rows[K])
    x = limit_warm.point_from_commands(a, seg, smooth.u / lp.um, lp.slew)
    assert x is not None
    np.testing.assert_allclose(a.A_eq @ x, a.b_eq, atol=1e-8)
    assert np.max(a.A_ub @ x - a.b_ub) <= 1e-8
    assert np.all(x >= a.lower - 1e-12) and np.all(x <= a.upper + 1e-12)
    assert a.cost @ x == pytest.approx(a.cost @ smooth.x, rel=1e-9, abs=1e-9)


def test_a_warm_round_carries_each_rows_status_by_what_it_limits():
    """A row round's start basis: every old row keeps its status (found by what it limits: kind, sample,
    index, sign, offset; other rows by their position among their kind), every new row is basic.  Checked
    against a reference built here with one Python tuple per row (the old code's keys); the keys are now
    arrays, matched without a loop over rows."""
    from flexmotion_ros.core.linear_program import LpBackend, LpBasis, LpSolution

    problem = rest_to_rest(WB, 1.0, 1.0)
    rate = 50.0
    unlimited, limits = _bench_limits(problem, rate)
    lp = limit_lp.LimitLP(problem, 1.0 / rate, limits)
    K = unlimited.samples + 20
    sol = lp.solve(K)
    seg = map_runs(solution_runs(sol, lp.um, lp.slew), K, K, 2)
    inner = np.flatnonzero(seg.run_of() >= 0)
    few = [set(inner[::7].tolist()) for _ in lp.blocks]
    more = [s | set(inner[3::5].tolist()) for s in few]
    a1 = lp.assemble(K, seg, "scaled", few)
    a2 = lp.assemble(K, seg, "scaled", more)
    m1 = a1.b_ub.size + a1.b_eq.size
    m2 = a2.b_ub.size + a2.b_eq.size
    assert m2 > m1
    rng = np.random.default_rng(3)
    basis = LpBasis(col_status=np.zeros(a1.cost.size, np.int8), row_status=rng.integers(0, 5, m1).astype(np.int8))
    answer = LpSolution(
        status=limit_lp.LpStatus.OPTIMAL,
        x=None,
        objective=None,
        eq_marginals=None,
        ub_marginals=None,
        message="",
        backend=LpBackend.HIGHSPY,
        basis_reader=lambda: basis,
    )
    got = limit_warm.WarmStart(rows=a1, solution=answer).carried(a2)

    def tuple_keys(a):
        other = a.meta[:, 0] == -1
        ordinal = np.cumsum(other) - 1
        keys = [
            ("o", int(o)) if oth else (int(m[0]), int(m[1]), int(m[2]), float(m[3]), float(sv))
            for m, sv, oth, o in zip(a.meta.tolist(), a.s.tolist(), other.tolist(), ordinal.tolist())
        ]
        return keys + [("e", i) for i in range(a.b_eq.size)]

    old = dict(zip(tuple_keys(a1), basis.row_status.tolist()))
    want = np.array([old.get(k, 1) for k in tuple_keys(a2)], np.int8)
    assert got is not None
    np.testing.assert_array_equal(got.row_status, want)
    assert np.count_nonzero(want == 1) - np.count_nonzero(basis.row_status == 1) == m2 - m1
    # an LP that is not the old one with rows added (a row gone) gets no basis
    assert limit_warm.WarmStart(rows=a2, solution=answer).carried(a1) is None
