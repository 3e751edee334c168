"""Exact zero-order-hold time-optimal moves at a fixed sample rate.

A planner that streams at ``rate_hz`` sends a sequence ``u_0, ..., u_{K-1}``,
each held for ``dt = 1/rate_hz``.  Sampling the continuous bang-bang profile
naively does not reach the target (the switches fall between samples).  This
module finds the *fewest* samples ``K`` and commands ``|u_k| <= u_max`` that
bring the model exactly to rest at the target at sample ``K``.

Method
------
With ``g_m = e^{A m dt} Gamma(dt)`` (``m`` samples to go) the final state is
zero iff ``sum_m g_m u_m = w_K := -e^{A K dt} x0``.  For each ``K`` the
linear program ``t*(K) = min t  s.t.  sum g_m u_m = w_K, |u_m| <= t`` gives
the smallest peak command that arrives in ``K`` samples; ``K`` is feasible
iff ``t*(K) <= u_max``, and feasibility is monotone in ``K`` (hold zero after
arriving).  Lower bounds come with proofs:

* the continuous optimum ``T*``: any sequence is an admissible continuous
  input, so ``K dt >= T*``;
* weak duality: for any ``nu``, ``t*(K) >= nu^T w_K / sum_m |nu^T g_m|``; a
  ratio above ``u_max`` proves that ``K`` samples cannot reach the target.

Far from the continuous switches the optimal commands sit at ``+-t`` with
the sign of the continuous switching function, so the LP is solved with only
windows around the switches free, and the window solution is accepted only
if its dual certifies it for the full problem (signs agree on every fixed
sample); otherwise the windows grow.  The solution is then corrected to an
exact final state and checked by matrix-exponential simulation.  The LP and
its bound are :mod:`.peak_lp`; this module searches the count.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from ..errors import GoalError, SolverError
from ..model.boundary import MoveProblem
from ..model.modal_model import check_positive
from ..results import BangBangProfile, SampledProfile
from ..simulation.exact import simulate_samples
from ..simulation.prepared import PreparedMove, prepare
from ..time_optimal.solver import plan_time_optimal
from ..tolerances import BOUND_RTOL, LP_RTOL
from .check import verified_samples
from .correction import (
    correct_exactly,  # noqa: F401  (re-exported: the other sampled planners import it from here)
    exact_candidates,
    lands_exactly,
)
from .peak_lp import (  # dual_bound, solve_peak_lp, window_mask: also imported from here by the other sampled planners
    dual_bound,
    grid_sample_vectors,
    solve_peak_lp,
    window_mask,
)
from .switch_samples import switch_sample_sequence

MAX_EXTRA_SAMPLES = 200
#: Work bound of the count search above ``K_lo``: at most ``SAMPLE_BUDGET / K_lo`` counts (but at least
#: ``MIN_EXTRA_SAMPLES``, at most ``MAX_EXTRA_SAMPLES``).  Each count costs ``O(K)`` products, least-norm
#: corrections over ``K x n`` matrices and window LPs (about 3 s CPU per count at 2.4e6 samples, a 40 min move at
#: 1 kHz): 200 counts of such a move are many minutes.  The sampled optimum of a long move lands within a few
#: samples of ``K_lo`` (its peak is within ~1/K of ``u_max`` there; fuzz: at most +4 at 1.6e6-2.4e6 samples).
SAMPLE_BUDGET = 20_000_000
MIN_EXTRA_SAMPLES = 8


def extra_samples(K_lo: int) -> int:
    """Counts tried above ``K_lo`` by :func:`plan_time_optimal_zoh` (the work bound of ``SAMPLE_BUDGET``)."""
    return max(MIN_EXTRA_SAMPLES, min(MAX_EXTRA_SAMPLES, SAMPLE_BUDGET // max(K_lo, 1)))


#: Try :func:`.switch_samples.switch_sample_sequence` before the LP at every count (False: the LP alone, as before).
SWITCH_SAMPLES = True


def plan_time_optimal_zoh(
    problem: MoveProblem | PreparedMove, rate_hz: float, continuous: BangBangProfile | None = None
) -> SampledProfile:
    """Fewest zero-order-hold samples at ``rate_hz`` that reach rest exactly.

    Parameters
    ----------
    problem : MoveProblem or PreparedMove
        The move; a :class:`PreparedMove` reuses its responses (and its
        attached continuous optimum if ``continuous`` is not given).
    rate_hz : float
        Command rate (Hz), ``> 0``.  Checked here: this is a public entry
        point (``plan_move`` validates it once before calling it).
    continuous : BangBangProfile, optional
        The continuous time-optimal profile of ``problem`` if already known.

    Returns
    -------
    SampledProfile
        ``minimal`` is True when ``samples - 1`` is proved infeasible.

    Raises
    ------
    SolverError
        If no sequence passes the exact final-state check.
    """
    t0 = time.perf_counter()
    rate = check_positive("rate_hz", rate_hz, "Hz")
    dt = 1.0 / rate
    move = prepare(problem)
    problem = move.problem
    if continuous is None:
        continuous = move.continuous if move.continuous is not None else plan_time_optimal(move)
    T = continuous.duration
    if T == 0.0:
        states = simulate_samples(problem.model, problem.x0, np.empty(0), dt)
        return SampledProfile(problem, np.empty(0), dt, states, 0.0, 0.0, True, 0, continuous, time.perf_counter() - t0)
    if T / dt > 5e6:
        raise GoalError("rate_hz", f"a {T:.3g} s move at {rate:g} Hz needs over 5e6 samples; lower the rate")
    K_lo = max(1, math.ceil(T / dt * (1.0 - 1e-12)))
    # the scale of the sampled move (K_lo dt >= T): for a move far shorter than
    # a sample (u_max 1e12) the continuous T would leave the LP badly scaled
    scale = move.error_scale(K_lo * dt)
    # dual direction of the continuous optimum (nu = -lambda(T)), in scaled coordinates
    nu = -np.asarray(continuous.certificate.costate_final, dtype=float) * scale
    extra = extra_samples(K_lo)
    found = fewest_samples(move, dt, K_lo, K_lo + extra, nu, continuous, t0)
    if found is None:
        if extra < MAX_EXTRA_SAMPLES:  # the work bound ended the search, not the range
            raise SolverError(
                f"sampled planner: no exact sequence at {rate:g} Hz within {extra} samples of the continuous "
                f"optimum's {K_lo} (a {T:.3g} s move: each count costs O(samples) work and the fewest samples' "
                "peak lies within ~1/samples of u_max); lower the rate"
            )
        raise SolverError(
            f"sampled planner: no feasible sequence within {MAX_EXTRA_SAMPLES} samples of the continuous optimum"
        )
    return found


def fewest_samples(
    move: PreparedMove,
    dt: float,
    K_lo: int,
    K_max: int,
    nu: np.ndarray | None,
    continuous: BangBangProfile | None,
    t0: float,
) -> SampledProfile | None:
    """The fewest samples in ``[K_lo, K_max]`` reaching rest exactly, or None if none of them does.

    Parameters
    ----------
    move : PreparedMove
        The move.
    dt : float
        Sample period (s).
    K_lo : int
        A proved lower bound on the sample count (``ceil(T / dt)`` for a
        proved lower bound ``T`` on the continuous optimum, s).
    K_max : int
        The last count tried.
    nu : ndarray or None
        A dual direction (scaled by ``move.error_scale(K_lo dt)``) whose
        switching-function signs guess the saturated samples; None: none known
        (every sample is free once the windows have grown).
    continuous : BangBangProfile or None
        Recorded in the result.
    t0 : float
        ``time.perf_counter()`` at the start of planning (s).

    Returns
    -------
    SampledProfile or None
        ``minimal`` when every count below it is proved infeasible (the
        continuous bound, or a weak-duality bound above ``u_max``).
    """
    system = move.response
    scale = move.error_scale(K_lo * dt)

    def finish(cmds: np.ndarray, minimal: bool, lower: int) -> SampledProfile:
        return finish_sampled(move, cmds, dt, continuous, minimal, lower, t0)

    return search_samples(system, move.x0, move.u_max, scale, dt, K_lo, K_max, nu, finish)


def reaches_rest_within(move: PreparedMove, dt: float, K: int) -> bool | None:
    """Can ``K`` samples of at most ``u_max`` bring ``move`` to rest?  One full linear program (None: undecided).

    Feasibility is monotone in ``K`` (the target is an equilibrium: a sequence
    that arrives in ``K`` samples followed by holds arrives in any more), so a
    False here also refuses every count below ``K`` -- one LP instead of a
    search over every count (the verdict of ``min peak > u_max`` is the LP's own
    optimum: with every sample free, weak duality is tight).
    """
    system = move.response
    scale = move.error_scale(K * dt)
    G = grid_sample_vectors(system, K, dt) / scale
    w = -system.expm_x(K * dt, move.x0) / scale
    sol = solve_peak_lp(G, w, np.ones(K), np.ones(K, dtype=bool))
    if sol is None:
        return None
    return bool(sol[1] <= move.u_max * (1.0 + LP_RTOL))


def search_samples(
    system,
    x0: np.ndarray,
    u_max: float,
    scale: np.ndarray,
    dt: float,
    K_lo: int,
    K_max: int,
    nu: np.ndarray | None,
    finish: Callable[[np.ndarray, bool, int], SampledProfile],
) -> SampledProfile | None:
    """The fewest-samples search of :func:`fewest_samples` for any linear system (e.g. the robust augmented one).

    Parameters
    ----------
    system : ModalResponse or compatible
        ``input_integral``, ``expm_x`` and ``expm_x_many`` of the system the
        sequence must bring to its origin.
    x0 : ndarray
        Its shifted initial state.
    u_max : float
        Bound on every command (N).
    scale : ndarray
        Per-state unit of the linear programs (state units).
    dt : float
        Sample period (s).
    K_lo, K_max : int
        Proved lower bound on the count; last count tried.
    nu : ndarray or None
        Scaled dual direction guessing the saturated samples' signs.
    finish : callable
        ``finish(commands, minimal, lower_bound) -> SampledProfile``: the
        exact checks; a :class:`SolverError` from it tries one more sample.

    The sample vectors ``g_m`` (``m`` samples to go) do not depend on the
    count, so they are built once for ``K_max`` and sliced: the work per
    count is the linear program alone, not a rebuild of ``K x n`` responses.
    """
    um = u_max
    G_all = grid_sample_vectors(system, K_max, dt) / scale  # rows: m = samples to go
    if nu is not None and not np.any(nu):
        nu = None
    proved_infeasible_below = K_lo  # every K < K_lo is infeasible (the given bound)
    K = K_lo
    while K <= K_max:
        G = G_all[:K]
        w = -system.expm_x(K * dt, x0) / scale
        S = G @ nu if nu is not None else np.ones(K)
        if nu is not None and SWITCH_SAMPLES:
            # no LP: +-t with the signs of S, one free sample per switch (an n x (switches + 1) solve);
            # a sequence within the bound is feasible at K, and K's proof is the bookkeeping's, as below
            fast = switch_sample_sequence(G, w, S, um)
            if fast is not None:
                try:
                    return finish(fast[::-1].copy(), K == proved_infeasible_below, proved_infeasible_below)
                except SolverError:  # the exact check decides: the LP path tries this count
                    pass
        signs = np.where(S >= 0.0, 1.0, -1.0)
        width = 4
        result = None
        while True:
            free = window_mask(S, width) if width < K else np.ones(K, dtype=bool)
            sol = solve_peak_lp(G, w, signs, free)
            if sol is not None:
                u, t_star, nu_lp = sol
                bound = dual_bound(G, w, nu_lp)
                # feasible within the window: feasible, full stop (the exact
                # correction below decides); infeasible: only a dual bound
                # above u_max over ALL samples proves it, else widen
                if t_star <= um * (1.0 + LP_RTOL) or bound > um * (1.0 + BOUND_RTOL) or free.all():
                    result = (u, t_star, bound, nu_lp)
                    break
            if free.all():
                break
            width *= 4
        if result is None:
            # no sequence at all reaches the target in K samples (fewer samples
            # than states): the least-squares residual proves it
            u_ls, *_ = np.linalg.lstsq(G.T, w, rcond=None)
            if np.max(np.abs(G.T @ u_ls - w)) > 1e-6 * max(float(np.max(np.abs(w))), 1e-300):
                proved_infeasible_below = K + 1  # infeasible at K => at every K' < K
                K += 1
                continue
            # the LP failed numerically (as few samples as states: a square,
            # ill-conditioned system); its least-norm solution, if within the
            # bound, goes to the exact checks; otherwise one more sample
            peak = float(np.max(np.abs(u_ls)))
            if not peak <= um:
                K += 1
                continue
            result = (u_ls, peak, -math.inf, nu)
        u, t_star, bound, nu_lp = result
        if t_star <= um * (1.0 + LP_RTOL):  # the exact correction and checks decide
            u_in = u * (um / max(t_star, um))
            for cand in exact_candidates(G, w, u_in, um, free):
                if lands_exactly(G, w, cand):
                    cmds = cand[::-1].copy()  # m = samples to go -> forward order
                    try:
                        return finish(cmds, K == proved_infeasible_below, proved_infeasible_below)
                    except SolverError:  # the exact check decides: one more sample
                        pass
        if bound > um * (1.0 + BOUND_RTOL):
            proved_infeasible_below = K + 1  # infeasible at K => at every K' < K
        nu = nu_lp
        K += 1
    return None


def finish_sampled(
    problem: MoveProblem | PreparedMove,
    cmds: np.ndarray,
    dt: float,
    continuous: BangBangProfile | None,
    minimal: bool,
    lower: int,
    t0: float,
) -> SampledProfile:
    """The exact check of :func:`~flexmotion_ros.core.sampled.check.verified_samples` for a ZOH optimum."""
    return verified_samples(problem, cmds, dt, "time_optimal", minimal, lower, continuous, None, t0)
