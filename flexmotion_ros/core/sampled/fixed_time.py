"""Zero-order-hold moves that arrive at a requested sample: the least-peak LP at exactly that many samples."""

from __future__ import annotations

import math
import time

import numpy as np

from ..errors import InputError, SolverError
from ..model.boundary import MoveProblem
from ..model.modal_model import check_positive
from ..results import BangBangProfile, SampledProfile
from ..simulation.prepared import PreparedMove, prepare
from ..time_optimal.fixed_time import check_arrival_time, plan_fixed_time
from ..time_optimal.rigid_body import rigid_time
from ..time_optimal.solver import plan_time_optimal
from ..tolerances import BOUND_RTOL, LP_RTOL
from .lp_tools import sample_vectors
from .zoh import (
    correct_exactly,
    dual_bound,
    finish_sampled,
    plan_time_optimal_zoh,
    solve_peak_lp,
    window_mask,
)


def plan_fixed_time_zoh(
    problem: MoveProblem | PreparedMove, arrival_time: float, rate_hz: float, continuous: BangBangProfile | None = None
) -> SampledProfile:
    """Least-peak zero-order-hold sequence arriving at rest at sample ``round(arrival_time * rate_hz)``.

    If that many samples cannot reach the target within ``u_max`` (the
    request rounds below the sampled optimum), the fewest feasible samples
    are used instead (``extra["requested_samples"]`` tells).  Reuses the
    windowed least-peak linear program, its dual bound and the exact
    correction of :mod:`.zoh`; checked by matrix-exponential simulation.

    Parameters
    ----------
    problem : MoveProblem or PreparedMove
        The move; a :class:`PreparedMove` reuses its responses and its
        attached time-optimal profile (for the fewest-samples sequence).
    arrival_time : float
        Requested arrival time (s), ``>= T*``.
    rate_hz : float
        Command rate (Hz), ``> 0``.  Checked here: this is a public entry
        point (``plan_move`` validates it once before calling it).
    continuous : BangBangProfile, optional
        The continuous fixed-time profile (:func:`plan_fixed_time`) if known.

    Raises
    ------
    FlexmotionError
        Bad ``arrival_time`` or ``rate_hz``.
    SolverError
        No sequence passes the exact final-state check.
    """
    t0 = time.perf_counter()
    rate = check_positive("rate_hz", rate_hz, "Hz")
    dt = 1.0 / rate
    move = prepare(problem)
    problem = move.problem
    if move.continuous is None:  # the time-optimal move, solved once for both planners below
        move = move.with_continuous(plan_time_optimal(move))
    if continuous is None:
        continuous = plan_fixed_time(move, arrival_time)
    T_req = continuous.duration
    K_req = round(T_req * rate)
    um = problem.u_max
    fewest = plan_time_optimal_zoh(move, rate)
    K = max(K_req, fewest.samples)
    if K == fewest.samples:
        out = fewest
        out.extra.update({"requested_samples": K_req, "peak_command": float(np.max(np.abs(out.commands), initial=0.0))})
        out.method = "fixed_time"
        return out
    system = move.response
    x0 = move.x0
    # LP units: the move's error scale (33 uniform instants missed a fast, damped
    # mode on a long move: units of 1e-9 of its excursion, an ill-posed LP)
    scale = move.error_scale(K * dt)
    G = sample_vectors(system, K, dt) / scale  # rows: m = samples to go
    w = -system.expm_x(K * dt, x0) / scale
    nu = -np.asarray(continuous.certificate.costate_final, float) * scale
    u, t_star, lower = least_peak_windows(G, w, nu, um, K)
    u_exact = correct_exactly(G, w, u, um)
    if u_exact is None:
        raise SolverError("fixed-time sampled planner: exact correction left the bound; nothing is returned")
    cmds = u_exact[::-1].copy()
    out = finish_sampled(move, cmds, dt, continuous, False, fewest.samples, t0)
    out.method = "fixed_time"
    out.extra.update(
        {
            "requested_samples": K_req,
            "peak_command": float(np.max(np.abs(cmds))),
            "least_peak": float(t_star),
            "least_peak_lower_bound": float(lower),
        }
    )
    return out


#: Gap between a window LP's peak and its own full-problem dual bound (relative) that proves the
#: window optimal outright (the dual's signs are then irrelevant).
WINDOW_GAP_RTOL = 1e-9
#: Most free samples in one windowed least-peak LP of :func:`least_peak_windows` (a work bound: HiGHS
#: took 1.6 s at 71,000 free samples, 10 s at 268,000, 18 s at 522,000; fuzz case 665).  A request of
#: more samples than this is planned from windows of at most this many free samples.
MAX_FREE_SAMPLES = 50_000


def least_peak_windows(
    G: np.ndarray, w: np.ndarray, nu: np.ndarray, u_max: float, K: int
) -> tuple[np.ndarray, float, float]:
    """The least-peak sequence at ``K`` samples from windows around the sign changes of ``S = G nu``.

    Samples outside the windows are fixed at ``+-t`` with the signs of ``S``;
    the windows grow (x4) until the window LP is optimal for the full problem,
    which either of two proofs shows:

    * its full-problem dual bound (weak duality over every sample) is within
      :data:`WINDOW_GAP_RTOL` of its peak;
    * its dual has the sign of every fixed sample (the KKT conditions of the
      full LP: the full LP's optimum is the window's), with the bound within
      the LP solver's own accuracy (``LP_RTOL``) of the peak.  Fuzz case 665
      (522,000 samples) met this at 1,539 free samples; the 1e-9 gap, below
      HiGHS's accuracy there (``t*`` itself moved by 1e-8 between windows),
      was never met and the windows grew to the full LP (10 LPs, 32 s).

    At most :data:`MAX_FREE_SAMPLES` samples are free (a work bound): past it,
    the best window sequence within ``u_max`` is returned with the lower bound
    it has.  Rows of ``G``: ``m`` = samples to go; ``nu``: a dual direction
    in the same (scaled) units (the continuous fixed-time co-state).

    Returns
    -------
    (u, t, lower) : (ndarray, float, float)
        Commands (samples to go), the LP's peak ``t`` (N), and the best proved
        lower bound on the least peak at ``K`` samples (N; weak duality, the
        LPs' duals and ``nu`` itself).

    Raises
    ------
    SolverError
        Every window LP failed, or needs a peak over ``u_max`` within the work bound.
    """
    S = G @ nu
    signs = np.where(S >= 0.0, 1.0, -1.0)
    lower = dual_bound(G, w, nu)  # any direction bounds the least peak below
    best = None
    width = 4
    while True:
        free = window_mask(S, width) if width < K else np.ones(K, dtype=bool)
        if np.count_nonzero(free) > MAX_FREE_SAMPLES:  # the work bound: the best window so far
            if best is not None and best[1] <= u_max * (1.0 + 1e-12):
                break
            raise SolverError(
                f"fixed-time sampled planner: the least-peak LP at {K} samples needs more than "
                f"{MAX_FREE_SAMPLES} free samples (its work bound); nothing is returned"
            )
        sol = solve_peak_lp(G, w, signs, free)
        if sol is not None:
            u, t_star, nu_lp = sol
            lower = max(lower, dual_bound(G, w, nu_lp))
            if best is None or t_star < best[1]:
                best = (u, t_star)
            signed = bool(np.all((signs * (G @ nu_lp))[~free] >= 0.0))
            if (
                lower >= t_star * (1.0 - WINDOW_GAP_RTOL)
                or (signed and lower >= t_star * (1.0 - LP_RTOL))
                or free.all()
            ):
                best = (u, t_star)  # the accepted window (not an unproved lower peak of a smaller one)
                break
        elif free.all():
            raise SolverError(f"fixed-time sampled planner: linear program failed at {K} samples")
        width *= 4
    u, t_star = best
    if t_star > u_max * (1.0 + 1e-12):
        raise SolverError(f"fixed-time sampled planner: {K} samples need peak {t_star:.9g} > u_max = {u_max}")
    return u, t_star, lower


def plan_fixed_time_lp(problem: MoveProblem | PreparedMove, arrival_time: float, rate_hz: float) -> SampledProfile:
    """Least-peak sequence arriving at rest at sample ``round(arrival_time * rate_hz)``, from the LP alone.

    For when the continuous time-optimum ``T*`` is not available (its planner
    refused the model): the full least-peak linear program at the requested
    count (every sample free, no continuous guess), its exact correction and
    the one exact sampled check.  ``arrival_time`` is checked against the rigid
    body's minimum time (a proved lower bound on ``T*``); a count that cannot
    reach rest within ``u_max`` is refused naming ``arrival_time`` and the
    least peak it would need (proved by the LP's dual).

    Raises
    ------
    InputError
        ``arrival_time`` below the rigid-body bound, or too early for ``u_max`` at this rate.
    SolverError
        The LP failed, the request has more than :data:`MAX_FREE_SAMPLES` samples (the
        work bound), or no sequence passes the exact final-state check.
    """
    t0 = time.perf_counter()
    rate = check_positive("rate_hz", rate_hz, "Hz")
    dt = 1.0 / rate
    move = prepare(problem)
    problem = move.problem
    um = problem.u_max
    T_rigid = rigid_time(problem.model, um, move.x0, problem.include_position)
    T_req = check_arrival_time(arrival_time, T_rigid)
    lower = max(1, math.ceil(T_rigid * rate * (1.0 - 1e-12)))
    K = max(round(T_req * rate), lower)
    if K > MAX_FREE_SAMPLES:  # every sample free: the LP's work grows faster than K (18 s at 522,000)
        raise SolverError(
            f"fixed-time sampled planner: with no continuous move to guide it, the least-peak LP would free all "
            f"{K} samples at {rate:g} Hz, past its work bound of {MAX_FREE_SAMPLES}; nothing is returned"
        )
    system = move.response
    scale = move.error_scale(K * dt)
    G = sample_vectors(system, K, dt) / scale  # rows: m = samples to go
    w = -system.expm_x(K * dt, move.x0) / scale
    sol = solve_peak_lp(G, w, np.ones(K), np.ones(K, dtype=bool))
    if sol is None:
        raise SolverError(f"fixed-time sampled planner: linear program failed at {K} samples; nothing is returned")
    u, t_star, nu = sol
    if t_star > um * (1.0 + LP_RTOL):
        proof = " (proved by the LP's dual)" if dual_bound(G, w, nu) > um * (1.0 + BOUND_RTOL) else ""
        raise InputError(
            "arrival_time",
            f"{T_req:.6g} s is too early: {K} samples at {rate:g} Hz need a peak command of {t_star:.6g} > u_max = "
            f"{um:g}{proof} to arrive at rest; choose a later arrival_time",
        )
    u_exact = correct_exactly(G, w, u * (um / max(t_star, um)), um)
    if u_exact is None:
        raise SolverError("fixed-time sampled planner: exact correction left the bound; nothing is returned")
    cmds = u_exact[::-1].copy()
    out = finish_sampled(move, cmds, dt, None, False, lower, t0)
    out.method = "fixed_time"
    out.extra.update(
        {
            "requested_samples": round(T_req * rate),
            "peak_command": float(np.max(np.abs(cmds))),
            "least_peak": float(t_star),
        }
    )
    return out
