"""Continuous-time minimum-fuel moves for a given move time (seed eq. 2.38).

Fuel is ``J = int_0^T |u(t)| dt`` (N s).  For a final time ``T >= T*`` (the
time-optimal time) Pontryagin's principle gives the *bang-off-bang* input
``u = -u_max dez(B^T lambda)``: full force where ``|B^T lambda| > 1``, zero
where it is below 1.

Time-to-go ``tau = T - t``, ``S(tau) = nu^T e^{A tau} B``: the problem
``min int |u|  s.t.  int_0^T e^{A tau} B u dtau = w := -e^{AT} x0,
|u| <= u_max`` has the concave dual::

    d(nu) = nu^T w - u_max int_0^T (|S(tau)| - 1)_+ dtau

whose maximiser gives the input ``u = u_max sgn(S) [|S| > 1]``.  ``grad d``
is the final-state miss and ``-hess d = u_max sum_j g_j g_j^T / |S'(tau_j)|``
over the crossings of ``|S| = 1`` (``g = e^{A tau} B``), so a damped Newton
method converges from any start; it starts from the dual of the sampled
linear program (:mod:`.fuel_lp`).  Every crossing is isolated *with proof*
(:func:`~flexmotion_ros.core.switching.isolate_roots` applied to ``S -+ 1``),
so the levels are the exact pointwise minimiser of the Lagrangian for the
final ``nu``; with the exact arrival checked by matrix-exponential
simulation, weak duality (``J(u) >= d(nu)`` for *every* admissible ``u``)
certifies optimality: the gap ``J - d(nu)`` is reported.

The fuel/time trade-off curve is in :mod:`.fuel_curve`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import SolverError
from ..model.boundary import MoveProblem
from ..results import BangBangProfile
from ..simulation.error_scale import state_scale
from ..simulation.exact import PiecewiseConstant, simulate
from ..simulation.prepared import PreparedMove, prepare
from ..time_optimal.solver import plan_time_optimal
from ..tolerances import FINAL_STATE_RTOL, T_STAR_RTOL
from .dual import MAX_DUAL_EVALUATIONS, DualEval, dual_eval, dual_evaluation_budget
from .lp import check_move_time, seed_costate


@dataclass
class FuelProfile:
    """A continuous-time bang-off-bang minimum-fuel input and its checks.

    Attributes
    ----------
    problem : MoveProblem
    switch_times : ndarray
        Interior switching times (s).
    levels : ndarray
        Input on each interval: ``+u_max``, ``0`` or ``-u_max``.
    duration : float
        Move time ``T`` (s).
    fuel : float
        ``int |u| dt`` (N s).
    fuel_lower_bound : float
        Weak-duality bound ``d(nu)``: no admissible input arriving at ``T`` uses less.
    costate : ndarray
        ``nu = -lambda(T)`` (the dual variable; unscaled state units).
    final_state, final_state_error, final_state_error_relative
        As for :class:`BangBangProfile` (exact matrix-exponential simulation).
    unproved_cells : int
        Cells where the crossings of ``|S| = 1`` were not isolated with proof.
    """

    problem: MoveProblem
    switch_times: np.ndarray
    levels: np.ndarray
    duration: float
    fuel: float
    fuel_lower_bound: float
    costate: np.ndarray
    final_state: np.ndarray
    final_state_error: float
    final_state_error_relative: float
    unproved_cells: int = 0
    iterations: int = 0
    solve_time_s: float = 0.0
    method: str = "min_fuel"
    extra: dict = field(default_factory=dict)

    @property
    def certified(self) -> bool:
        """Optimal by weak duality: crossings proved, duality gap closed."""
        gap = self.fuel - self.fuel_lower_bound
        return self.unproved_cells == 0 and gap <= 1e-8 * max(self.fuel, 1e-300)

    def input(self) -> PiecewiseConstant:
        """The input as a :class:`PiecewiseConstant`."""
        return PiecewiseConstant.from_switches(self.switch_times, self.levels, self.duration)

    def to_dict(self) -> dict:
        """JSON-friendly summary (same keys as :class:`BangBangProfile`, plus fuel)."""
        gap = self.fuel - self.fuel_lower_bound
        msg = "ok" if self.certified else f"duality gap {gap:.2e} N s, {self.unproved_cells} unproved cell(s)"
        return {
            "method": self.method,
            "duration": float(self.duration),
            "switch_times": [float(t) for t in self.switch_times],
            "levels": [float(v) for v in self.levels],
            "final_state": [float(v) for v in self.final_state],
            "final_state_error": float(self.final_state_error),
            "final_state_error_relative": float(self.final_state_error_relative),
            "certified": self.certified,
            "certificate": {"passed": self.certified, "message": msg, "fuel_lower_bound": float(self.fuel_lower_bound)},
            "fuel": float(self.fuel),
            "solve_time_s": float(self.solve_time_s),
        }


#: The coarse sampled LP that seeds Newton's co-state: samples per half period of the fastest mode,
#: and at most this many.  The seed only saves Newton iterations; HiGHS's time grows faster than
#: the samples.  Fuzz case 39 (a 457 s move, a 26 rad/s mode): 16 samples per half period asked
#: for 61,000 samples (9 s of HiGHS, twice) where Newton then took 58 ms; at 8,192 samples the LP
#: takes 0.2 s and Newton 6 iterations, at 2,048 Newton missed (58 evaluations, 1.4 s).
SEED_SAMPLES_PER_HALF_PERIOD = 16
MAX_SEED_SAMPLES = 8192


def _initial_costates(problem, system, x0, T, time_optimal):
    """Starting co-states ``nu`` for Newton, best first (a generator: each is computed when asked for).

    1. the dual of a coarse sampled LP (at most :data:`MAX_SEED_SAMPLES` samples);
    2. the time-optimal co-state, scaled so that the coasts around its switches (width
       ``2 / (alpha |S'|)``) add up to ``T - T*`` (the right start for ``T`` near ``T*``, where
       the coarse LP is infeasible).
    """
    wmax = float(np.max(system.wd)) if system.wd.size else 0.0
    N = min(MAX_SEED_SAMPLES, max(256, math.ceil(T * wmax / math.pi * SEED_SAMPLES_PER_HALF_PERIOD)))
    nu = seed_costate(system, x0, problem.u_max, N, T / N)
    if nu is not None:
        yield nu
    nu = -np.asarray(time_optimal.certificate.costate_final, dtype=float)
    tau = T - np.asarray(time_optimal.switch_times)
    _, dS = system.switching(nu, tau, derivative=True)
    total = float(np.sum(2.0 / np.abs(dS))) if tau.size else time_optimal.duration
    yield nu * total / max(T - time_optimal.duration, 1e-12 * T)


def _time_optimal_as_fuel(problem: MoveProblem, to: BangBangProfile, t0: float) -> FuelProfile:
    fuel = problem.u_max * to.duration
    return FuelProfile(
        problem,
        to.switch_times.copy(),
        to.levels.copy(),
        to.duration,
        fuel,
        fuel,
        -np.asarray(to.certificate.costate_final, float),
        to.final_state,
        to.final_state_error,
        to.final_state_error_relative,
        0 if to.certified else 1,
        0,
        time.perf_counter() - t0,
        extra={"time_optimal": True},
    )


def plan_min_fuel(
    problem: MoveProblem | PreparedMove,
    move_time: float,
    time_optimal: BangBangProfile | None = None,
    nu0: np.ndarray | None = None,
    max_iter: int = 80,
) -> FuelProfile:
    """Continuous-time minimum-fuel (bang-off-bang) input arriving at rest at ``move_time``.

    Parameters
    ----------
    problem : MoveProblem or PreparedMove
        The move (a :class:`PreparedMove` reuses its responses).
    move_time : float
        Final time ``T`` (s), ``>= T*``.
    time_optimal : BangBangProfile, optional
        The time-optimal profile, if known.
    nu0 : ndarray, optional
        Starting co-state (e.g. from a neighbouring move time).

    Raises
    ------
    GoalError
        ``move_time`` below ``T*``.
    SolverError
        No bang-off-bang input passed the exact final-state check (e.g. a
        singular arc, ``|S| = 1`` on an interval: use the sampled planner).
    """
    t0 = time.perf_counter()
    move = prepare(problem)
    problem = move.problem
    if time_optimal is None:
        time_optimal = plan_time_optimal(move)
    T = check_move_time(move_time, time_optimal.duration)
    x0 = move.x0.copy()
    if not np.any(x0) or T <= time_optimal.duration * (1.0 + T_STAR_RTOL):
        return _time_optimal_as_fuel(problem, time_optimal, t0)
    system = move.response
    budget = [dual_evaluation_budget(system, T)]  # shared by every start (each also at most MAX_DUAL_EVALUATIONS)
    if nu0 is not None:
        try:
            return _newton(problem, system, x0, T, np.asarray(nu0, float), max_iter, t0, budget)
        except SolverError:
            pass  # a start from another move time can land on the wrong structure: start afresh
    error: BangOffBangMissed | None = None
    for nu in _initial_costates(problem, system, x0, T, time_optimal):
        if budget[0] <= 0:
            break
        try:
            return _newton(problem, system, x0, T, nu, max_iter, t0, budget)
        except BangOffBangMissed as exc:
            if exc.singular:  # the dual's maximum leaves a miss: no start does better
                raise
            # a start that lands on another structure: the next start.  The refusal carries the
            # start with the highest dual value (the closest to the optimum: the LP's window guess)
            if error is None or exc.value > error.value:
                error = exc
    if error is None:
        raise BangOffBangMissed("min_fuel: no Newton start within the dual-evaluation budget", np.zeros(x0.size), False)
    raise error


class BangOffBangMissed(SolverError):
    """Newton found no bang-off-bang input that arrives: the final state is still missed.

    ``singular``: Newton reached the dual's maximum with the miss left (``|S| = 1`` on an
    interval, a singular arc: no start does better); otherwise its budget ran out.
    ``costate``: the best dual iterate, a good guess of the sampled LP's saturated samples
    (the windowed LP is accepted only when its duality gap over every sample closes).
    """

    def __init__(self, message: str, costate: np.ndarray, singular: bool, value: float = -math.inf) -> None:
        why = "a singular arc, |B^T lambda| = 1 on an interval" if singular else "Newton's budget ran out"
        super().__init__(f"{message} ({why})")
        self.costate = np.asarray(costate, float)
        self.singular = singular
        self.value = float(value)  # the dual value d(costate) (N s): higher is nearer the optimum


#: Most halvings of a Newton step.
MAX_LINE_SEARCH = 30


def _newton(problem, system, x0, T, nu, max_iter, t0, budget: list[int] | None = None) -> FuelProfile:
    """Damped Newton ascent on the concave dual ``d(nu)``; the result is checked by :func:`_assemble`."""
    um = problem.u_max
    w = -system.expm_x(T, x0)
    s = state_scale(system, x0, um, T)  # the move's error scale (see .lp: coarse units missed fast modes)
    budget = budget if budget is not None else [2 * MAX_DUAL_EVALUATIONS]
    limit = min(MAX_DUAL_EVALUATIONS, budget[0])  # this start's evaluations
    ev = dual_eval(system, nu, w, T, um)
    best = (float(np.max(np.abs(ev.grad / s))), nu, ev)
    stalled = 0
    flat = 0  # iterations in a row that raised the dual value by rounding only
    evaluations = 1
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 (the count is returned after the loop)
        g = ev.grad / s
        gmax = float(np.max(np.abs(g)))
        if gmax < best[0]:
            stalled = 0 if gmax < 0.5 * best[0] else stalled + 1
            best = (gmax, nu, ev)
        else:
            stalled += 1
        # converged (relative miss at rounding level), or rounding noise stops progress
        if gmax <= 1e-14 or (stalled >= 3 and best[0] <= 1e-10):
            break
        # the dual's maximum reached while the miss stays: no bang-off-bang optimum (a singular
        # arc, |S| = 1 on an interval; fuzz case 191 spent 1,900 evaluations, 57 s, here).
        # The sampled LP is exact there; so is the work bound
        if (flat >= 4 and stalled >= 4) or evaluations >= limit:
            break
        Gc = system.expm_B(ev.crossings) / s
        _, dS = system.switching(nu, ev.crossings, derivative=True)
        M = um * (Gc.T / np.maximum(np.abs(dS), 1e-300)) @ Gc
        mu = 1e-12 * (np.trace(M) + 1e-300)
        step = None
        for _ in range(8):  # Levenberg damping if M is (nearly) singular
            try:
                step = np.linalg.solve(M + mu * np.eye(M.shape[0]), g)
                if np.all(np.isfinite(step)):
                    break
            except np.linalg.LinAlgError:
                pass
            mu = max(mu * 100.0, 1e-12)
        if step is None:
            break
        slope = float(g @ step)
        t = 1.0
        improved = False
        for _ in range(MAX_LINE_SEARCH):
            if evaluations >= limit:
                break
            cand = nu + t * step / s
            ev_c = dual_eval(system, cand, w, T, um)
            evaluations += 1
            if ev_c.value >= ev.value + 1e-4 * t * slope or np.max(np.abs(ev_c.grad / s)) < 0.5 * np.max(np.abs(g)):
                improved = True
                break
            t *= 0.5
        if not improved:
            break
        flat = flat + 1 if ev_c.value - ev.value <= 1e-13 * max(abs(ev.value), 1e-300) else 0
        nu, ev = cand, ev_c
    budget[0] -= evaluations
    if float(np.max(np.abs(ev.grad / s))) > best[0]:
        _, nu, ev = best
    try:
        return _assemble(problem, system, nu, ev, T, it, t0)
    except SolverError as exc:
        raise BangOffBangMissed(str(exc), nu, singular=flat >= 4 and stalled >= 4, value=ev.value) from None


def _assemble(problem, system, nu, ev: DualEval, T, iterations, t0) -> FuelProfile:
    um = problem.u_max
    # forward time: reverse the tau-intervals; merge neighbours with equal level
    lv = ev.levels[::-1]
    br = T - ev.breaks[::-1]
    keep = np.concatenate([[True], lv[1:] != lv[:-1]])
    levels = um * lv[keep]
    switch_times = br[1:-1][keep[1:]]
    u = PiecewiseConstant.from_switches(switch_times, levels, T)
    x0s = problem.shifted_initial()
    states = simulate((system.A(), system.B()), x0s, u)
    xT = states[-1]
    scale = np.abs(x0s) + np.max(np.abs(states), axis=0)
    scale = np.where(scale > 0.0, scale, 1.0)
    rel = float(np.max(np.abs(xT) / scale))
    if not rel <= FINAL_STATE_RTOL:
        raise SolverError(
            f"min_fuel: continuous bang-off-bang input misses the target (relative final-state error {rel:.3e}); "
            "nothing is returned"
        )
    final_abs = simulate(problem.model, problem.x0, u, times=[T])[0]
    fuel = um * float(np.sum(np.diff(np.concatenate([[0.0], switch_times, [T]]))[levels != 0.0]))
    return FuelProfile(
        problem=problem,
        switch_times=switch_times,
        levels=levels,
        duration=float(T),
        fuel=fuel,
        fuel_lower_bound=ev.value,
        costate=nu,
        final_state=final_abs,
        final_state_error=float(np.max(np.abs(xT))),
        final_state_error_relative=rel,
        unproved_cells=ev.unproved,
        iterations=iterations,
        solve_time_s=time.perf_counter() - t0,
    )
