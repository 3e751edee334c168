"""Time-optimal moves under rigid-body Coulomb friction: the bang-bang extremal, found, not only continued.

The friction model and the exact event-located simulator are :mod:`.contact`.

Time-optimal moves
------------------
With ``|u| = u_max > F`` the contact never sticks during a bang-bang move,
the velocity only crosses zero transversally, and the system is piecewise
linear.  The hybrid maximum principle gives ``u = -u_max sgn(B^T lambda)``,
``lambda' = -A^T lambda`` between events and a jump of ``lambda`` along
``C^T`` at each velocity reversal (``lambda^- = S^T lambda^+``, ``S`` the
saltation matrix), which keeps the Hamiltonian continuous.  The switch times,
the duration and ``lambda(T)`` solve these conditions (final state,
``B^T lambda(t_j) = 0``, ``H = 0``) by Newton's method (:mod:`.extremal`)
from a starting point found in turn by

1. continuation in ``F`` from the certified frictionless optimum
   (:mod:`.continuation`, bounded: it stops where the structure changes);
2. the structure of the fewest-sample move at a coarse rate
   (:mod:`.sampled_lp` and :mod:`.pattern_search`: between reversals the friction is a known force, so
   for a velocity-sign pattern the move is an LP; the pattern is iterated to
   consistency), read off and polished (:mod:`.structure`).  The first
   sample period comes from the proved rigid-body bound (damped too); where
   no sequence exists at a period, finer ones are tried (samples too long for
   the modes to be brought to rest: long moves of a damped rigid body), and
   where no sliding pattern reaches rest, patterns that hold the body by
   friction on the way (``|u| <= F`` while the modes are steered).

The result is checked by the exact friction simulation (rest at the target)
and certified as a Pontryagin extremal (sign structure proved per costate
piece, :mod:`.certificate`).  The friction system is not linear, so an
extremal is *not* proved globally optimal; the rigid-body friction optimum is
reported as a proved lower bound (c = 0, from rest).  When no extremal is
found (e.g. the optimum rests on the way, ``|u| = F`` holding the body while
the modes are steered: a stick arc, outside the bang-bang conditions), the
exact sampled move is returned: with status ``exact_sampled_pattern_optimal``
when the discrete-time Pontryagin conditions of its own velocity-sign/stick
pattern hold (a dual of its least-peak LP, checked: :mod:`.sampled_certificate`;
a stick arc is a boundary arc ``v = 0`` there), else ``exact_sampled``; an exact
bang-bang move whose check failed has status ``exact_not_extremal``.  The
status enum and message say exactly what was proved.  The zero-order-hold
version is :mod:`.zoh`.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..errors import GoalError, InputError, SolverError
from ..model.boundary import MoveProblem
from ..results import BangBangProfile
from ..time_optimal.solver import plan_time_optimal
from .certificate import FrictionCertificate, FrictionStatus
from .contact import FrictionSystem
from .continuation import continue_in_friction
from .lower_bound import rigid_friction_time
from .lp_work import EffortSpent
from .pattern_search import fastest_samples, pattern_template
from .profile import FrictionProfile, better, sampled_profile, try_assemble
from .sampled_lp import FrictionLP
from .structure import extremal_from_samples, has_stick_arcs


def check_coulomb_force(coulomb_force, u_max: float) -> float:
    """``coulomb_force`` as float if in ``[0, u_max)`` N, else raise (names the parameter)."""
    try:
        F = float(coulomb_force)
    except (TypeError, ValueError):
        raise InputError(
            "coulomb_force", f"must be a number in [0, u_max) = [0, {u_max:g}) N, got {coulomb_force!r}"
        ) from None
    if not (math.isfinite(F) and 0.0 <= F < u_max):
        raise InputError(
            "coulomb_force",
            f"must be in [0, u_max) = [0, {u_max:g}) N (at F >= u_max the machine cannot start), got {F}",
        )
    return F


def plan_time_optimal_friction(
    problem: MoveProblem, coulomb_force: float, rate_hz: float | None = None, *, continuation: bool = True
) -> FrictionProfile:
    """Bang-bang move to rest under rigid-body Coulomb friction, checked by exact simulation.

    Parameters
    ----------
    problem : MoveProblem
        Model, bound, initial state, target (``None``: final position free).
    coulomb_force : float
        ``F`` in ``[0, u_max)`` (N).
    rate_hz : float, optional
        Command rate (Hz) of the sampled plan to come: the coarse sampled moves use a whole number of
        its periods, so an ``exact_sampled`` result is itself a command sequence at this rate.
    continuation : bool
        False: skip step 1 (the zero-order-hold planner's fallback when no sequence near the continued
        extremal passes its check: the sampled structure search then gives a sequence at the rate).

    Returns
    -------
    FrictionProfile
        Rests at the target in the exact friction simulation; ``certified``
        if it is a proved Pontryagin extremal (see the module notes).

    Raises
    ------
    FlexmotionError
        ``coulomb_force`` out of range.
    SolverError
        If continuation from the frictionless optimum fails or the result
        misses the target in the exact friction simulation.
    """
    t0 = time.perf_counter()
    F = check_coulomb_force(coulomb_force, problem.u_max)
    base = plan_time_optimal(problem)
    model = problem.model
    lb = rigid_friction_time(model, problem.u_max, F, problem.x0, problem.target)
    if base.duration == 0.0:
        cert = FrictionCertificate(
            passed=True,
            switch_residual=0.0,
            extra_zeros=0,
            unproved_cells=0,
            sign_consistent=True,
            hamiltonian_max_abs=0.0,
            costate_final=np.zeros(model.n_states),
            message="already at rest",
            status=FrictionStatus.AT_REST,
        )
        return FrictionProfile(
            problem=problem,
            coulomb_force=F,
            switch_times=np.empty(0),
            levels=base.levels,
            duration=0.0,
            final_state=problem.x0.copy(),
            final_state_error=0.0,
            final_state_error_relative=0.0,
            reversals=np.empty(0),
            certificate=cert,
            frictionless_duration=0.0,
            lower_bound=lb,
            continuation_steps=0,
            solve_time_s=time.perf_counter() - t0,
        )
    scale, template = frictionless_scales(problem, base)
    direction = 1.0 if (problem.target if problem.target is not None else 0.0) >= problem.x0[0] else -1.0

    def monotone(tau):
        return np.full(np.shape(tau), direction)

    reverses = bool(np.any(template(np.linspace(0.0, 1.0, 257)) != direction))

    best: FrictionProfile | None = None
    # 1. the fast path: continuation in F from the frictionless optimum (bounded)
    cont = continue_in_friction(problem, base, F, scale) if continuation else None
    steps = 0
    if cont is not None:
        ext, y, steps = cont
        best = better(best, try_assemble(ext, y, base, lb, steps, t0))
        if best is not None and best.certified:
            return best
    # 2. the structure of the fewest-sample move at a coarse rate (friction as a known force on each
    #    velocity-sign piece, the pattern iterated to consistency), polished by Newton
    # the first count guessed from the rigid body's slow-down under friction (c = 0 from rest)
    rigid0 = rigid_friction_time(model, problem.u_max, 0.0, problem.x0, problem.target)
    T_first = base.duration * (lb / rigid0 if lb and rigid0 else 1.0)
    T_ref, sampled, finer, warm = T_first, None, STRUCTURE_FINER, None
    # the structure LPs share an effort budget (work, not wall time): a long move whose structure needs
    # fine samples (fuzz case 691 of seed 18: 353 s at least, a 23 rad/s mode, no sequence at 0.63 s samples)
    # solved LPs of 3,800 samples, 2 s each, for a minute
    effort, spent = [STRUCTURE_EFFORT], None
    try:
        for K_c in STRUCTURE_SAMPLES:
            sol, stalled, held = None, False, False
            for _ in range(2):  # a move much slower than the frictionless one: coarser samples
                dt_c = T_ref / K_c
                if rate_hz:  # a whole number of command periods: the sampled move is then a command sequence too
                    dt_c = max(1, round(dt_c * rate_hz)) / rate_hz
                lp = FrictionLP(problem, F, dt_c, effort, monotone_rows=True)
                sol = fastest_samples(lp, warm or template, K_c, K_max=4 * K_c)
                if sol is None and warm is not None:  # the coarser move's pattern did not carry over
                    sol = fastest_samples(lp, template, K_c, K_max=4 * K_c)
                if sol is None and reverses:  # the frictionless move's reversals may not suit: a monotone move
                    sol = fastest_samples(lp, monotone, K_c, K_max=4 * K_c)
                stalled = stalled or lp.stalled
                if sol is not None or not lp.feasible_solves or lp.stalled:
                    break  # found; or no LP had a solution, or more samples stopped helping: finer ones may
                if T_ref == T_first:
                    # before coarser samples, a move held by friction on the way at these (see below): where
                    # both exist the held one was 15-23 x shorter (seed-18 cases 3, 27, 39, 99, 127, 133: e.g.
                    # 1.40 s instead of 32.9 s; the coarser sliding move starts at 4 x the samples' time)
                    # its own effort budget (a quarter of the search's): where it finds nothing the coarser
                    # samples still have theirs (case 686 of seed 18, a 24.9 s move, was refused without)
                    held_lp = FrictionLP(problem, F, dt_c, [STRUCTURE_EFFORT // 4], monotone_rows=True)
                    held = True
                    try:
                        sol = fastest_samples(held_lp, monotone, K_c, K_max=4 * K_c, stick=True)
                    except EffortSpent:
                        sol = None
                    if sol is not None and sampled_profile(held_lp, sol, base, lb, steps, t0) is not None:
                        lp = held_lp
                        break  # (its exact check passed; the coarser samples otherwise: case 686's held
                        # moves failed theirs at every period, and the finer ones spent the budget)
                    sol = None
                T_ref *= 4.0
            if sol is None and not stalled and not held:
                # no sliding pattern reaches rest (every sample moving forward or back): a move that rests on
                # the way, the body held by friction (|u| <= F) while the modes are steered, never moving back
                # (not where the samples are too long to bring the modes to rest: finer ones are tried first)
                dt_c = T_first / K_c
                if rate_hz:
                    dt_c = max(1, round(dt_c * rate_hz)) / rate_hz
                lp = FrictionLP(problem, F, dt_c, effort, monotone_rows=True)
                sol = fastest_samples(lp, monotone, K_c, K_max=4 * K_c, stick=True)
            if sol is None:
                # no sequence at this resolution (samples too long for the modes to be brought to rest, e.g.
                # a long damped move with fast modes): finer samples over the same time
                T_ref = T_first
                continue
            if has_stick_arcs(sol.u, F, sol.t) or np.any(sol.pattern == 0.0):
                # the body rests for a while (|u| <= F holds it while the modes are steered): no bang-bang
                # extremal of the sliding system describes that; the sampled move is the answer if it passes
                # the exact check, else finer samples are tried (an exact bang-bang move found before wins)
                if best is not None:
                    sampled = (lp, sol)
                    break
                prof = sampled_profile(lp, sol, base, lb, steps, t0)
                if prof is not None:
                    return prof
                T_ref = T_first
                continue
            sampled = (lp, sol)
            T_ref = sol.K * lp.dt
            warm = pattern_template(sol.pattern)  # the finer search starts from this move's pattern
            got = extremal_from_samples(problem, sol.u, lp.dt, F, scale, sol.t, [STRUCTURE_EVALS])
            if got is not None:
                best = better(best, try_assemble(*got, base, lb, steps, t0))
                if best is not None and best.certified:
                    return best
            finer -= 1
            if finer < 0:
                break
    except EffortSpent as exc:
        spent = exc  # what was found so far stands
    if best is not None:
        alt = sampled_profile(*sampled, base, lb, steps, t0) if sampled is not None else None
        if alt is not None and alt.duration < best.duration:
            return alt  # neither is a proved extremal: the shorter exact move
        best.alternative = alt
        return best  # exact, not a proved extremal: the certificate says which condition failed
    if sampled is not None:
        prof = sampled_profile(*sampled, base, lb, steps, t0)
        if prof is not None:
            return prof
    if spent is not None:  # nothing found within the budget: refused, naming why (one line)
        raise GoalError(
            "goal",
            f"a move of at least {lb or T_first:.3g} s (proved) under {F:g} N of friction whose modes (up to "
            f"{max(model.omega, default=0.0):.3g} rad/s) need samples of {lp.dt:.2g} s or shorter to be brought "
            f"to rest: its sampled structure (over {round(T_first / lp.dt):,} samples) is past the friction "
            f"planner's work budget; plan it as shorter moves",
        )
    raise SolverError(
        "friction planner: neither the continuation from the frictionless optimum nor the structure of a "
        "sampled move gave an exact move; nothing is returned"
    )


#: Samples of the coarse sampled moves the structure is read from, coarsest first; the finer ones are
#: tried when a coarser one has no sequence (or, up to ``STRUCTURE_FINER`` times, gave no extremal).
STRUCTURE_SAMPLES = (64, 192, 576, 1728)
#: Effort budget (:func:`~.lp_work.lp_effort`, squared LP rows plus columns, summed) of the structure search's
#: LPs: past it the search stops with what it has.  Seed-18 fuzz cases 0-299 spent at most 4.9e8 (case 166,
#: 1.6 s CPU); case 691 spent about 1e10 (a minute) for an 800 s move.
STRUCTURE_EFFORT = 1_000_000_000
#: Finer sampled moves tried after the first one found (its structure gave no certified extremal).
STRUCTURE_FINER = 1
#: Residual evaluations (exact friction runs) Newton may spend on the structure of one sampled move
#: (was 60; in the fuzz profile of 60 cases (seed 18) the 8 structures that converged took 4-9, the 31
#: that failed 1-64: a failure is seldom saved by more evaluations).
STRUCTURE_EVALS = 20


def frictionless_scales(problem: MoveProblem, base: BangBangProfile):
    """Per-state scale (how large each state gets in the frictionless move) and its velocity-sign
    template (sign of ``v`` at normalised time ``tau``, the first guess of the friction pattern)."""
    grid = np.linspace(0.0, base.duration, 257)
    fs0 = FrictionSystem.for_model(problem.model, 0.0, closed_form=True)
    xs = fs0.run(problem.x0, base.input(), grid).states
    xf = problem.model.rest_state(problem.target if problem.target is not None else 0.0)
    scale = np.max(np.abs(xs - xf), axis=0) + np.abs(problem.x0 - xf)
    scale = np.where(scale > 0.0, scale, 1.0)
    v = xs[:, 1]
    direction = 1.0 if (xf[0] - problem.x0[0]) >= 0.0 else -1.0
    sgn = np.where(v > 0.0, 1.0, np.where(v < 0.0, -1.0, direction))
    mids = np.sign(sgn[:-1] + sgn[1:])
    mids[mids == 0.0] = direction

    def template(tau, mids=mids):
        return mids[np.minimum((np.asarray(tau) * mids.size).astype(int), mids.size - 1)]

    return scale, template
