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

The sampled version (:func:`plan_fixed_time_zoh`) is the least-peak linear
program of :mod:`.zoh` at exactly ``round(T_req * rate_hz)`` samples.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from ..errors import InputError, SolverError
from ..model.boundary import MoveProblem
from ..results import BangBangProfile
from ..simulation.exact import PiecewiseConstant, simulate
from ..simulation.prepared import PreparedMove, prepare
from ..tolerances import FINAL_STATE_RTOL, SAME_TIME_RTOL
from .certificate import certify
from .solver import plan_time_optimal
from .warm_start import WarmStart, remainder


def check_arrival_time(arrival_time, T_star: float) -> float:
    """``arrival_time`` as float if finite and ``>= T*``, else raise naming the parameter and the range."""
    try:
        T = float(arrival_time)
    except (TypeError, ValueError):
        raise InputError(
            "arrival_time", f"must be a time in [T*, inf) = [{T_star:.9g}, inf) s, got {arrival_time!r}"
        ) from None
    if not math.isfinite(T) or T < T_star * (1.0 - SAME_TIME_RTOL):
        raise InputError(
            "arrival_time",
            f"must be in [T*, inf) = [{T_star:.9g}, inf) s (T* is the time-optimal move time at u_max), got {T}",
        )
    return max(T, T_star)


#: Most bound evaluations (each a certified time-optimal plan, warm-started) of the root-find.
MAX_BOUND_EVALUATIONS = 60
#: ``|log T*(u') - log T_req|`` below which a profile's structure is tried at ``T_req`` (one Newton).
TRY_STRUCTURE_LOG = 0.05


def _warm_guess(prof: BangBangProfile, T_guess: float) -> WarmStart | None:
    """``prof``'s structure stretched to a duration guess, as the next bound's warm start."""
    warm = remainder(prof, 0.0)
    if warm is None or not prof.duration > 0.0:
        return None
    return replace(warm, roots=warm.roots * (T_guess / prof.duration), duration=T_guess)


def _bound_search(move: PreparedMove, best: BangBangProfile, T_req: float, xtol: float):
    """Profiles ``(x, T*(e^x) profile)`` of a safeguarded secant search of ``log T*(e^x) = log T_req``.

    Regula falsi with the Illinois rule on a bracket (``T*`` falls strictly
    with the bound), every evaluation a certified time-optimal plan
    warm-started from the nearest profile already solved (stretched to the
    duration the secant predicts): when the switch structure is the same,
    Newton on the switches replaces the cold solve.  At most
    :data:`MAX_BOUND_EVALUATIONS` plans.  Yields each evaluated profile.
    """
    um = move.u_max
    target = math.log(T_req)
    known: list[tuple[float, float, BangBangProfile]] = [(math.log(um), math.log(best.duration) - target, best)]

    def evaluate(x: float) -> tuple[float, BangBangProfile]:
        near = sorted(known, key=lambda k: abs(k[0] - x))
        if len(near) >= 2 and near[0][0] != near[1][0]:
            slope = (near[0][1] - near[1][1]) / (near[0][0] - near[1][0])
        else:
            slope = -0.5  # the rigid body's T ~ u'^(-1/2)
        g_guess = near[0][1] + slope * (x - near[0][0])
        warm = _warm_guess(near[0][2], math.exp(target + g_guess))
        prof = plan_time_optimal(move.with_bound(math.exp(x)), warm_start=warm)
        g = math.log(prof.duration) - target
        known.append((x, g, prof))
        return g, prof

    x_hi, g_hi = known[0][0], known[0][1]
    # T* grows at least like u'^(-1/2) as u' falls (rigid body, from rest); bracket from a guess
    x_lo = x_hi + 2.0 * g_hi
    g_lo, prof = evaluate(x_lo)
    yield x_lo, prof
    n = 1
    while g_lo < 0.0 and n < MAX_BOUND_EVALUATIONS:
        x_hi, g_hi, x_lo = x_lo, g_lo, x_lo - math.log(4.0)
        g_lo, prof = evaluate(x_lo)
        n += 1
        yield x_lo, prof
    if g_lo < 0.0:
        return
    side = 0
    while n < MAX_BOUND_EVALUATIONS and abs(x_hi - x_lo) > xtol and g_lo != 0.0 and g_hi != 0.0:
        x = (x_lo * g_hi - x_hi * g_lo) / (g_hi - g_lo)
        if not min(x_lo, x_hi) < x < max(x_lo, x_hi):
            x = 0.5 * (x_lo + x_hi)
        g, prof = evaluate(x)
        n += 1
        yield x, prof
        if g > 0.0:
            x_lo, g_lo = x, g
            if side == 1:
                g_hi *= 0.5  # Illinois: the end kept twice in a row counts half
            side = 1
        elif g < 0.0:
            x_hi, g_hi = x, g
            if side == -1:
                g_lo *= 0.5
            side = -1
        else:
            return


def lowest_bound(
    problem: MoveProblem | PreparedMove, arrival_time: float, T_star: float | None = None, xtol: float = 1e-15
) -> tuple[float, BangBangProfile]:
    """The bound ``u' <= u_max`` whose time-optimal move takes ``arrival_time`` (root-find; see module notes).

    ``problem``: a :class:`PreparedMove` shares its responses with every
    bound tried, and its attached time-optimal profile (at ``u_max``) is used
    instead of solving again.  Returns ``(u', profile at u')``; the profile's
    duration equals ``arrival_time`` (s) to the root-finder's tolerance (the
    caller polishes).
    """
    move = prepare(problem)
    um = move.u_max
    best = move.continuous if move.continuous is not None else plan_time_optimal(move)
    T_star = best.duration if T_star is None else T_star
    T_req = check_arrival_time(arrival_time, T_star)
    if T_req <= T_star * (1.0 + SAME_TIME_RTOL):
        return um, best
    found = (math.inf, math.log(um), best)
    for x, prof in _bound_search(move, best, T_req, xtol):
        err = abs(math.log(prof.duration / T_req))
        if err < found[0]:
            found = (err, x, prof)
    return math.exp(found[1]), found[2]


def _polish(
    move: PreparedMove, T: float, switch_times: np.ndarray, signs: np.ndarray, bound: float, max_iter: int = 30
):
    """Newton on ``(t_1..t_L, u')`` with the duration fixed at ``T``: final state exactly at rest.

    ``x(T) = e^{AT} x0 + u' sum_k sign_k (Gamma(T - t_k) - Gamma(T - t_{k+1}))``
    with ``Gamma(tau) = int_0^tau e^{As} B ds``; ``dx/dt_j = u' (sign_{j-1} - sign_j) e^{A (T - t_j)} B``.
    """
    sys = move.response
    x0 = move.x0
    scale = np.abs(x0) + bound * np.max(np.abs(sys.input_integral(np.linspace(0.0, T, 65))), axis=0)
    scale = np.where(scale > 0.0, scale, 1.0)
    eAx = sys.expm_x(T, x0)
    L = switch_times.size

    def resid(z):
        t, ub = z[:L], z[L]
        G = sys.input_integral(T - np.concatenate([[0.0], t, [T]]))
        contrib = (signs[:, None] * (G[:-1] - G[1:])).sum(axis=0)
        return (eAx + ub * contrib) / scale, contrib

    def jacobian(z, contrib):
        J = np.empty((contrib.size, L + 1))
        if L:
            J[:, :L] = (z[L] * (signs[:-1] - signs[1:])[:, None] * sys.expm_B(T - z[:L])).T / scale[:, None]
        J[:, L] = contrib / scale
        return J

    z, r = _damped_newton(np.concatenate([switch_times, [bound]]), resid, jacobian, L, T, max_iter)
    return z[:L], float(z[L]), float(np.max(np.abs(r)))


def _damped_newton(z, resid, jacobian, L: int, T: float, max_iter: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Newton on ``z = (t_1..t_L, u', ...)`` with step halving; the last ``(z, residual)``.

    A step is taken only if it keeps ``0 < t_1 < ... < t_L < T`` and ``u' > 0`` and lowers the largest
    residual; it stops at rounding (``4 eps``), after ``max_iter`` steps or 20 halvings without progress.
    ``resid(z)`` returns ``(residual, contrib)``, ``jacobian(z, contrib)`` the Jacobian there.
    """
    r, contrib = resid(z)
    rn = float(np.max(np.abs(r)))
    for _ in range(max_iter):
        if rn <= 4.0 * np.finfo(float).eps:
            break
        step, *_ = np.linalg.lstsq(jacobian(z, contrib), -r, rcond=None)
        h = 1.0
        for _ in range(20):
            zc = z + h * step
            tc = zc[:L]
            if zc[L] > 0.0 and (L == 0 or (tc[0] > 0.0 and tc[-1] < T and np.all(np.diff(tc) > 0.0))):
                rc, cc = resid(zc)
                rcn = float(np.max(np.abs(rc)))
                if rcn < rn:
                    break
            h *= 0.5
        else:
            break
        z, r, contrib, rn = zc, rc, cc, rcn
    return z, r


#: Relative final-state residual at which a continuation step is accepted.  Newton on the
#: closed forms stalls at rounding, ``~ eps (1 + omega_max T)`` of the excursion (phases of
#: ``omega T``): 1e-13 refused a 100 s move with a 42 rad/s mode at 3e-13 and sent it to the
#: root-find (17 full solves).  The returned move is judged by the exact check (``FINAL_STATE_RTOL``)
#: and the certificate, not by this.
CONTINUATION_RTOL = 1e-10
#: Most continuation steps (each one Newton solve); past it the root-find takes over.
MAX_CONTINUATION_STEPS = 60


def _polish_with_costate(
    move: PreparedMove, T: float, switch_times: np.ndarray, signs: np.ndarray, bound: float, nu: np.ndarray
):
    """Newton on ``(t_1..t_L, u', nu)``: at rest at ``T`` and ``S(T - t_j) = 0`` at every switch.

    With more switches than states (``L + 1 > n``) the arrival equations alone
    leave a family of exact moves; :func:`_polish` lands on one near its start,
    not on the optimum, whose certificate then fails until the root-find has
    ``T*(u')`` to 1e-10 (fuzz case 227: 17 time-optimal solves).  Adding
    Pontryagin's switching conditions for one co-state (``nu`` normalised
    against the reference's direction) makes the system square.  Returns
    ``(switch_times, u', residual)``.
    """
    sys = move.response
    x0 = move.x0
    n = x0.size
    L = switch_times.size
    scale = np.abs(x0) + bound * np.max(np.abs(sys.input_integral(np.linspace(0.0, T, 65))), axis=0)
    scale = np.where(scale > 0.0, scale, 1.0)
    eAx = sys.expm_x(T, x0)
    ref = np.asarray(nu, float) * scale
    ref = ref / np.linalg.norm(ref)

    def resid(z):
        t, ub, nus = z[:L], z[L], z[L + 1 :]
        G = sys.input_integral(T - np.concatenate([[0.0], t, [T]]))
        contrib = (signs[:, None] * (G[:-1] - G[1:])).sum(axis=0)
        S = sys.switching(nus / scale, T - t)
        return np.concatenate([(eAx + ub * contrib) / scale, S, [nus @ ref - 1.0]]), contrib

    def jacobian(z, contrib):
        t, ub, nus = z[:L], z[L], z[L + 1 :]
        J = np.zeros((n + L + 1, L + 1 + n))
        E = sys.expm_B(T - t) / scale  # rows: e^{A tau_j} B in scaled units
        J[:n, :L] = (ub * (signs[:-1] - signs[1:])[:, None] * E).T
        J[:n, L] = contrib / scale
        _, dS = sys.switching(nus / scale, T - t, derivative=True)
        J[n : n + L, :L] = np.diag(-dS)
        J[n : n + L, L + 1 :] = E
        J[n + L, L + 1 :] = ref
        return J

    z, r = _damped_newton(np.concatenate([switch_times, [bound], ref]), resid, jacobian, L, T, 30)
    return z[:L], float(z[L]), float(np.max(np.abs(r[:n])))


def _continuation_tangent(move: PreparedMove, T: float, t_sw: np.ndarray, signs: np.ndarray, ub: float):
    """``d(t_1..t_L, u')/dT`` along the fixed-structure solution curve (least squares), or None."""
    sys = move.response
    L = t_sw.size
    # dx(T)/dT at fixed switches: A e^{AT} x0 + u' (sign_0 e^{AT} B + sum_j (sign_j - sign_{j-1}) e^{A (T - t_j)} B)
    jumps = np.concatenate([[signs[0]], signs[1:] - signs[:-1]])
    dF = sys.A_x(sys.expm_x(T, move.x0)) + ub * (jumps[:, None] * sys.expm_B(T - np.concatenate([[0.0], t_sw]))).sum(
        axis=0
    )
    G = sys.input_integral(T - np.concatenate([[0.0], t_sw, [T]]))
    J = np.empty((dF.size, L + 1))
    if L:
        J[:, :L] = (ub * (signs[:-1] - signs[1:])[:, None] * sys.expm_B(T - t_sw)).T
    J[:, L] = (signs[:, None] * (G[:-1] - G[1:])).sum(axis=0)
    scale = np.max(np.abs(J), axis=1)
    scale = np.where(scale > 0.0, scale, 1.0)
    d, *_ = np.linalg.lstsq(J / scale[:, None], -dF / scale, rcond=None)
    return d if np.all(np.isfinite(d)) else None


def _continue_in_time(move: PreparedMove, best: BangBangProfile, T_req: float):
    """Follow ``(switch times, u')`` from ``T*`` to ``T_req`` with the switch structure fixed.

    A tangent predictor (the curve's derivative in ``T``) and one Newton
    correction per step; the step doubles on success and shrinks on failure.
    The work is bounded: at most :data:`MAX_CONTINUATION_STEPS` Newton solves
    on the switches (the number of switches, not ``T``, sets each one's cost).
    Returns ``(switch_times, u')`` or None if a step fails (the structure changes).
    """
    signs = np.sign(best.levels)
    T, t_sw, ub = best.duration, best.switch_times.copy(), move.u_max
    step = 0.25
    for _ in range(MAX_CONTINUATION_STEPS):
        if T >= T_req:
            return t_sw, ub
        T_new = min(T_req, T * (1.0 + step))
        d = _continuation_tangent(move, T, t_sw, signs, ub)
        if d is not None:
            t_g, ub_g = t_sw + (T_new - T) * d[:-1], ub + (T_new - T) * d[-1]
        if (
            d is None
            or ub_g <= 0.0
            or (t_g.size and (t_g[0] <= 0.0 or t_g[-1] >= T_new or np.any(np.diff(t_g) <= 0.0)))
        ):
            t_g, ub_g = t_sw * (T_new / T), ub * (T / T_new) ** 2  # the rigid body's scaling
        t_new, ub_new, res = _polish(move, T_new, t_g, signs, ub_g)
        if res <= CONTINUATION_RTOL and ub_new > 0.0:
            T, t_sw, ub = T_new, t_new, ub_new
            step = min(2.0 * step, 1.0)
        else:
            step *= 0.25
            if step < 1e-4:
                return None
    return (t_sw, ub) if T >= T_req else None


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
    cont = _continue_in_time(move, best, T_req)
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
    for x, prof in _bound_search(move, best, T_req, 1e-15):
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
    switch_times, bound, _ = _polish(move, T_req, prof.switch_times * (T_req / prof.duration), signs, bound)
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
        switch_times, bound, res = _polish_with_costate(move, T_req, guess, signs, bound, nu)
    else:
        switch_times, bound, res = _polish(move, T_req, guess, signs, bound)
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
