"""Work the friction planner no longer repeats (issue 18's 50 ms median): what it skips, and that the answer holds.

- The zero-order-hold plan of an exact sampled move takes its states at the command rate from the event-located
  run that checked the move (no second event-located run of every command period).
- The structure LPs hand HiGHS their equality rows in compressed columns, built directly.
- The continuation gives up on a Newton step that needs more than two halvings (and spends what is left on
  half steps of the force).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import sparse

from flexmotion_ros.core import ModalModel, MoveProblem
from flexmotion_ros.core.friction import (
    certificate,
    continuation,
    extremal,
    pattern_search,
    plan_time_optimal_friction,
    sampled_lp,
    simulate_coulomb,
)
from flexmotion_ros.core.friction.certificate import FrictionStatus
from flexmotion_ros.core.friction.contact import ClosedForm, FrictionSystem
from flexmotion_ros.core.friction.continuation import continue_in_friction
from flexmotion_ros.core.friction.sampled_lp import FrictionLP
from flexmotion_ros.core.friction.time_optimal import frictionless_scales
from flexmotion_ros.core.friction.zoh import plan_time_optimal_friction_zoh
from flexmotion_ros.core.simulation.exact import PiecewiseConstant
from flexmotion_ros.core.time_optimal.solver import plan_time_optimal

from .test_sampled_certificate import fuzz_1  # seed-18 case 1: an exact sampled move of 35 x 0.07 s


def fuzz_3():
    """Seed-18 fuzz case 3: the continuation from the frictionless optimum fails (a stick arc is optimal)."""
    m = ModalModel(
        b0=1.3149203870334059,
        c=0.0,
        omega=(1.4770789860688625, 36.383540837222505),
        zeta=(0.2859453294866526, 0.052069422404516216),
        b=(1.8270725388183044, 0.9063610116919681),
    )
    return MoveProblem(m, 0.46516869809156663, [0.0] * m.n_states, 0.0005821571179681396), 0.05561538887722265


def fuzz_2():
    """Seed-18 fuzz case 2: the continuation reaches ``F`` in its first Newton solve."""
    m = ModalModel(
        b0=2.3439555016096496, c=0.0, omega=(6.961156899566678,), zeta=(0.2035088397773171,), b=(-0.5750588807387604,)
    )
    return MoveProblem(m, 4.0948396817021555, [0.0] * m.n_states, -0.04222571153647792), 1.9646741504252323


def test_zoh_of_a_sampled_move_reuses_its_checked_run(monkeypatch, spy):
    """Before: the ZOH ran the event-located check again over all 245 command periods of the 35-sample move.
    Now no event-located run at all; its states agree with one (matrix exponentials) to 1e-10 of the excursion."""
    problem, F = fuzz_1()
    continuous = plan_time_optimal_friction(problem, F, 100.0)
    assert continuous.sample_period is not None and continuous.exact_run is not None
    runs = spy(FrictionSystem, "run")
    sampled = plan_time_optimal_friction_zoh(problem, F, 100.0, continuous)
    assert not runs
    monkeypatch.undo()  # the reference below runs the real event-located simulation
    u = np.asarray(sampled.commands, float)
    assert u.size == round(continuous.duration * 100.0)
    assert np.max(np.abs(u)) <= problem.u_max
    dt = 0.01
    ref = (
        FrictionSystem.for_model(problem.model, F)
        .run(problem.x0, PiecewiseConstant.from_samples(u, dt), dt * np.arange(u.size + 1))
        .states
    )
    scale = np.max(np.abs(ref), axis=0) + 1e-300
    assert np.max(np.abs(np.asarray(sampled.states) - ref) / scale) <= 1e-10


def test_structure_lp_rows_are_built_in_compressed_columns(spy):
    """Before: triplets converted coo -> csr here and csr -> csc in the solver call.  Now the rows arrive in
    compressed columns, the same matrix as the triplet assembly of the LP's equations."""
    problem, F = fuzz_1()
    lp = FrictionLP(problem, F, 0.07)
    K = 40
    s = np.ones(K)
    s[10:14] = 0.0  # a stuck stretch: no drive of the rigid body there
    seen = {}
    spy(sampled_lp, "solve_lp", lambda **kw: seen.update(kw))
    sol = lp.solve(K, s)
    A = seen["A_eq"]
    assert sparse.issparse(A) and A.format == "csc"
    G, Hf, free, _ = lp.kdata(K)
    G = lp.stuck_rows(G, s == 0.0)
    w = -free + F * (s @ Hf)
    nI = G.shape[1]
    ref = np.zeros((nI + 1 + K, 2 * K + 2))
    ref[:nI, :K], ref[:nI, -1] = G.T, -w
    ref[nI, K], ref[nI, -1] = 1.0, -lp.x0[1]
    for k in range(K):
        r = nI + 1 + k
        ref[r, K + k + 1], ref[r, K + k], ref[r, k], ref[r, -1] = 1.0, -lp.ev, -lp.gv * (s[k] != 0.0), F * lp.fv * s[k]
    assert np.array_equal(A.toarray(), ref)
    assert sol is None or sol.t > 0.0


def _continuation_solves(problem, F, monkeypatch):
    """``(result, [(converged, exact runs) per Newton solve])`` of the continuation to ``F``."""
    base = plan_time_optimal(problem)
    scale, _ = frictionless_scales(problem, base)
    solves = []
    real = continuation.newton_solve

    def counting(*args, **kwargs):
        budget = kwargs.get("budget", args[6] if len(args) > 6 else None)
        before = budget[0]
        out = real(*args, **kwargs)
        solves.append((out[0], before - budget[0]))
        return out

    monkeypatch.setattr(continuation, "newton_solve", counting)
    return continue_in_friction(problem, base, F, scale), solves


def test_a_failing_newton_solve_gives_up_early(monkeypatch):
    """Fuzz case 3: before, the first Newton solve halved its steps on and spent all 48 exact runs of the
    continuation; now it stops at the first step that needs a third halving."""
    problem, F = fuzz_3()
    out, solves = _continuation_solves(problem, F, monkeypatch)
    assert out is None
    converged, runs = solves[0]
    assert not converged and runs <= 24  # was 48: the whole budget


def test_the_budget_left_by_a_failed_solve_certifies_a_move():
    """Fuzz case 111: before, the first solve spent the budget and the move came back
    ``exact_sampled_pattern_optimal`` (0.70 s); now the half step and then the full force converge: a
    certified extremal of 0.694 s, exact in the event-located simulation."""
    m = ModalModel(
        b0=0.3779174579049933, c=0.0, omega=(41.9471999730257,), zeta=(0.10667377282835651,), b=(1.0118850333198148,)
    )
    problem = MoveProblem(m, 1.7279200953778595, [0.0] * m.n_states, 0.07486497673454966)
    F = 0.2302527582469297
    prof = plan_time_optimal_friction(problem, F, 100.0)
    assert prof.certified and prof.duration < 0.6943
    xf = m.rest_state(problem.target)
    x = simulate_coulomb(m, problem.x0, prof.input(), F, [prof.duration, 2.0 * prof.duration + 1.0])
    assert np.max(np.abs(x - xf) / (np.abs(xf) + 1e-3)) <= 1e-8
    assert np.max(np.abs(prof.levels)) <= problem.u_max


def test_a_succeeding_continuation_still_reaches_the_force(monkeypatch):
    """Fuzz case 2 (full Newton steps): still continued to ``F`` in one solve."""
    problem, F = fuzz_2()
    out, solves = _continuation_solves(problem, F, monkeypatch)
    assert out is not None and out[0].sys.F == F
    assert len(solves) == 1 and solves[0][0]


def test_a_repeated_structure_lp_is_answered_without_highs(monkeypatch):
    """The count and pattern searches ask for the same (samples, pattern, signs) LP again (11 % of the LPs of
    seed-18 cases 0-99): HiGHS solves it once, the answer is the same object, its arrays read-only."""
    problem, F = fuzz_3()
    lp = FrictionLP(problem, F, 0.05)
    calls = []
    real = sampled_lp.solve_lp
    monkeypatch.setattr(sampled_lp, "solve_lp", lambda **kw: calls.append(kw) or real(**kw))
    s = np.ones(40)
    first = lp.solve(40, s, signs=False)
    assert first is not None
    assert lp.solve(40, s.copy(), signs=False) is first
    assert len(calls) == 1 and lp.solves == 1
    assert lp.solve(40, s) is not first  # another LP (with sign rows)
    assert len(calls) == 2
    assert not first.u.flags.writeable and not first.pattern.flags.writeable
    fresh = FrictionLP(problem, F, 0.05).solve(40, s, signs=False)
    assert np.array_equal(fresh.u, first.u) and fresh.t == first.t


def fuzz_117():
    """Seed-18 fuzz case 117 (4 modes, c = 0, F = 0.26 u_max): the continuation needs many damped steps."""
    m = ModalModel(
        b0=1.4446872725040838,
        c=0.0,
        omega=(1.265170336310518, 4.7016699726202535, 9.260280994610827, 17.73702223785588),
        zeta=(0.07442385067926148, 0.22553285724464242, 0.29718495907667375, 0.04319857153245638),
        b=(0.6742888237519163, -0.4543616465987259, 0.8894249925294883, -1.0820562071819722),
    )
    u_max = 1.9015541706141468
    return MoveProblem(m, u_max, [0.0] * m.n_states, -2.785122576367948), 0.25931094338372146 * u_max


def test_newton_updates_the_differenced_columns_instead_of_differencing_every_step(spy):
    """Before: every Newton step through a reversal differenced the switching rows in all L + 1 switch times
    (20 of the 26 exact runs of case 2's continuation).  Now they are differenced once and then updated along
    the steps (Broyden), differenced again only where an updated Jacobian's step fails: 10 runs in all."""
    problem, F = fuzz_2()
    base = plan_time_optimal(problem)
    scale, _ = frictionless_scales(problem, base)
    runs = spy(FrictionSystem, "run")
    out = continue_in_friction(problem, base, F, scale)
    assert out is not None
    assert 0 < len(runs) <= 12, len(runs)


def test_the_updated_newton_certifies_an_extremal_the_differenced_one_missed():
    """Case 117: before, the continuation's Newton stalled (its step through the differenced Jacobian failed
    its line search) and the plan was the sampled move of 4.02 s, certified only for its pattern.  Now the
    continuation converges: a certified extremal of 4.00 s, checked by the exact friction simulation."""
    problem, F = fuzz_117()
    prof = plan_time_optimal_friction(problem, F, 100.0)
    assert prof.certified
    assert prof.duration < 4.0
    xf = problem.model.rest_state(problem.target)
    x = simulate_coulomb(problem.model, problem.x0, prof.input(), F, [prof.duration, 2.0 * prof.duration + 1.0])
    full = simulate_coulomb(problem.model, problem.x0, prof.input(), F, np.linspace(0.0, prof.duration, 200))
    scale = np.max(np.abs(full - xf), axis=0) + 1e-300
    assert np.max(np.abs(x - xf) / scale) < 1e-8
    assert prof.lower_bound is None or prof.duration >= prof.lower_bound


# ------------------------------------ issue 18, third pass: where the continuation cannot reach the force
def fuzz_59():
    """Seed-18 fuzz case 59 (1 mode): Newton converges at ``F`` at once, but ``B^T lambda`` changes sign where no
    switch is; the move with the new switch does not converge (the optimum rests on the way)."""
    m = ModalModel(
        b0=0.25144518333834454, c=0.0, omega=(5.105498837600142,), zeta=(0.08731335399612714,), b=(-1.1734925738186242,)
    )
    u_max = 0.19470289959806864
    return MoveProblem(m, u_max, [0.0] * m.n_states, 0.00011437653063550585), 0.22845336361740354 * u_max


def _exact_runs(spy) -> list:
    """A list that gets True per Newton residual that runs (one exact friction run each; past its budget a
    residual answers None without a run) and False per one that does not: count with ``sum``."""
    return spy(extremal.Extremal, "residual", lambda self, *args, **kwargs: self.budget is None or self.budget[0] > 0)


def test_continuation_stops_after_two_failed_solves_in_a_row(monkeypatch):
    """Fuzz case 3: before, the solves at F, F / 2 and F / 4 all failed (48 exact runs); now the continuation stops
    after the second failure in a row (no continuation of seed-18 cases 0-299 that reached F had two)."""
    problem, F = fuzz_3()
    out, solves = _continuation_solves(problem, F, monkeypatch)
    assert out is None
    assert len(solves) == 2  # was 3
    assert continuation.MAX_FAILS_IN_A_ROW == 2
    assert not any(converged for converged, _ in solves)


def test_switch_consistency_re_solves_are_capped(monkeypatch, spy):
    """Fuzz case 59: before, the re-solve with the switches moved to the sign changes of ``B^T lambda`` spent the
    rest of the continuation's 48 exact runs (37) and failed; now each re-solve gets ``RESOLVE_EVALS`` of them
    (1 of 73 such re-solves in seed-18 cases 0-299 converged, in 6), a failed one counts as a failed solve, and
    the plan is the same exact sampled move."""
    problem, F = fuzz_59()
    runs = _exact_runs(spy)
    re_solves = []
    real = certificate.newton_solve

    def recording(*args, **kwargs):  # (converged, exact runs) of each re-solve
        before = sum(runs)
        out = real(*args, **kwargs)
        re_solves.append((out[0], sum(runs) - before))
        return out

    monkeypatch.setattr(certificate, "newton_solve", recording)
    out, solves = _continuation_solves(problem, F, monkeypatch)
    assert out is None
    assert solves and all(converged for converged, _ in solves)  # Newton converged; the switches did not agree
    assert re_solves and all(not ok and n <= 10 for ok, n in re_solves)  # was one re-solve of 37 runs
    assert len(re_solves) <= continuation.MAX_FAILS_IN_A_ROW
    prof = plan_time_optimal_friction(problem, F, 100.0)
    assert prof.duration == pytest.approx(0.43, abs=1e-12)
    assert prof.certificate.status is FrictionStatus.SAMPLED_PATTERN
    xf = problem.model.rest_state(problem.target)
    x = simulate_coulomb(problem.model, problem.x0, prof.input(), F, [prof.duration, 2.0 * prof.duration + 1.0])
    assert np.max(np.abs(x - xf)) <= 1e-8 * abs(problem.target)
    assert np.max(np.abs(prof.levels)) <= problem.u_max


def test_costate_sweep_reuses_the_runs_step_matrices(spy):
    """Before: the costate sweep of a Newton residual formed ``e^{A h}`` for ``h = t1 - t0`` of every segment, which
    differs from the run's own step in the last bit: a second closed form per segment.  Now the run records its step
    lengths and the sweep's matrices are the run's (cache hits), the same sensitivities to rounding."""
    problem, F = fuzz_2()
    base = plan_time_optimal(problem)
    scale, _ = frictionless_scales(problem, base)
    ext = extremal.Extremal(problem, np.asarray(base.levels, float), F, scale)
    y = np.concatenate([base.switch_times, [base.duration], base.certificate.costate_final])
    t_sw, T, lam = ext.unpack(y)
    run = ext.sys.run(problem.x0, PiecewiseConstant.from_switches(t_sw, ext.levels, T), [T], lock_after=float(t_sw[-1]))
    new = spy(ClosedForm, "steps", lambda self, h: h not in self._cache)  # True: a closed form not cached
    Lams = ext.costates(run, lam)
    assert len(new) >= len(run.segments) >= 3 and not any(new)
    assert len(run.lengths) == len(run.segments)
    for (t0, t1, _, _), h in zip(run.segments, run.lengths):
        assert h > 0.0 and abs(t0 + h - t1) <= 1e-15 * T
    # the sweep is the product of the run's own transition matrices (and the identity at T)
    sysf = ext.sys
    assert np.array_equal(Lams[-1], sysf.fast.steps(run.lengths[-1])[0].T)


def test_a_solve_started_from_an_earlier_block_skips_the_differences(spy):
    """Fuzz case 2: the continuation's next solve starts from the previous solve's differenced switching columns
    (Broyden across solves: differenced again only where a step fails).  From the frictionless optimum at ``F``
    again with the first solve's block: the same extremal in fewer exact runs (no L + 1 differences)."""
    problem, F = fuzz_2()
    base = plan_time_optimal(problem)
    scale, _ = frictionless_scales(problem, base)
    levels = np.asarray(base.levels, float)
    y0 = np.concatenate([base.switch_times, [base.duration], base.certificate.costate_final])
    runs = _exact_runs(spy)
    ok1, ext1, y1 = extremal.newton_solve(problem, levels, F, scale, y0, budget=[48], halvings=3)
    first = sum(runs)
    assert ok1 and ext1.block_first is not None and ext1.block_first.shape == (ext1.L, ext1.L + 1)
    ok2, ext2, y2 = extremal.newton_solve(
        problem, levels, F, scale, y0, budget=[48], halvings=3, block=ext1.block_first
    )
    second = sum(runs) - first
    assert ok2 and ext2.block_first is None  # no differences at the start
    assert second <= first - ext1.L  # (L + 1 differences saved, give or take a line-search trial)
    assert np.allclose(y2, y1, rtol=1e-9, atol=1e-12 * np.max(np.abs(y1)))


def fuzz_41():
    """Seed-18 fuzz case 41 (4 modes, c = 0): its count search at 0.17 s samples probes counts near 62."""
    m = ModalModel(
        b0=1.84916349532185,
        c=0.0,
        omega=(0.6088781094104881, 1.9155854623425015, 2.5018157748938226, 5.173572720946352),
        zeta=(0.29433346250130293, 0.244042055301409, 0.2975567414616436, 0.01338970225000503),
        b=(-1.8410536927437477, 1.886742123085353, -0.8058056550129307, -1.6326457074709795),
    )
    u_max = 0.1617941799213381
    return MoveProblem(m, u_max, [0.0] * m.n_states, 2.998892594812966), 0.1073952239425012 * u_max


def _with_signs(K, s, signs=True, *args, **kwargs) -> bool:
    """Whether a :meth:`FrictionLP.solve` call is of the LP with sign rows."""
    return bool(signs)


def test_a_pattern_whose_relaxation_is_past_the_peak_is_not_solved_with_sign_rows(spy):
    """Fuzz case 41: the fixed point of the pattern solves each candidate with sign rows; where the same LP
    without them (a relaxation: its least peak a lower bound) already needs more than ``u_max``, the signed LP
    cannot be of use to the count search, and is no longer solved.  Counts 55-69: the same answer wherever one
    within ``u_max`` exists, 11 signed LPs instead of 25."""
    problem, F = fuzz_41()
    um = problem.u_max * (1.0 + 1e-12)
    before, after = 0, 0
    for K in range(55, 70):
        s0 = np.ones(K)
        lp_ref = FrictionLP(problem, F, 0.17, monotone_rows=True)
        ref_lps = spy(lp_ref, "solve", _with_signs)
        ref = pattern_search.consistent_pattern(lp_ref, K, s0)
        lp_new = FrictionLP(problem, F, 0.17, monotone_rows=True)
        new_lps = spy(lp_new, "solve", _with_signs)
        new = pattern_search.consistent_pattern(lp_new, K, s0, peak_max=um)
        before, after = before + sum(ref_lps), after + sum(new_lps)
        if new is None:
            assert ref is not None and ref.t > um  # nothing within u_max was left out
        else:
            assert ref is not None and new.t == ref.t and np.array_equal(new.u, ref.u)
    assert after <= before - 10, (before, after)  # 11 of 25


def test_switch_segments_are_looked_up_not_searched():
    """A Newton residual found the segment starting at each switch by ``argmin |starts - t_j|`` (twice per switch);
    a switch is a break of the input, so a segment starts exactly there: a lookup, the same indices.  A time that
    is no segment start still gets the nearest one."""
    problem, F = fuzz_117()
    base = plan_time_optimal(problem)
    scale, _ = frictionless_scales(problem, base)
    ext = extremal.Extremal(problem, np.asarray(base.levels, float), F, scale)
    t_sw, T = np.asarray(base.switch_times, float), base.duration
    run = ext.sys.run(problem.x0, PiecewiseConstant.from_switches(t_sw, ext.levels, T), [T], lock_after=float(t_sw[-1]))
    starts = np.array([seg[0] for seg in run.segments])
    assert len(run.segments) > t_sw.size  # reversals split the arcs
    assert extremal.segment_at(run, t_sw) == [int(np.argmin(np.abs(starts - t))) for t in t_sw]
    odd = 0.5 * (starts[1:] + starts[:-1]) + 1e-3 * np.diff(starts)
    assert extremal.segment_at(run, odd) == [int(np.argmin(np.abs(starts - t))) for t in odd]
