"""Arrive at a requested time: the lowest force bound whose time-optimal move takes that long.

Several axes or machines arrive together if each arrives, at rest and
without vibration, at one requested time ``T_req`` no shorter than its own
optimum ``T*``.  Among all inputs that do so, the one with the smallest peak
``|u|`` is the time-optimal move for the bound ``u'`` with ``T*(u') = T_req``:
``T*(u')`` decreases strictly with ``u'`` (reachable sets grow with the
bound), so an input with a smaller peak would arrive later.  Using less than
the full force leaves margin for disturbances and model error.

Method
------
1. ``T* = T*(u_max)`` from :func:`~.time_optimal.plan_time_optimal`; requests
   below it are refused (``arrival_time`` must be ``>= T*``).
2. Safeguarded root-find of ``log T*(u') = log T_req`` in ``log u'``
   (Brent's method on a bracket; each evaluation a certified time-optimal
   plan).  For rest-to-rest moves linearity gives an independent check:
   the move by ``gamma`` at bound ``u'`` is ``u'/u_max`` times the move by
   ``gamma u_max / u'`` at ``u_max``.
3. Newton on the switch times and ``u'`` with the duration held at exactly
   ``T_req`` (closed-form final state and Jacobian), then the exact
   matrix-exponential check and the Pontryagin certificate at bound ``u'``,
   which proves ``T_req`` minimal for ``u'`` and so ``u'`` the lowest bound.

The bound search (step 2) and the arrival check are in :mod:`.fixed_time_bound`,
the Newton steps at a fixed duration (step 3, and the continuation in ``T``
from ``T*`` tried first) in :mod:`.fixed_time_newton`; this module is the
planner, its exact check and its certificate.

The sampled version (:func:`plan_fixed_time_zoh`) is the least-peak linear
program of :mod:`.zoh` at exactly ``round(T_req * rate_hz)`` samples.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..errors import SolverError
from ..model.boundary import MoveProblem
from ..results import BangBangProfile
from ..simulation.exact import PiecewiseConstant, simulate
from ..simulation.prepared import PreparedMove, prepare
from ..tolerances import FINAL_STATE_RTOL
from .certificate import certify
from .fixed_time_bound import TRY_STRUCTURE_LOG, bound_search, check_arrival_time
from .fixed_time_newton import CONTINUATION_RTOL, continue_in_time, polish, polish_with_costate
from .solver import plan_time_optimal


def plan_fixed_time(problem: MoveProblem | PreparedMove, arrival_time: float) -> BangBangProfile:
    """Vibration-free move arriving at rest at exactly ``arrival_time`` with the least peak force.

    Parameters
    ----------
    problem : MoveProblem or PreparedMove
        The move; a :class:`PreparedMove` reuses its responses and, if
        attached, its time-optimal profile (else it is solved here).
    arrival_time : float
        Requested move time ``T_req`` (s), ``>= T*`` (the time-optimal time at ``u_max``).

    Returns
    -------
    BangBangProfile
        ``method = "fixed_time"``, ``duration == arrival_time``, levels
        ``+-u'`` with ``u' <= u_max`` (``extra["bound_used"]``); the
        certificate is the Pontryagin certificate at bound ``u'``.

    Raises
    ------
    FlexmotionError
        ``arrival_time`` below ``T*`` or not finite (names ``arrival_time`` and the range).
    SolverError
        No profile passes the exact final-state check.
    """
    t0 = time.perf_counter()
    move = prepare(problem)
    problem = move.problem
    best = move.continuous if move.continuous is not None else plan_time_optimal(move)
    move = move.with_continuous(best)
    T_star = best.duration
    T_req = check_arrival_time(arrival_time, T_star)
    if best.duration == 0.0:  # already at rest: hold still until the requested time
        return _assemble(move, T_req, np.empty(0), np.array([1.0]), 0.0, best, T_star, t0)
    # fast path: continuation in the duration from T*, Newton on (switch times, u') at each step
    cont = continue_in_time(move, best, T_req)
    if cont is not None:
        switch_times, bound = cont
        try:
            out = _assemble(
                move, T_req, switch_times, np.sign(best.levels), min(bound, problem.u_max), best, T_star, t0
            )
        except SolverError:  # the exact check refused it: the root-find below
            out = None
        if out is not None and out.certified and bound <= problem.u_max:
            return out
    # otherwise the root-find on u' finds the structure at T_req (the structure changes on the way):
    # each profile near T_req is tried there (one Newton), the first certified one is the answer
    err_best, x_best, prof_best = math.inf, math.log(problem.u_max), best
    for x, prof in bound_search(move, best, T_req, 1e-15):
        err = abs(math.log(prof.duration / T_req))
        if err < err_best:
            err_best, x_best, prof_best = err, x, prof
        if err < TRY_STRUCTURE_LOG:
            out = _at_arrival(move, T_req, prof, math.exp(x), T_star, t0)
            if out is not None and out.certified:
                return out
    # none certified: the closest profile's structure, polished at T_req and checked (or refused)
    bound, prof = math.exp(x_best), prof_best
    signs = np.sign(prof.levels)
    switch_times, bound, _ = polish(move, T_req, prof.switch_times * (T_req / prof.duration), signs, bound)
    if bound > problem.u_max:
        if bound > problem.u_max * (1.0 + 1e-9):
            raise SolverError(f"fixed-time planner needs bound {bound} > u_max = {problem.u_max}; nothing is returned")
        bound = problem.u_max
    return _assemble(move, T_req, switch_times, signs, bound, prof, T_star, t0)


def _at_arrival(move: PreparedMove, T_req: float, prof: BangBangProfile, bound: float, T_star: float, t0: float):
    """``prof``'s switch structure polished (Newton) at exactly ``T_req`` and assembled; None if it fails."""
    signs = np.sign(prof.levels)
    guess = prof.switch_times * (T_req / prof.duration)
    if guess.size + 1 > move.x0.size and prof.certificate is not None:  # arrival alone: a family of moves
        nu = -np.asarray(prof.certificate.costate_final, float)
        switch_times, bound, res = polish_with_costate(move, T_req, guess, signs, bound, nu)
    else:
        switch_times, bound, res = polish(move, T_req, guess, signs, bound)
    if not (res <= CONTINUATION_RTOL and 0.0 < bound <= move.u_max * (1.0 + 1e-9)):
        return None
    try:
        return _assemble(move, T_req, switch_times, signs, min(bound, move.u_max), prof, T_star, t0)
    except SolverError:
        return None


def _assemble(
    move: PreparedMove, T, switch_times, signs, bound, ref: BangBangProfile, T_star: float, t0: float
) -> BangBangProfile:
    levels = bound * np.asarray(signs, float)
    u = PiecewiseConstant.from_switches(switch_times, levels, T)
    problem = move.problem
    x0s = move.x0
    sysr = move.response
    states = simulate((sysr.A(), sysr.B()), x0s, u)  # the independent matrix-exponential check
    xT = states[-1]
    sc = np.abs(x0s) + np.max(np.abs(states), axis=0)
    sc = np.where(sc > 0.0, sc, 1.0)
    err = float(np.max(np.abs(xT))) if xT.size else 0.0
    rel = float(np.max(np.abs(xT) / sc)) if xT.size else 0.0
    if bound > 0.0 and T > 0.0:
        # co-state direction: the reference one, projected onto the directions that vanish at the switches
        nu = -np.asarray(ref.certificate.costate_final, float)
        if len(switch_times):
            E = sysr.expm_B(T - np.asarray(switch_times))  # rows: e^{A tau_j} B, nu must be orthogonal
            if E.shape[0] >= nu.size - 1:
                nu = np.linalg.svd(E)[2][-1]  # the (numerical) null direction
            else:
                Q, _ = np.linalg.qr(E.T)
                nu = nu - Q @ (Q.T @ nu)
            # orientation: S must have the sign of the first level just after the start
            tau0 = T - 0.5 * float(np.concatenate([switch_times, [T]])[0])
            if np.sign(sysr.switching(nu, np.array([tau0]))[0]) != np.sign(levels[0]):
                nu = -nu
        cert = certify(sysr, nu, T, bound, switch_times, levels, states)
    else:
        cert = ref.certificate
    final_abs = simulate(problem.model, problem.x0, u, times=[T])[0]
    prof = BangBangProfile(
        problem=problem,
        switch_times=np.asarray(switch_times, float),
        levels=levels,
        duration=float(T),
        final_state=final_abs,
        final_state_error=err,
        final_state_error_relative=rel,
        certificate=cert,
        solve_time_s=time.perf_counter() - t0,
        method="fixed_time",
        extra={"bound_used": float(bound), "time_optimal_duration": float(T_star)},
    )
    if not rel <= FINAL_STATE_RTOL or np.max(np.abs(levels), initial=0.0) > problem.u_max:
        raise SolverError(
            f"fixed-time planner missed the target: relative final-state error {rel:.3e}; nothing is returned"
        )
    return prof
