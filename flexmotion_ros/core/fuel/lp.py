"""The sampled minimum-fuel linear program (zero-order hold at ``dt``), and the sampled-move helpers.

Fuel is ``J = dt sum_k |u_k|`` (N s).  With ``g_m = e^{A m dt} Gamma(dt)``
(``m`` samples to go)

``min dt sum_k |u_k|  s.t.  sum_m g_m u_m = w_K := -e^{A K dt} x0, |u_m| <= u_max``

is a linear program: its optimum is exact for the sampled problem.  Only
samples near the crossings of ``|nu^T g_m| = dt`` are free variables (the
others are fixed at ``0`` or ``+-u_max`` from a guess of ``nu``); the window
solution is accepted only if the duality gap against the *full* problem's
dual ``d_K(nu) = nu^T w - u_max sum_m (|nu^T g_m| - dt)_+`` closes, else the
windows grow.  The continuous-time problem is in :mod:`.min_fuel`.

The helpers (state scale, exact arrival correction, the verified
:class:`SampledProfile`) serve the limited planner too (:mod:`.limit_lp`,
:mod:`.limits`); the sample vectors are :func:`.zoh.sample_vectors`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import GoalError, SolverError
from ..linear_program import LpMethod, LpStatus, solve_lp
from ..model.boundary import MoveProblem
from ..model.modal_model import check_positive
from ..results import BangBangProfile, SampledProfile
from ..sampled.check import verified_samples
from ..sampled.lp_tools import correct_arrival, sample_vectors
from ..simulation.error_scale import state_scale
from ..simulation.modal_response import ModalResponse
from ..simulation.prepared import PreparedMove, prepare
from ..time_optimal.solver import plan_time_optimal
from ..tolerances import HIGHS_OPTIONS, LP_GAP_RTOL, MAX_SAMPLES, T_STAR_RTOL

#: Sample counts tried above an infeasible requested one when the fewest feasible is not known.
MAX_EXTRA_COUNTS = 16
#: Most free samples in one fuel LP (a work bound).  Fuzz case 73 (7 modes, a 853 s move at
#: 100 Hz): one HiGHS dual-simplex call over all 85,308 samples ran for more than 4.6 min CPU.
#: Past it the windows stop growing: the best feasible window is returned with the proved lower
#: bound it has (``fuel_lower_bound``; ``fuel_gap_closed`` False), never a sequence that misses.
MAX_FREE_SAMPLES = 20_000
#: Past :data:`MAX_FREE_SAMPLES`: the most blocks of the blocked LP (each block of consecutive samples
#: holds one command: an exact restriction of the sampled problem, so its optimum is a feasible
#: sequence at the full rate; its dual guesses the windows).
BLOCKED_SAMPLES = 4096
#: Work bound of one fuel LP, in dual-simplex iterations times the LP's columns: HiGHS's
#: iteration limit is this over the columns (a bound HiGHS honours inside a solve; it does not
#: look at its time limit there).  Fuzz cases 0-272 at 100 Hz: every windowed or full LP took
#: at most 1,435 iterations (3.5e6 column-iterations); case 73's blocked LP 10,091 over 8,126
#: columns (8.2e7, 6.6 s).  A window LP of case 73 ran for minutes inside HiGHS when Newton
#: started from another co-state.  About 0.3-0.5 ms an iteration over 16,000 columns here.
LP_WORK_BUDGET = 2e8
#: The fewest iterations a fuel LP is allowed, however many its columns.
MIN_LP_ITERATIONS = 2000
#: Most interior-point iterations of an LP solved by HiGHS's interior method here (a work bound
#: HiGHS honours inside a solve).  The fuzz's seed and blocked LPs converge in 30-40.
MAX_IPM_ITERATIONS = 200


def fuel_of_samples(commands: np.ndarray, dt: float) -> float:
    """``dt sum |u_k|`` (N s)."""
    return float(dt * np.sum(np.abs(commands)))


def check_move_time(move_time: float, T_star: float) -> float:
    """``move_time`` (s) checked against ``T*``; a value within ``T_STAR_RTOL`` below it is ``T*``."""
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
    gap_closed: bool = True  # fuel - bound within LP_GAP_RTOL (optimal); False: the work bound's best window


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


def _unit_rows(Gs: np.ndarray) -> np.ndarray:
    """Each state row's largest entry over the LP's columns (1 where none): the rows' units."""
    rows = np.max(np.abs(Gs), axis=0) if Gs.size else np.ones(Gs.shape[1])
    return np.where(rows > 0.0, rows, 1.0)


def _iteration_limit(columns: int) -> int:
    """HiGHS's iteration limit for a fuel LP of ``columns`` columns (:data:`LP_WORK_BUDGET`)."""
    return max(MIN_LP_ITERATIONS, int(LP_WORK_BUDGET / max(columns, 1)))


def _solve_fuel_lp(G, w, dt, um, scale, levels, free, unit_rows: bool = False) -> _LPResult | LpStatus:
    """``min fuel`` with samples outside ``free`` fixed at ``levels * u_max``.

    Returns the solution, or the status HiGHS ended with: ``INFEASIBLE`` (proved), or no
    verdict (``TIME_LIMIT``: the work bound :data:`LP_WORK_BUDGET`; ``OTHER``: numerical).

    ``unit_rows``: each state row divided by its largest free entry (the work-bound path: a long
    move's position row was 1e-4 of the others, and HiGHS answered "not set").
    """
    F = np.flatnonzero(free)
    nF = F.size
    fixed = ~free
    Gs = G / scale
    rhs = w / scale - um * (Gs[fixed].T @ levels[fixed])
    rows = _unit_rows(Gs[F]) if unit_rows else np.ones(G.shape[1])
    # u_f = u_max (p - q), 0 <= p, q <= 1
    A_eq = um * np.hstack([Gs[F].T, -Gs[F].T]) / rows[:, None]
    res = solve_lp(
        cost=np.ones(2 * nF),
        A_eq=A_eq,
        b_eq=rhs / rows,
        lower=0.0,
        upper=1.0,
        iteration_limit=_iteration_limit(2 * nF),
        **HIGHS_OPTIONS,
    )
    if res.status is not LpStatus.OPTIMAL:
        return res.status
    u = um * levels.astype(float)
    u[F] = um * (res.x[:nF] - res.x[nF:])
    nu = dt * um * np.asarray(res.eq_marginals, dtype=float) / (scale * rows)  # d fuel / d w
    return _LPResult(u, fuel_of_samples(u, dt), _dual_bound(G, w, nu, dt, um), nu, nF)


def _solve_blocked_lp(G, w, dt, um, scale, blocks: int) -> _LPResult | LpStatus:
    """``min fuel`` with the samples held in ``blocks`` runs of equal commands (the last run shorter).

    Returns the solution, or the status HiGHS ended with (as :func:`_solve_fuel_lp`).
    """
    K = G.shape[0]
    m = math.ceil(K / blocks)
    starts = np.arange(0, K, m)
    sizes = np.diff(np.append(starts, K)).astype(float)
    Gs = np.add.reduceat(G / scale, starts, axis=0)  # block columns: sums of the sample vectors
    # rows to unit size: a long move's position row was 1e-4 of the others in these units (fuzz
    # case 73, 4,096 blocks: HiGHS "not set" without, optimal in 0.5 s with)
    rows = _unit_rows(Gs)
    Gs = Gs / rows
    nB = starts.size
    A_eq = um * np.hstack([Gs.T, -Gs.T])
    # costs near 1 (the block's share of a full block): costs of m, the samples per block, left
    # HiGHS without a verdict ("Not Set", fuzz case 577) where these solve in 0.04 s
    cost = np.tile(sizes / m, 2)
    lp = {"cost": cost, "A_eq": A_eq, "b_eq": w / scale / rows, "lower": 0.0, "upper": 1.0, **HIGHS_OPTIONS}
    res = solve_lp(**lp, iteration_limit=_iteration_limit(2 * nB))
    if res.status in (LpStatus.TIME_LIMIT, LpStatus.OTHER):
        # no verdict from the dual simplex within its work bound (fuzz case 273: 4,072 blocks
        # needed 63,605 iterations): the interior method, without crossover.  Its optimum is a
        # feasible sequence (made exact below) and a guess of nu, never a proof
        res = solve_lp(**lp, method=LpMethod.IPM, crossover=False, iteration_limit=MAX_IPM_ITERATIONS)
    if res.status is not LpStatus.OPTIMAL:
        return res.status
    u = np.repeat(um * (res.x[:nB] - res.x[nB:]), sizes.astype(int))
    nu = dt * um * m * np.asarray(res.eq_marginals, dtype=float) / (scale * rows)
    return _LPResult(u, fuel_of_samples(u, dt), _dual_bound(G, w, nu, dt, um), nu, nB, gap_closed=False)


def seed_costate(system: ModalResponse, x0: np.ndarray, um: float, K: int, dt: float) -> np.ndarray | None:
    """A co-state guess ``nu`` from the full sampled fuel LP (``K`` samples of ``dt`` s); None if none.

    The dual simplex first, within :data:`LP_WORK_BUDGET`; without a verdict there, HiGHS's
    interior-point method without crossover (only the duals are wanted), within
    :data:`MAX_IPM_ITERATIONS`.  Unbounded, the dual simplex ran past 8 min CPU inside one HiGHS
    call (fuzz case 273: 8,192 samples, a 1,058 s move, two modes near 20 rad/s; with the rows
    in unit size it solved in 3 s, but then ran for minutes on cases 73 and 257) and took 18.6 s
    on case 257; the interior method takes 0.04-0.3 s on each.

    Returns
    -------
    ndarray or None
        ``nu`` (unscaled state units: ``d fuel / d w``, N s per state unit); None if the LP
        is infeasible (``T`` within a sample or so of ``T*``) or neither method gave an optimum
        within its bound.  It is a guess, not a bound: nothing proved rests on it.
    """
    G = sample_vectors(system, K, dt)
    w = -system.expm_x(K * dt, x0)
    scale = state_scale(system, x0, um, K * dt)
    Gs = G / scale
    lp = {"cost": np.ones(2 * K), "A_eq": um * np.hstack([Gs.T, -Gs.T]), "b_eq": w / scale, "lower": 0.0, "upper": 1.0}
    res = solve_lp(**lp, iteration_limit=_iteration_limit(2 * K), **HIGHS_OPTIONS)
    if res.status in (LpStatus.TIME_LIMIT, LpStatus.OTHER):
        res = solve_lp(**lp, method=LpMethod.IPM, crossover=False, iteration_limit=MAX_IPM_ITERATIONS, **HIGHS_OPTIONS)
    if res.status is not LpStatus.OPTIMAL:
        return None
    return dt * um * np.asarray(res.eq_marginals, dtype=float) / scale


def min_fuel_lp(
    system: ModalResponse,
    x0: np.ndarray,
    um: float,
    K: int,
    dt: float,
    nu_guess: np.ndarray | None = None,
    max_free: int | None = None,
) -> _LPResult | None:
    """Exact minimum-fuel ZOH sequence with ``K`` samples (samples-to-go order), None if infeasible.

    With ``nu_guess`` only windows around its level changes are free; the
    window solution is accepted when its full-problem duality gap closes.
    At most ``max_free`` (default :data:`MAX_FREE_SAMPLES`) samples are free in one LP (a work bound): past it,
    a blocked LP (:data:`BLOCKED_SAMPLES` runs of equal commands, feasible at
    the full rate) and windows around its dual's level changes; the best
    feasible sequence is returned with the best proved lower bound
    (``gap_closed`` False unless that bound closes the gap).

    Raises
    ------
    SolverError
        More than ``max_free`` samples and neither the blocked LP nor a window feasible.
    """
    max_free = MAX_FREE_SAMPLES if max_free is None else int(max_free)
    G = sample_vectors(system, K, dt)
    w = -system.expm_x(K * dt, x0)
    # LP units: the move's error scale (uniform and geometric instants).  The 33 uniform
    # instants of ``lp_state_scale`` missed a fast, damped mode on a long move (fuzz case 191:
    # 1.8e-24 for a 39 rad/s mode's rate, entries of 1e22): HiGHS answered "model error" at
    # every sample count and the planner refused after 400 LPs (23 s)
    scale = state_scale(system, x0, um, K * dt)
    result = best = None
    lower = -math.inf
    guesses = [] if nu_guess is None else [nu_guess]
    if K > max_free:  # the blocked LP: a feasible sequence at this rate, its dual another guess
        blocked = _solve_blocked_lp(G, w, dt, um, scale, min(BLOCKED_SAMPLES, max_free))
        if isinstance(blocked, _LPResult):
            best, lower = blocked, blocked.bound
            guesses.append(blocked.nu)
    for guess in guesses:
        if result is not None:
            break
        lower = max(lower, _dual_bound(G, w, guess, dt, um))
        levels = _levels_from(G, guess, dt)
        width = 4
        while 2 * width < K:
            free = _window(levels, width)
            if np.count_nonzero(free) > max_free:
                break
            sol = _solve_fuel_lp(G, w, dt, um, scale, levels, free, unit_rows=K > max_free)
            if isinstance(sol, _LPResult):
                lower = max(lower, sol.bound)
                if best is None or sol.fuel < best.fuel:
                    best = sol
                if sol.fuel - lower <= LP_GAP_RTOL * max(sol.fuel, um * dt):
                    result = sol
                    break
                levels = _levels_from(G, sol.nu, dt)  # the window's dual is a better guess of nu
            width *= 4
    if result is None and best is not None and best.fuel - lower <= LP_GAP_RTOL * max(best.fuel, um * dt):
        result = best  # the blocked optimum proved optimal by the bound
    if result is None and K <= max_free:
        full = _solve_fuel_lp(G, w, dt, um, scale, np.zeros(K), np.ones(K, dtype=bool))
        if isinstance(full, _LPResult):
            result = full
        elif best is not None and full is not LpStatus.INFEASIBLE:
            # no verdict within the work bound: the best feasible window, with the bound it has
            result = best
            result.gap_closed = False
        else:
            return None
    elif result is None:
        if best is None:
            raise SolverError(
                f"min_fuel: the sampled fuel LP at {K} samples ({K * dt:.4g} s at {1.0 / dt:g} Hz) found no "
                f"feasible window of at most {max_free} free samples (its work bound); nothing is returned"
            )
        result = best
        result.gap_closed = False
    if result.bound < lower:
        result.bound = lower
    result.gap_closed = result.gap_closed or result.fuel - result.bound <= LP_GAP_RTOL * max(result.fuel, um * dt)
    # exact arrival: move samples strictly inside the bound (fractional ones first: fuel unchanged to rounding)
    u0 = result.u
    inner = np.abs(u0) < um * (1.0 - 1e-9)
    frac = inner & (np.abs(u0) > um * 1e-9)
    Gs, ws = G / scale, w / scale
    best = None
    # the fractional samples alone (about one per state) can make an ill-conditioned system whose
    # least-norm change leaves the bound and is clipped away (fuzz case 363: 4e-3 of the scale
    # missed): then every sample strictly inside the bound moves (zeros too: fuel changes by rounding)
    for movable in (frac, inner) if frac.sum() >= G.shape[1] else (inner,):
        u = np.clip(correct_arrival(Gs, ws, u0, movable), -um, um)
        miss = float(np.max(np.abs(Gs.T @ u - ws)))
        if best is None or miss < best[0]:
            best = (miss, u)
        if miss <= 1e-12:
            break
    u = best[1]
    result.u = u
    result.fuel = fuel_of_samples(u, dt)
    return result


def plan_min_fuel_zoh(
    problem: MoveProblem | PreparedMove,
    rate_hz: float,
    move_time: float,
    time_optimal: BangBangProfile | None = None,
    nu_guess: np.ndarray | None = None,
    continuous=None,
    fewest_samples: Callable[[], int] | None = None,
) -> SampledProfile:
    """Minimum-fuel zero-order-hold sequence at ``rate_hz`` arriving at rest after ``ceil(move_time * rate_hz)`` samples.

    If fewer samples than the sampled time-optimum would be needed (a
    ``move_time`` within one sample of ``T*``), the fewest feasible count is used.
    ``problem`` may be a :class:`PreparedMove` (its responses are reused);
    ``rate_hz`` (Hz, ``> 0``) is checked here: a public entry point.

    ``fewest_samples``: a callable giving the sampled time-optimum's fewest samples
    (:func:`~flexmotion_ros.core.sampled.zoh.plan_time_optimal_zoh`), asked for only if the
    requested count is infeasible; without it, :data:`MAX_EXTRA_COUNTS` counts up are tried.

    Returns
    -------
    SampledProfile
        ``method = "min_fuel"``; ``extra`` holds ``fuel`` (N s), ``fuel_lower_bound``
        (weak-duality bound: the gap proves optimality) and ``lp_free_samples``.
    """
    t0 = time.perf_counter()
    rate = check_positive("rate_hz", rate_hz, "Hz")
    dt = 1.0 / rate
    move = prepare(problem)
    problem = move.problem
    if time_optimal is None:
        time_optimal = plan_time_optimal(move)
    T = check_move_time(move_time, time_optimal.duration)
    system = move.response
    x0 = move.x0.copy()
    um = problem.u_max
    if not np.any(x0):
        return verified_samples(
            move, np.empty(0), dt, "min_fuel", True, 0, continuous, {"fuel": 0.0, "fuel_lower_bound": 0.0}, t0
        )
    K = max(1, math.ceil(T / dt * (1.0 - 1e-12)))
    if K > MAX_SAMPLES:
        raise GoalError(
            "rate_hz", f"a {T:.3g} s move at {rate:g} Hz needs over {MAX_SAMPLES:g} samples; lower the rate"
        )
    K_lo = max(1, math.ceil(time_optimal.duration / dt * (1.0 - 1e-12)))
    sol = min_fuel_lp(system, x0, um, K, dt, nu_guess)
    if sol is None:
        # within a sample or so of T*: the ZOH needs more samples.  With ``fewest_samples`` (the
        # sampled time-optimum's proved fewest count) one more LP; without, a few counts up (this
        # was one LP per count, up to 400)
        counts = range(K + 1, K + 1 + MAX_EXTRA_COUNTS)
        if fewest_samples is not None:
            fewest = int(fewest_samples())
            counts = sorted({max(K + 1, fewest), fewest + 1})
        for count in counts:
            sol = min_fuel_lp(system, x0, um, count, dt, nu_guess)
            if sol is not None:
                break
    if sol is None:
        raise SolverError("min_fuel: no feasible sampled sequence near the requested move time")
    cmds = sol.u[::-1].copy()
    extra = {
        "fuel": sol.fuel,
        "fuel_lower_bound": sol.bound,
        "fuel_gap_closed": sol.gap_closed,
        "lp_free_samples": sol.free,
        "costate": sol.nu.tolist(),
    }
    return verified_samples(move, cmds, dt, "min_fuel", False, K_lo, continuous, extra, t0)
