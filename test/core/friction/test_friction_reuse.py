"""Exact runs resumed at a switch, and the continuation's retry budget (issue 18, branch wip/friction5).

A differenced column of the Newton solve moves one switch: the exact run up to the switch before it is the
last recorded run's, so it resumes there -- the same numbers to the bit, fewer segments propagated.  A Newton
solve after a failed one gets :data:`~flexmotion_ros.core.friction.continuation.RETRY_EVALS` exact runs.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from flexmotion_ros.core import ModalModel, MoveProblem
from flexmotion_ros.core.friction import continuation
from flexmotion_ros.core.friction.contact import FrictionSystem
from flexmotion_ros.core.friction.continuation import continue_in_friction
from flexmotion_ros.core.friction.extremal import Extremal
from flexmotion_ros.core.friction.time_optimal import frictionless_scales
from flexmotion_ros.core.simulation.exact import PiecewiseConstant
from flexmotion_ros.core.time_optimal.solver import plan_time_optimal


def two_mode_model() -> ModalModel:
    return ModalModel(b0=1.0, c=-0.2, omega=(2.0, 7.0), zeta=(0.05, 0.1), b=(0.8, -0.4))


def _same_run(a, b) -> bool:
    return (
        np.array_equal(a.states, b.states)
        and a.segments == b.segments
        and a.lengths == b.lengths
        and all(np.array_equal(x, y) for x, y in zip(a.starts, b.starts, strict=True))
        and [(t, kind) for t, kind, _ in a.events] == [(t, kind) for t, kind, _ in b.events]
        and all(np.array_equal(x, y) for (_, _, x), (_, _, y) in zip(a.events, b.events, strict=True))
    )


@settings(max_examples=40, deadline=None)
@given(
    levels=st.lists(st.sampled_from([-1.0, -0.3, 0.0, 0.4, 1.0]), min_size=3, max_size=8),
    gaps=st.lists(st.floats(0.05, 1.5), min_size=8, max_size=8),
    F=st.floats(0.0, 0.9),
    j=st.integers(0, 6),
    shift=st.floats(-0.04, 0.04),
    closed_form=st.booleans(),
)
def test_a_resumed_run_is_the_fresh_run_to_the_bit(levels, gaps, F, j, shift, closed_form):
    """Reversals, stick arcs and slips included (levels inside and outside the friction band)."""
    model = two_mode_model()
    sysf = FrictionSystem.for_model(model, F, closed_form=closed_form)
    x0 = np.zeros(model.n_states)
    breaks = np.concatenate([[0.0], np.cumsum(gaps[: len(levels)])])
    T = float(breaks[-1])
    recorded = sysf.run(x0, PiecewiseConstant(breaks, np.array(levels)), [T], record=True)
    assert len(recorded.snapshots) == len(levels) - 1
    j = min(j, len(levels) - 2)
    # move the break after snapshot j (the switch at breaks[j + 2], or the end) by a little
    moved = breaks.copy()
    moved[j + 2] += shift * min(gaps[j + 1], gaps[j + 2] if j + 2 < len(levels) else 1.0)
    u = PiecewiseConstant(moved, np.array(levels))
    T2 = float(moved[-1])
    fresh = sysf.run(x0, u, [T2], lock_after=T2 - 1e-3, record=True)
    resumed = sysf.run(x0, u, [T2], lock_after=T2 - 1e-3, record=True, resume=(recorded, j))
    assert _same_run(fresh, resumed)
    assert len(resumed.snapshots) == len(fresh.snapshots)


def fuzz_91() -> tuple[MoveProblem, float]:
    """Seed-18 fuzz case 91 (two modes, the first solve at F fails, F / 2 and F converge)."""
    m = ModalModel(b0=0.1624385351501347, c=0.0, omega=(2.6775175325948934, 31.339179580365897),
                   zeta=(0.26172554781448876, 0.22173607794199518), b=(1.0036100418740708, -1.1396792058990308))  # fmt: skip
    return MoveProblem(m, 0.3372766423691558, [0.0] * m.n_states, -1.3695952924153657e-05), 0.051444966175545455


def test_differenced_columns_resume_the_last_run(spy):
    """Every differenced residual of the continuation of case 91 equals a fresh one, and the residuals
    propagate fewer segments than fresh runs would (the difference runs start at the switch before the column)."""
    problem, F = fuzz_91()
    base = plan_time_optimal(problem)
    scale, _ = frictionless_scales(problem, base)
    real = Extremal.residual
    checked = []

    def residual(self, y, want_lam_jac=False, column=-1, **kwargs):
        out = real(self, y, want_lam_jac, column, **kwargs)
        if column >= 1 and out is not None:
            saved, budget = self._jac_run, self.budget
            self._jac_run, self.budget = None, None
            checked.append(np.array_equal(out, real(self, y, want_lam_jac)))
            self._jac_run, self.budget = saved, budget
        return out

    Extremal.residual = residual
    try:
        out = continue_in_friction(problem, base, F, scale)
    finally:
        Extremal.residual = real
    assert out is not None
    assert checked and all(checked)
    # the resumed runs propagate only the segments after the switch before their column
    fresh_segments = []
    resumed_segments = []

    def count(self, y, want_lam_jac=False, column=-1, **kwargs):
        n0 = len(advances)
        r = real(self, y, want_lam_jac, column, **kwargs)
        (resumed_segments if column >= 1 else fresh_segments).append(len(advances) - n0)
        return r

    advances = spy(FrictionSystem, "advance")
    Extremal.residual = count
    try:
        continue_in_friction(problem, base, F, scale)
    finally:
        Extremal.residual = real
    assert resumed_segments and np.mean(resumed_segments) < np.mean(fresh_segments)


def fuzz_870() -> tuple[MoveProblem, float]:
    """Seed-18 fuzz case 870: the continuation fails at F (10 runs) and at F / 2 (24 runs on main 0f97951)."""
    m = ModalModel(b0=1.227756996943952, c=-0.3580454191236001, omega=(33.10817437056428, 45.51763678410096),
                   zeta=(0.0030680991751525387, 0.19313912939073993), b=(1.3975647874635235, 0.5649222979864416))  # fmt: skip
    return MoveProblem(m, 0.1381779509082399, [0.0] * m.n_states, 0.11642100540126424), 0.03177695270567355


def test_a_retry_after_a_failed_solve_has_its_own_small_budget(spy):
    problem, F = fuzz_870()
    base = plan_time_optimal(problem)
    scale, _ = frictionless_scales(problem, base)
    forces = spy(continuation, "newton_solve", lambda *args, **kwargs: float(args[2]))
    runs = spy(FrictionSystem, "run")  # the exact runs (a residual past the budget makes none)
    assert continue_in_friction(problem, base, F, scale) is None
    assert forces == [F, F / 2]
    # 10 runs at F, then at most RETRY_EVALS at F / 2 (34 in all on main 0f97951)
    assert len(runs) <= 10 + continuation.RETRY_EVALS


def test_a_rejected_line_search_trial_forms_no_jacobian(spy):
    """A trial point whose residual is not below the current one returns ``(r, None, False)``: the same ``r``
    to the bit; the continuation of case 870 (its steps at F and F / 2 rejected) forms fewer Jacobians than
    residuals asked for one."""
    problem, F = fuzz_870()
    base = plan_time_optimal(problem)
    scale, _ = frictionless_scales(problem, base)
    y = np.concatenate([base.switch_times, [base.duration], base.certificate.costate_final])
    ext = Extremal(problem, np.asarray(base.levels, float), F, scale)
    r, J, _ = ext.residual(y, True)
    r_cut, J_cut, rev_cut = ext.residual(y, True, below=0.5 * float(np.max(np.abs(r))))
    assert J is not None and J_cut is None and rev_cut is False
    assert np.array_equal(r, r_cut) and np.array_equal(r, ext.residual(y))
    formed = []
    real = Extremal.residual

    def recording(self, y, want_lam_jac=False, column=-1, below=np.inf):
        out = real(self, y, want_lam_jac, column, below)
        if want_lam_jac and out is not None:
            formed.append(out[1] is not None)
        return out

    Extremal.residual = recording
    try:
        assert continue_in_friction(problem, base, F, scale) is None
    finally:
        Extremal.residual = real
    assert formed.count(False) >= 3  # the rejected trials of the first step at F (at least)
