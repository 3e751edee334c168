"""Zero-order-hold robust time-optimal moves: the fewest samples keeping the robust constraints exact."""

from __future__ import annotations

import math
import time

import numpy as np

from ..errors import InputError, SolverError
from ..model.boundary import MoveProblem
from ..results import BangBangProfile, SampledProfile
from ..simulation.error_scale import state_scale
from ..simulation.prepared import PreparedMove, prepare
from ..time_optimal.robust import RobustModalResponse
from ..tolerances import BOUND_RTOL, LP_RTOL
from .check import AugmentedSystem, verified_samples
from .lp_tools import sample_vectors
from .zoh import dual_bound, search_samples, solve_peak_lp

#: Sample counts tried above the continuous robust move's ``ceil(T / dt)``.
MAX_EXTRA_SAMPLES = 200
#: Without a continuous robust move: counts tried by doubling above the nominal ``ceil(T* / dt)``
#: before the search gives up (2^12 times the first gap: far past any robust move of the budget).
MAX_DOUBLINGS = 12
#: Without a continuous robust move: the longest full least-peak LP (samples) of the bracket.  Its
#: work grows with the samples (fuzz seed 15 case 775, 7 modes: 7-11 s CPU per LP at 89,000-179,000
#: samples); past it the method refuses rather than run for minutes.
MAX_BRACKET_SAMPLES = 30_000
#: The bisection stops within this many samples; the windowed search walks the rest.
BRACKET_RESOLUTION = 16


def plan_robust_time_optimal_zoh(
    problem: MoveProblem | PreparedMove,
    profile: BangBangProfile | None,
    order: int,
    rate_hz: float,
    lower_duration: float = 0.0,
) -> SampledProfile:
    """Fewest zero-order-hold samples keeping the robust constraints exactly (nominal model and derivatives).

    The nominal planner's search (:func:`~.zoh.search_samples`) on the
    augmented system: samples away from the continuous switches saturate with
    the sign of the robust optimum's switching function, windowed peak LPs
    around the switches are accepted only if their dual certifies them over
    every sample (windows grow otherwise), a count is proved infeasible by
    weak duality, an exact least-norm correction follows and the result is
    checked by the augmented matrix-exponential simulation.  ``K_lo = ceil(T
    / dt)`` is a proved lower bound (every sequence is a continuous input).

    Every returned sequence passes the one exact sampled check
    (:func:`~flexmotion_ros.core.sampled.check.verified_samples`: nominal
    final state against the move's error scale, bound), extended with the
    augmented system (nominal states and their frequency derivatives), whose
    final state is judged against its own trajectory's excursion as before.

    Parameters
    ----------
    problem : MoveProblem or PreparedMove
        The move (a :class:`PreparedMove` reuses its shifted state and scales).
    profile : BangBangProfile or None
        The continuous robust profile; None if the continuous robust solver
        found none (then :func:`bracket_samples` finds the count from the
        linear programs alone, above ``lower_duration``).
    order : int
        Derivative order of the robust constraints.
    rate_hz : float
        Command rate (Hz), ``> 0`` (not checked here: ``plan_move`` validates it).
    lower_duration : float
        A proved lower bound on the robust move's duration (s), e.g. the
        nominal time-optimal ``T*``; used only without ``profile``.
    """
    t0 = time.perf_counter()
    move = prepare(problem)
    problem = move.problem
    dt = 1.0 / rate_hz
    um = problem.u_max
    system = RobustModalResponse(problem.model, order, problem.include_position)
    xa0 = system.augment(move.x0)
    aug = AugmentedSystem(A=system.A(), B=system.B(), x0=xa0)
    if profile is None:
        K_first = max(1, math.ceil(lower_duration / dt * (1.0 - 1e-12)))
        if K_first > MAX_BRACKET_SAMPLES:
            raise SolverError(too_long_without_continuous(problem.model.omega, lower_duration, rate_hz))
        K_lo, K_hi, nu = bracket_samples(system, xa0, um, dt, K_first)
        T = K_hi * dt
    else:
        T = profile.duration
    if T / dt > 5e6:
        raise InputError("rate_hz", f"a {T:.3g} s move at {rate_hz:g} Hz needs over 5e6 samples; lower the rate")
    if profile is not None:
        K_lo = max(1, math.ceil(T / dt * (1.0 - 1e-12)))
    # LP units: how large each augmented state gets (uniform and geometric
    # instants: on a long move 33 uniform ones missed a fast, damped mode's
    # derivative states, whose units then came out 1e-160: G overflowed)
    scale = state_scale(system, xa0, um, T)
    if profile is not None:  # the continuous robust optimum's dual direction guesses the saturated samples
        costate = np.asarray(profile.certificate.costate_final, dtype=float)
        nu = -costate * scale if costate.size == scale.size else None
    else:  # the bracket's dual direction, in these units
        nu = nu * scale if nu is not None else None

    def finish(cmds: np.ndarray, minimal: bool, lower: int) -> SampledProfile:
        return verified_samples(move, cmds, dt, "robust_time_optimal", minimal, lower, profile, None, t0, augmented=aug)

    # the nominal planner's fewest-samples search on the augmented system:
    # windowed peak LPs accepted by their dual over every sample, each count
    # proved infeasible by weak duality, the sample vectors built once
    K_max = K_lo + MAX_EXTRA_SAMPLES if profile is not None else max(K_hi, K_lo) + MAX_EXTRA_SAMPLES
    found = search_samples(system, xa0, um, scale, dt, K_lo, K_max, nu, finish)
    if found is None and profile is None:
        raise SolverError(
            f"robust time-optimal: no sampled sequence at {rate_hz:g} Hz passed the exact check within "
            f"{MAX_EXTRA_SAMPLES} samples of the linear programs' fewest ({K_hi}); nothing is returned"
        )
    if found is None:
        raise SolverError(
            f"robust time-optimal: no sampled sequence at {rate_hz:g} Hz within {MAX_EXTRA_SAMPLES} samples of "
            "the continuous robust move; nothing is returned"
        )
    return found


def too_long_without_continuous(omega, lower_duration: float, rate_hz: float) -> str:
    """The refusal of a move too long for the sampled robust planner without a continuous robust move.

    Parameters
    ----------
    omega : sequence of float
        The modes' natural frequencies (rad/s).
    lower_duration : float
        A proved lower bound on the move's duration (s), e.g. the nominal ``T*``.
    rate_hz : float
        Command rate (Hz).
    """
    wmax = float(np.max(omega)) if len(omega) else 0.0
    return (
        f"robust time-optimal: the move lasts at least {lower_duration:.4g} s (its time-optimal lower bound), "
        f"{math.ceil(lower_duration * rate_hz)} samples at {rate_hz:g} Hz, and spans "
        f"{lower_duration * wmax / math.pi:.3g} half periods of the fastest mode ({wmax:.3g} rad/s): the "
        f"continuous robust solver found no move over that span, and it is longer than the "
        f"{MAX_BRACKET_SAMPLES / rate_hz:.4g} s ({MAX_BRACKET_SAMPLES} samples) the sampled robust planner "
        "searches without it; nothing is returned "
        "(shorten the move, or plan it time_optimal or shaped)"
    )


def bracket_samples(
    system: RobustModalResponse, xa0: np.ndarray, u_max: float, dt: float, K_lo: int
) -> tuple[int, int, np.ndarray | None]:
    """The fewest samples by the full least-peak LPs alone: ``(proved lower bound, fewest feasible, dual)``.

    For when no continuous robust move guesses the count (its solver found
    none).  Feasibility is monotone in the count (hold zero after arriving), so
    counts double above ``K_lo`` until one is feasible, then bisection narrows
    the bracket; a count below is proved infeasible only by its weak-duality
    bound (else it just stays unproved: the lower bound is not raised).  The
    LP units are the move's error scale at the largest count tried.  Returns
    the dual direction of the feasible count's LP (in those units divided out:
    multiply by the caller's scale), to guess its saturated samples.

    Raises
    ------
    SolverError
        No count within :data:`MAX_DOUBLINGS` doublings, nor up to
        :data:`MAX_BRACKET_SAMPLES` (the full LPs' work bound), is feasible.
    """
    proved = K_lo  # every count below is infeasible (the given bound)
    gap = max(K_lo, 16)
    trial = K_lo
    feasible: dict[int, np.ndarray] = {}
    G_all = scale = None
    K_built = 0

    def probe(K: int) -> bool:
        nonlocal proved, G_all, scale, K_built
        if K > MAX_BRACKET_SAMPLES:
            raise SolverError(
                f"robust time-optimal: no sampled sequence of {lo} samples or fewer ({lo * dt:.4g} s at "
                f"{1.0 / dt:g} Hz) keeps the robust constraints within the bound (least-peak LPs), and the "
                f"continuous robust solver found no move: longer moves are past the {MAX_BRACKET_SAMPLES} "
                "samples the sampled robust planner searches without it; nothing is returned"
            )
        if K > K_built:  # units and sample vectors at the largest count yet (sliced below it)
            K_built = 2 * K
            scale = state_scale(system, xa0, u_max, K_built * dt)
            G_all = sample_vectors(system, K_built, dt) / scale
        G = G_all[:K]
        w = -system.expm_x(K * dt, xa0) / scale
        sol = solve_peak_lp(G, w, np.ones(K), np.ones(K, dtype=bool))
        if sol is None:
            return False
        _, t_star, nu = sol
        if t_star <= u_max * (1.0 + LP_RTOL):
            feasible[K] = nu / scale
            return True
        if dual_bound(G, w, nu) > u_max * (1.0 + BOUND_RTOL):
            proved = max(proved, K + 1)
        return False

    lo = K_lo - 1  # the largest count known infeasible (below the given bound: every one)
    for _ in range(MAX_DOUBLINGS + 1):
        if probe(trial):
            break
        lo = trial
        trial = min(K_lo + gap, max(MAX_BRACKET_SAMPLES, lo + 1))  # the cap itself is tried once
        gap *= 2
    else:
        raise SolverError(
            f"robust time-optimal: no sampled sequence of up to {lo} samples ({lo * dt:.4g} s) keeps the "
            "robust constraints within the bound; nothing is returned"
        )
    hi = trial
    while hi - lo > BRACKET_RESOLUTION:  # lo infeasible, hi feasible; the windowed search walks the rest
        mid = (lo + hi) // 2
        if probe(mid):
            hi = mid
        else:
            lo = mid
    return proved, hi, feasible[hi]
