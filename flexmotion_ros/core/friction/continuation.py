"""Continuation in the friction force from the certified frictionless optimum (the fast path).

Newton's method on the extremal conditions (:class:`~.extremal.Extremal`) at
``F_try``, from the solution at the last force reached, with the step doubled
after a success and halved after a failure.  At every step the switches must
be the sign changes of ``B^T lambda`` (:func:`~.structure.consistent_switches`);
a pair of switches that merges is dropped.  Where the structure changes in a
way this cannot follow, the continuation stops and says so (None): the
planner then finds the structure from a sampled move (:mod:`.structure`)
instead of guessing on.  The number of Newton solves is bounded, so a stalled
continuation costs little.
"""

from __future__ import annotations

import numpy as np

from ..model.boundary import MoveProblem
from ..results import BangBangProfile
from .certificate import consistent_switches
from .extremal import Extremal, newton_solve

#: Newton iterations per solve (a step that needs more is too long: halve it).
MAX_ITER = 12
#: Residual evaluations (one exact friction run each) the whole continuation may spend.
MAX_EVALS = 48
#: Newton solves the continuation may spend before it gives up.
MAX_SOLVES = 8
#: Line-search trials per Newton step in the continuation (``1, 1/2, 1/4``; the default is 8).  In the
#: seed-18 fuzz (cases 0-299) every continuation solve that converged took full, half or quarter steps;
#: the failing ones halved further, each halving an exact run, until the budget was spent (2026-12-05).
LINE_SEARCH_TRIALS = 3

#: Failed Newton solves (or switch-consistency re-solves) in a row after which the continuation gives up.  In
#: the seed-18 fuzz (cases 0-299, 2026-12-06) every continuation that reached F had at most one failed solve in
#: a row (8 of 83 one: at F, then F / 2 and F converged); the 217 that failed halved on for 10-40 ms more.
MAX_FAILS_IN_A_ROW = 2
#: Residual evaluations of one re-solve with the switches moved to the sign changes of ``B^T lambda``
#: (:func:`~.certificate.consistent_switches`).  In the seed-18 fuzz (cases 0-299, 2026-12-06) 1 of 73 such
#: re-solves in the continuation converged (in 6 evaluations); the 72 that failed took 21 on average (up to
#: 38, most of a failing continuation's 20-50 ms).
RESOLVE_EVALS = 10
#: Residual evaluations of a Newton solve after a failed one (a failed solve or re-solve: the force step halved,
#: from the failed solve's start and differences).  In the seed-18 fuzz (1,000 cases, 2026-12-06) every such
#: solve in a continuation that reached ``F`` converged in 5-10 runs (32 solves); the 820 in continuations that
#: failed took a median of 10, up to 31 (a failing one differences its columns again, ``L + 1`` runs, before
#: giving up).  A retry that fails is the second failure in a row: the continuation then stops.
RETRY_EVALS = 12


def continue_in_friction(
    problem: MoveProblem,
    base: BangBangProfile,
    F: float,
    scale: np.ndarray,
    max_solves: int = MAX_SOLVES,
    max_evals: int = MAX_EVALS,
) -> tuple[Extremal, np.ndarray, int] | None:
    """``(extremal, y, solves)`` at friction ``F`` continued from the frictionless optimum, or None.

    At most ``max_solves`` Newton solves and ``max_evals`` residual evaluations in all.
    """
    budget = [max_evals]
    levels = np.asarray(base.levels, float)
    lam0 = np.asarray(base.certificate.costate_final, float)
    y = np.concatenate([base.switch_times, [base.duration], lam0])
    done, step, solves = 0.0, F, 0
    ext = None
    failed = 0  # failed solves in a row
    block = None  # the switching rows' differenced columns to start the next solve from (Broyden across solves)
    while ext is None or done < F:
        if solves >= max_solves or budget[0] <= 0 or failed >= MAX_FAILS_IN_A_ROW:
            return None
        F_try = min(F, done + step)
        # after a failure a smaller share of the budget: a retry that converges does so in a few runs
        own = [min(budget[0], RETRY_EVALS)] if failed else budget
        left = own[0]
        ok, ext_new, y_new = newton_solve(
            problem, levels, F_try, scale, y, MAX_ITER, own, LINE_SEARCH_TRIALS, block=block
        )
        if own is not budget:
            budget[0] -= left - own[0]
        solves += 1
        # the next solve starts where this one did (after a failure) or ended (after a success, same switches):
        # the differences in the L + 1 switch times were a third of a continuation's exact runs
        nxt = ext_new.block_last if ok else ext_new.block_first
        block = nxt if nxt is not None else (None if ok else block)
        if ok:
            # converged; where B^T lambda changes sign where no switch is, a re-solve with the new structure
            # (a failure counts as a failed solve: the structure changes before F_try, and a smaller step may
            # follow it, as on the three-mode beam of the tests)
            out = consistent_switches(problem, ext_new, y_new, F_try, scale, budget, RESOLVE_EVALS)
            ok = out is not None
            if ok:
                ext_new, y_new = out
        if ok:
            failed = 0
            levels, y, done, ext = ext_new.levels, y_new, F_try, ext_new
            step = min(2.0 * step, F - done) if done < F else step
            continue
        failed += 1
        step *= 0.5
        if step < 1e-2 * max(F, 1e-300):
            # a pair of switches may have merged (its interval shrinks to zero where the structure
            # ends): drop the closest pair and re-solve at the last force reached
            L = levels.size - 1
            gaps = np.diff(y[:L])
            if not gaps.size or gaps.min() >= 0.1 * y[L]:
                return None
            k = int(np.argmin(gaps))
            ok2, ext2, y2 = newton_solve(
                problem,
                np.delete(levels, [k + 1, k + 2]),
                done,
                scale,
                np.delete(y, [k, k + 1]),
                budget=budget,
                halvings=LINE_SEARCH_TRIALS,
            )
            solves += 1
            if not ok2:
                return None
            levels, y, ext = ext2.levels, y2, ext2
            step = max(F - done, 0.0) * 0.25
    return ext, y, solves
