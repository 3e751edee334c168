"""Minimum-fuel moves for a given move time, and the fuel/time trade-off (seed eq. 2.38).

Fuel is ``J = int_0^T |u(t)| dt`` (N s).  For a final time ``T >= T*`` (the
time-optimal time) Pontryagin's principle gives the *bang-off-bang* input
``u = -u_max dez(B^T lambda)``: full force where ``|B^T lambda| > 1``, zero
where it is below 1.

Continuous time (time-to-go ``tau = T - t``, ``S(tau) = nu^T e^{A tau} B``)
-------------------------------------------------------------------------
The problem ``min int |u|  s.t.  int_0^T e^{A tau} B u dtau = w := -e^{AT} x0,
|u| <= u_max`` has the concave dual::

    d(nu) = nu^T w - u_max int_0^T (|S(tau)| - 1)_+ dtau

whose maximiser gives the input ``u = u_max sgn(S) [|S| > 1]``.  ``grad d``
is the final-state miss and ``-hess d = u_max sum_j g_j g_j^T / |S'(tau_j)|``
over the crossings of ``|S| = 1`` (``g = e^{A tau} B``), so a damped Newton
method converges from any start; it starts from the dual of the sampled
linear program below.  Every crossing is isolated *with proof*
(:func:`~flexmotion_ros.core.switching.isolate_roots` applied to ``S -+ 1``),
so the levels are the exact pointwise minimiser of the Lagrangian for the
final ``nu``; with the exact arrival checked by matrix-exponential
simulation, weak duality (``J(u) >= d(nu)`` for *every* admissible ``u``)
certifies optimality: the gap ``J - d(nu)`` is reported.

Sampled (zero-order hold at ``dt``)
-----------------------------------
``min dt sum_k |u_k|  s.t.  sum_m g_m u_m = w_K, |u_m| <= u_max`` with
``g_m = e^{A m dt} Gamma(dt)`` is a linear program: its optimum is exact for
the sampled problem.  Only samples near the crossings of ``|nu^T g_m| = dt``
are free variables (the others are fixed at ``0`` or ``+-u_max`` from a
guess of ``nu``); the window solution is accepted only if the duality gap
against the *full* problem's dual ``d_K(nu) = nu^T w - u_max sum_m
(|nu^T g_m| - dt)_+`` closes, else the windows grow.

The trade-off curve
-------------------
With the target at rest, a move that arrives early can hold zero (no fuel)
until any later time, so the minimum fuel ``J(T)`` is non-increasing in
``T``.  Its end points: ``J(T*) = u_max T*`` (at ``T*`` the bang-bang input
is the only admissible one) and ``J(T_max)`` = the minimum fuel with the
arrival time *free* in ``[T*, T_max]`` (monotonicity puts that optimum at
``T_max``).  As ``T_max -> inf`` it tends to the fuel of the unconstrained
time problem (for a rigid body with ``c = 0``: zero for rest-to-rest, the
momentum ``|v0 / b0|`` to stop a moving one).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linprog

from .boundary import MoveProblem
from .errors import GoalError, SolverError
from .modal_response import ModalResponse
from .model import check_positive
from .profile import BangBangProfile, SampledProfile
from .simulation import PiecewiseConstant, simulate, simulate_samples
from .switching import isolate_roots
from .time_optimal import FINAL_STATE_RTOL, plan_time_optimal

#: Accept a window LP when its duality gap on the full problem is below this (relative to the fuel).
LP_GAP_RTOL = 1e-9
#: HiGHS tolerances: the LP solutions are corrected to an exact arrival afterwards.
HIGHS_OPTIONS = {"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10}
#: Move times within this (relative) of ``T*`` are the time-optimal move.
T_STAR_RTOL = 1e-9
MAX_SAMPLES = 5_000_000


# --------------------------------------------------------------------- helpers
def state_scale(system: ModalResponse, x0: np.ndarray, u_max: float, T: float) -> np.ndarray:
    """How large each (shifted) state gets during a move of length ``T`` (for scaling)."""
    s = np.abs(x0) + u_max * np.max(np.abs(system.input_integral(np.linspace(0.0, T, 33))), axis=0)
    return np.where(s > 0.0, s, 1.0)


def sample_vectors(system: ModalResponse, K: int, dt: float) -> np.ndarray:
    """``g_m = e^{A m dt} Gamma(dt)`` for ``m = 0..K-1`` samples to go, shape ``(K, n)``."""
    gam = system.input_integral(np.array([dt]))[0]
    return system.expm_x_many(dt * np.arange(K), gam)


def correct_arrival(G: np.ndarray, w: np.ndarray, u: np.ndarray, movable: np.ndarray) -> np.ndarray:
    """Least-norm change of ``u[movable]`` that makes ``G^T u = w`` exact (to rounding).

    The LP solution misses ``w`` by its feasibility tolerance; the change is
    of that size, so it does not disturb the constraints' margins.
    """
    u = u.copy()
    idx = np.flatnonzero(movable)
    if idx.size < G.shape[1]:
        return u
    for _ in range(3):
        r = w - G.T @ u
        du, *_ = np.linalg.lstsq(G[idx].T, r, rcond=None)
        u[idx] += du
    return u


def verified_samples(
    problem: MoveProblem,
    commands: np.ndarray,
    dt: float,
    method: str,
    minimal: bool,
    lower_bound_samples: int,
    continuous=None,
    extra: dict | None = None,
    t0: float | None = None,
) -> SampledProfile:
    """A :class:`SampledProfile` after the exact (matrix-exponential) final-state and bound checks.

    Raises
    ------
    SolverError
        If the sequence misses the target (relative error above
        ``FINAL_STATE_RTOL``) or exceeds ``u_max``: nothing is returned.
    """
    commands = np.asarray(commands, dtype=float)
    states = simulate_samples(problem.model, problem.x0, commands, dt)
    target = problem.model.rest_state(problem.target if problem.target is not None else 0.0)
    dev = states[-1] - target
    centred = states - target
    if problem.target is None:
        dev, centred = dev[1:], centred[:, 1:]
    scale = np.max(np.abs(centred), axis=0)
    scale = np.where(scale > 0.0, scale, 1.0)
    err = float(np.max(np.abs(dev))) if dev.size else 0.0
    rel = float(np.max(np.abs(dev) / scale)) if dev.size else 0.0
    peak = float(np.max(np.abs(commands))) if commands.size else 0.0
    if not rel <= FINAL_STATE_RTOL:
        raise SolverError(f"{method}: sampled sequence misses the target (relative final-state error {rel:.3e}); nothing is returned")
    if peak > problem.u_max:
        raise SolverError(f"{method}: sampled command {peak} exceeds u_max = {problem.u_max}; nothing is returned")
    return SampledProfile(
        problem=problem,
        commands=commands,
        dt=dt,
        states=states,
        final_state_error=err,
        final_state_error_relative=rel,
        minimal=minimal,
        lower_bound_samples=int(lower_bound_samples),
        continuous=continuous,
        solve_time_s=(time.perf_counter() - t0) if t0 is not None else 0.0,
        method=method,
        extra=dict(extra or {}),
    )


def fuel_of_samples(commands: np.ndarray, dt: float) -> float:
    """``dt sum |u_k|`` (N s)."""
    return float(dt * np.sum(np.abs(commands)))


def _check_move_time(move_time: float, T_star: float) -> float:
    T = float(move_time)
    if not math.isfinite(T) or T < T_star * (1.0 - T_STAR_RTOL):
        raise GoalError("move_time", f"must be a finite time >= the time-optimal {T_star:.9g} s, got {move_time}")
    return max(T, T_star)


# ---------------------------------------------------------- sampled (the LP)
@dataclass
class _LPResult:
    u: np.ndarray  # samples to go
    fuel: float
    bound: float  # full-problem dual bound d_K(nu)
    nu: np.ndarray
    free: int


def _dual_bound(G: np.ndarray, w: np.ndarray, nu: np.ndarray, dt: float, um: float) -> float:
    """``d_K(nu) = nu^T w - u_max sum_m (|nu^T g_m| - dt)_+``: a lower bound on the fuel (any nu)."""
    return float(nu @ w - um * np.sum(np.maximum(np.abs(G @ nu) - dt, 0.0)))


def _levels_from(G: np.ndarray, nu: np.ndarray, dt: float) -> np.ndarray:
    s = (G @ nu) / dt
    return np.where(s > 1.0, 1.0, np.where(s < -1.0, -1.0, 0.0))


def _window(levels: np.ndarray, width: int) -> np.ndarray:
    K = levels.size
    free = np.zeros(K, dtype=bool)
    for c in np.flatnonzero(levels[1:] != levels[:-1]):
        free[max(0, c - width + 1) : min(K, c + width + 1)] = True
    free[:width] = True
    free[K - width :] = True
    return free


def _solve_fuel_lp(G, w, dt, um, scale, levels, free) -> _LPResult | None:
    """``min fuel`` with samples outside ``free`` fixed at ``levels * u_max``; None if infeasible."""
    F = np.flatnonzero(free)
    nF = F.size
    fixed = ~free
    Gs = G / scale
    rhs = w / scale - um * (Gs[fixed].T @ levels[fixed])
    # u_f = u_max (p - q), 0 <= p, q <= 1
    A_eq = um * np.hstack([Gs[F].T, -Gs[F].T])
    res = linprog(np.ones(2 * nF), A_eq=A_eq, b_eq=rhs, bounds=(0.0, 1.0), method="highs", options=HIGHS_OPTIONS)
    if res.status != 0:
        return None
    u = um * levels.astype(float)
    u[F] = um * (res.x[:nF] - res.x[nF:])
    nu = dt * um * np.asarray(res.eqlin.marginals, dtype=float) / scale  # d fuel / d w
    return _LPResult(u, fuel_of_samples(u, dt), _dual_bound(G, w, nu, dt, um), nu, nF)


def min_fuel_lp(system: ModalResponse, x0: np.ndarray, um: float, K: int, dt: float, nu_guess: np.ndarray | None = None) -> _LPResult | None:
    """Exact minimum-fuel ZOH sequence with ``K`` samples (samples-to-go order), None if infeasible.

    With ``nu_guess`` only windows around its level changes are free; the
    window solution is accepted when its full-problem duality gap closes.
    """
    G = sample_vectors(system, K, dt)
    w = -system.expm_x(K * dt, x0)
    scale = state_scale(system, x0, um, K * dt)
    result = None
    if nu_guess is not None:
        levels = _levels_from(G, nu_guess, dt)
        width = 4
        while 2 * width < K:
            free = _window(levels, width)
            sol = _solve_fuel_lp(G, w, dt, um, scale, levels, free)
            if sol is not None and sol.fuel - sol.bound <= LP_GAP_RTOL * max(sol.fuel, um * dt):
                result = sol
                break
            if sol is not None:  # the window's dual is a better guess of nu
                levels = _levels_from(G, sol.nu, dt)
            width *= 4
    if result is None:
        result = _solve_fuel_lp(G, w, dt, um, scale, np.zeros(K), np.ones(K, dtype=bool))
        if result is None:
            return None
    # exact arrival: move samples strictly inside the bound (fractional ones first: fuel unchanged to rounding)
    u = result.u
    inner = np.abs(u) < um * (1.0 - 1e-9)
    frac = inner & (np.abs(u) > um * 1e-9)
    u = correct_arrival(G / scale, w / scale, u, frac if frac.sum() >= G.shape[1] else inner)
    u = np.clip(u, -um, um)
    result.u = u
    result.fuel = fuel_of_samples(u, dt)
    return result


def plan_min_fuel_zoh(
    problem: MoveProblem,
    rate_hz: float,
    move_time: float,
    time_optimal: BangBangProfile | None = None,
    nu_guess: np.ndarray | None = None,
    continuous=None,
) -> SampledProfile:
    """Minimum-fuel zero-order-hold sequence at ``rate_hz`` arriving at rest after ``ceil(move_time * rate_hz)`` samples.

    If fewer samples than the sampled time-optimum would be needed (a
    ``move_time`` within one sample of ``T*``), the fewest feasible count is used.

    Returns
    -------
    SampledProfile
        ``method = "min_fuel"``; ``extra`` holds ``fuel`` (N s), ``fuel_lower_bound``
        (weak-duality bound: the gap proves optimality) and ``lp_free_samples``.
    """
    t0 = time.perf_counter()
    rate = check_positive("rate_hz", rate_hz, "Hz")
    dt = 1.0 / rate
    if time_optimal is None:
        time_optimal = plan_time_optimal(problem)
    T = _check_move_time(move_time, time_optimal.duration)
    system = ModalResponse(problem.model, problem.include_position)
    x0 = problem.shifted_initial()
    um = problem.u_max
    if not np.any(x0):
        return verified_samples(problem, np.empty(0), dt, "min_fuel", True, 0, continuous, {"fuel": 0.0, "fuel_lower_bound": 0.0}, t0)
    K = max(1, math.ceil(T / dt * (1.0 - 1e-12)))
    if K > MAX_SAMPLES:
        raise GoalError("rate_hz", f"a {T:.3g} s move at {rate:g} Hz needs over {MAX_SAMPLES:g} samples; lower the rate")
    K_lo = max(1, math.ceil(time_optimal.duration / dt * (1.0 - 1e-12)))
    sol = None
    K_stop = max(K, K_lo) + 400
    while sol is None and K <= K_stop:
        sol = min_fuel_lp(system, x0, um, K, dt, nu_guess)
        if sol is None:
            K += 1  # within a sample or so of T*: the ZOH needs a few more samples
    if sol is None:
        raise SolverError("min_fuel: no feasible sampled sequence near the requested move time")
    cmds = sol.u[::-1].copy()
    extra = {"fuel": sol.fuel, "fuel_lower_bound": sol.bound, "lp_free_samples": sol.free, "costate": sol.nu.tolist()}
    return verified_samples(problem, cmds, dt, "min_fuel", False, K_lo, continuous, extra, t0)


# ------------------------------------------------------- continuous (Newton)
class _Offset:
    """``S(tau) - offset`` for :func:`isolate_roots` (crossings of ``S = offset``)."""

    def __init__(self, system: ModalResponse, offset: float) -> None:
        self.sys = system
        self.offset = offset
        self.wd = system.wd

    def switching(self, nu, tau, derivative=False, order=None):
        out = self.sys.switching(nu, tau, derivative=derivative, order=order)
        if isinstance(out, tuple):
            return (out[0] - self.offset,) + tuple(out[1:])
        return out - self.offset

    def switching_derivative_bound(self, nu, order):
        return self.sys.switching_derivative_bound(nu, order)

    def switching_magnitude(self, nu, tau_max):
        m0, m1 = self.sys.switching_magnitude(nu, tau_max)
        return m0 + abs(self.offset), m1


@dataclass
class _DualEval:
    breaks: np.ndarray  # time-to-go breakpoints 0 .. T
    levels: np.ndarray  # -1/0/+1 on each tau-interval
    crossings: np.ndarray
    value: float
    grad: np.ndarray  # w - reached (unscaled)
    fuel: float
    unproved: int


def _dual_eval(system: ModalResponse, nu: np.ndarray, w: np.ndarray, T: float, um: float) -> _DualEval:
    up = isolate_roots(_Offset(system, 1.0), nu, T)
    dn = isolate_roots(_Offset(system, -1.0), nu, T)
    cross = np.unique(np.concatenate([up.roots, dn.roots]))
    cross = cross[(cross > 0.0) & (cross < T)]
    breaks = np.concatenate([[0.0], cross, [T]])
    mids = 0.5 * (breaks[:-1] + breaks[1:])
    S = system.switching(nu, mids)
    levels = np.where(S > 1.0, 1.0, np.where(S < -1.0, -1.0, 0.0))
    Gam = system.input_integral(breaks)
    dG = Gam[1:] - Gam[:-1]
    reached = um * (levels @ dG)
    on = levels != 0.0
    fuel = um * float(np.sum(np.diff(breaks)[on]))
    # d = nu^T w - u_max sum_on (sgn nu^T dGamma - length) = nu^T (w - reached) + fuel
    value = float(nu @ (w - reached)) + fuel
    return _DualEval(breaks, levels, cross, value, w - reached, fuel, up.unproved + dn.unproved)


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


def _initial_costate(problem, system, x0, T, time_optimal) -> np.ndarray:
    """``nu`` from a coarse sampled LP; near ``T*``, a scaled time-optimal co-state."""
    wmax = float(np.max(system.wd)) if system.wd.size else 0.0
    N = max(256, math.ceil(T * wmax / math.pi * 16))
    for _ in range(3):
        sol = min_fuel_lp(system, x0, problem.u_max, N, T / N)
        if sol is not None:
            return sol.nu
        N *= 4
    # T within a fine sample of T*: coasts of width 2 / (alpha |S'|) around the time-optimal switches
    nu = -np.asarray(time_optimal.certificate.costate_final, dtype=float)
    tau = T - np.asarray(time_optimal.switch_times)
    _, dS = system.switching(nu, tau, derivative=True)
    total = float(np.sum(2.0 / np.abs(dS))) if tau.size else time_optimal.duration
    return nu * total / max(T - time_optimal.duration, 1e-12 * T)


def _time_optimal_as_fuel(problem: MoveProblem, to: BangBangProfile, t0: float) -> FuelProfile:
    fuel = problem.u_max * to.duration
    return FuelProfile(
        problem, to.switch_times.copy(), to.levels.copy(), to.duration, fuel, fuel,
        -np.asarray(to.certificate.costate_final, float), to.final_state, to.final_state_error,
        to.final_state_error_relative, 0 if to.certified else 1, 0, time.perf_counter() - t0,
        extra={"time_optimal": True},
    )


def plan_min_fuel(
    problem: MoveProblem,
    move_time: float,
    time_optimal: BangBangProfile | None = None,
    nu0: np.ndarray | None = None,
    max_iter: int = 80,
) -> FuelProfile:
    """Continuous-time minimum-fuel (bang-off-bang) input arriving at rest at ``move_time``.

    Parameters
    ----------
    problem : MoveProblem
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
    if time_optimal is None:
        time_optimal = plan_time_optimal(problem)
    T = _check_move_time(move_time, time_optimal.duration)
    x0 = problem.shifted_initial()
    if not np.any(x0) or T <= time_optimal.duration * (1.0 + T_STAR_RTOL):
        return _time_optimal_as_fuel(problem, time_optimal, t0)
    system = ModalResponse(problem.model, problem.include_position)
    if nu0 is not None:
        try:
            return _newton(problem, system, x0, T, np.asarray(nu0, float), max_iter, t0)
        except SolverError:
            pass  # a start from another move time can land on the wrong structure: start afresh
    return _newton(problem, system, x0, T, _initial_costate(problem, system, x0, T, time_optimal), max_iter, t0)


def _newton(problem, system, x0, T, nu, max_iter, t0) -> FuelProfile:
    """Damped Newton ascent on the concave dual ``d(nu)``; the result is checked by :func:`_assemble`."""
    um = problem.u_max
    w = -system.expm_x(T, x0)
    s = state_scale(system, x0, um, T)
    ev = _dual_eval(system, nu, w, T, um)
    best = (float(np.max(np.abs(ev.grad / s))), nu, ev)
    stalled = 0
    it = 0
    for it in range(1, max_iter + 1):
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
        for _ in range(40):
            cand = nu + t * step / s
            ev_c = _dual_eval(system, cand, w, T, um)
            if ev_c.value >= ev.value + 1e-4 * t * slope or np.max(np.abs(ev_c.grad / s)) < 0.5 * np.max(np.abs(g)):
                improved = True
                break
            t *= 0.5
        if not improved:
            break
        nu, ev = cand, ev_c
    if float(np.max(np.abs(ev.grad / s))) > best[0]:
        _, nu, ev = best
    return _assemble(problem, system, nu, ev, T, it, t0)


def _assemble(problem, system, nu, ev: _DualEval, T, iterations, t0) -> FuelProfile:
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


# ------------------------------------------------------------ trade-off curve
@dataclass
class FuelCurve:
    """Minimum fuel versus move time.

    Attributes
    ----------
    move_times : ndarray
        ``T`` (s), from ``T*`` to ``T_max``.
    fuel : ndarray
        Continuous-time minimum fuel ``J(T)`` (N s); ``fuel[0] = u_max T*``.
    sampled_move_times, sampled_fuel : ndarray or None
        The same for the ZOH problem at ``rate_hz`` (``K dt``, exact LP optimum).
    time_optimal_time : float
        ``T*`` (s).
    """

    move_times: np.ndarray
    fuel: np.ndarray
    time_optimal_time: float
    sampled_move_times: np.ndarray | None = None
    sampled_fuel: np.ndarray | None = None
    profiles: list = field(default_factory=list, repr=False)

    def to_dict(self) -> dict:
        out = {
            "time_optimal_time": float(self.time_optimal_time),
            "move_times": [float(t) for t in self.move_times],
            "fuel": [float(f) for f in self.fuel],
        }
        if self.sampled_fuel is not None:
            out["sampled_move_times"] = [float(t) for t in self.sampled_move_times]
            out["sampled_fuel"] = [float(f) for f in self.sampled_fuel]
        return out


def fuel_time_curve(
    problem: MoveProblem,
    longest_time: float,
    points: int = 9,
    rate_hz: float | None = None,
    time_optimal: BangBangProfile | None = None,
) -> FuelCurve:
    """The fuel/time trade-off between ``T*`` and ``longest_time`` (equally spaced move times).

    With ``rate_hz`` also the exact sampled curve at the same times (rounded up
    to whole samples).

    Raises
    ------
    SolverError
        A point without a continuous bang-off-bang solution (singular arc):
        use the sampled curve (:func:`sampled_fuel_curve`).
    """
    if time_optimal is None:
        time_optimal = plan_time_optimal(problem)
    T_star = time_optimal.duration
    T_max = _check_move_time(longest_time, T_star)
    if not isinstance(points, (int, np.integer)) or points < 2:
        raise GoalError("points", f"must be an integer >= 2, got {points}")
    times = T_star + (T_max - T_star) * np.linspace(0.0, 1.0, points)
    fuel, profiles = [], []
    for T in times:
        # each point starts from its own coarse LP: more robust than continuation in T (the
        # pulse structure changes along the curve), and about as fast
        p = plan_min_fuel(problem, T, time_optimal)
        fuel.append(p.fuel)
        profiles.append(p)
    curve = FuelCurve(times, np.array(fuel), T_star, profiles=profiles)
    if rate_hz is not None:
        dt = 1.0 / check_positive("rate_hz", rate_hz, "Hz")
        s_times, s_fuel = [], []
        for T, p in zip(times, profiles):
            sp = plan_min_fuel_zoh(problem, rate_hz, T, time_optimal, nu_guess=None if p.extra.get("time_optimal") else p.costate)
            s_times.append(sp.duration)
            s_fuel.append(sp.extra["fuel"])
        curve.sampled_move_times = np.array(s_times)
        curve.sampled_fuel = np.array(s_fuel)
        del dt
    return curve


def sampled_fuel_curve(
    problem: MoveProblem,
    rate_hz: float,
    longest_time: float,
    points: int = 9,
    time_optimal: BangBangProfile | None = None,
) -> FuelCurve:
    """The exact sampled trade-off: minimum ZOH fuel for sample counts from the fewest to ``longest_time``.

    The first point is the fewest samples that arrive at all (the sampled
    time optimum, :func:`~flexmotion_ros.core.zoh.plan_zoh`); ``move_times``
    are ``K dt``.  ``fuel`` holds the sampled fuel (there is no continuous curve).
    """
    from .zoh import plan_zoh

    rate = check_positive("rate_hz", rate_hz, "Hz")
    dt = 1.0 / rate
    if time_optimal is None:
        time_optimal = plan_time_optimal(problem)
    T_max = _check_move_time(longest_time, time_optimal.duration)
    if not isinstance(points, (int, np.integer)) or points < 2:
        raise GoalError("points", f"must be an integer >= 2, got {points}")
    K_lo = plan_zoh(problem, rate, time_optimal).samples
    K_hi = max(K_lo, math.floor(T_max / dt * (1.0 + 1e-12)))
    Ks = np.unique(np.round(np.linspace(K_lo, K_hi, points)).astype(int))
    system = ModalResponse(problem.model, problem.include_position)
    x0 = problem.shifted_initial()
    fuel = []
    nu = None
    for K in Ks:
        sol = min_fuel_lp(system, x0, problem.u_max, int(K), dt, nu)
        if sol is None:
            raise SolverError(f"min_fuel: {K} samples infeasible although the sampled time optimum needs {K_lo}")
        fuel.append(sol.fuel)
        nu = sol.nu  # windows from the neighbour: accepted only if the full duality gap closes
    times = Ks * dt
    return FuelCurve(times, np.array(fuel), time_optimal.duration, times, np.array(fuel))
