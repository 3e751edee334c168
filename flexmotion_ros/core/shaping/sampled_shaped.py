"""A shaped command sampled at the node's rate, reaching rest exactly.

A node streams ``u_k`` held for ``dt = 1/rate_hz``.  :func:`sample_command`
averages the continuous command over each sample (averages of values within
the bound stay within it), then removes the remaining final-state error with
a least-norm change of the samples that have slack, so that the nominal model
reaches rest exactly at a sample instant; the result is checked by the
matrix-exponential simulation.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..errors import GoalError, SolverError
from ..model.boundary import MoveProblem
from ..results import SampledProfile
from ..sampled.check import verified_samples
from ..sampled.lp_tools import least_norm_correction, sample_vectors
from ..simulation.exact import PiecewiseConstant, simulate_samples
from ..simulation.prepared import PreparedMove, prepare
from ..tolerances import FINAL_STATE_RTOL

#: Sample counts tried past ``ceil(T / dt)`` before the command is refused.
MAX_EXTRA_SAMPLES = 4


def sample_average(u: PiecewiseConstant, dt: float, K: int) -> np.ndarray:
    """Mean of ``u`` over each of ``K`` samples of ``dt`` (s); zero past its end."""
    cum = np.concatenate([[0.0], np.cumsum(u.levels * np.diff(u.breaks))])
    edges = dt * np.arange(K + 1)
    integral = np.interp(edges, u.breaks, cum)  # int_0^t u is piecewise linear
    return np.diff(integral) / dt


def sample_command(
    problem: MoveProblem | PreparedMove,
    u: PiecewiseConstant,
    rate_hz: float,
    method: str,
    continuous=None,
    lower_bound_samples: int = 0,
) -> SampledProfile:
    """Zero-order-hold version of ``u`` at ``rate_hz`` reaching rest exactly (nominal model).

    Parameters
    ----------
    problem : MoveProblem or PreparedMove
        The move; a :class:`PreparedMove` reuses its responses.
    u : PiecewiseConstant
        The continuous command (N) to sample.
    rate_hz : float
        Command rate (Hz), ``> 0`` (not checked here: called through
        ``plan_move``, which validates it).
    method : str
        Method name for the profile and errors.
    continuous : optional
        The continuous profile ``u`` came from (kept in the result).
    lower_bound_samples : int
        A proved lower bound on the sample count (reported).

    Every returned sequence passes the one exact sampled check,
    :func:`~flexmotion_ros.core.sampled.check.verified_samples` (final-state
    error relative to the move's error scale, bound ``u_max``), which also
    builds the result.  Before it, a sample count is accepted only if the final
    state is also within ``FINAL_STATE_RTOL`` of the trajectory's own excursion
    (``max_t |x(t) - x_f|``): the criterion this planner always used, kept as
    an additional test so that routing through the common check loosens
    nothing (the error scale is usually the larger of the two).

    Raises
    ------
    SolverError
        If no correction within the bound reaches rest, or the exact simulation disagrees.
    """
    t0 = time.perf_counter()
    dt = 1.0 / rate_hz
    T = u.duration
    if T / dt > 5e6:
        raise GoalError("rate_hz", f"a {T:.3g} s move at {rate_hz:g} Hz needs over 5e6 samples; lower the rate")
    move = prepare(problem)
    problem = move.problem
    model, um = problem.model, problem.u_max
    system = move.response
    x0 = move.x0
    if T == 0.0:
        states = simulate_samples(model, problem.x0, np.empty(0), dt)
        return SampledProfile(
            problem, np.empty(0), dt, states, 0.0, 0.0, True, 0, continuous, time.perf_counter() - t0, method
        )
    K0 = max(1, math.ceil(T / dt * (1.0 - 1e-12)))
    # units of the correction: the move's error scale (uniform and geometric
    # instants; 33 uniform ones missed a fast, damped mode on a long move, whose
    # units came out ~1e-9 of its real excursion and wrecked the correction)
    scale = move.error_scale(T + dt)
    # g_m (m samples to go) do not depend on K: built once, sliced per count
    G_all = sample_vectors(system, K0 + MAX_EXTRA_SAMPLES, dt) / scale
    for K in range(K0, K0 + MAX_EXTRA_SAMPLES + 1):
        samples = sample_average(u, dt, K)
        G = G_all[:K][::-1]  # row k: sample k's effect at K dt
        w = -system.expm_x(K * dt, x0) / scale
        cmds = least_norm_correction(G, w, samples, um)
        if cmds is None:
            continue
        states = simulate_samples(model, problem.x0, cmds, dt)
        target = model.rest_state(problem.target if problem.target is not None else 0.0)
        dev = states[-1] - target
        sc = states - target
        if problem.target is None:
            dev, sc = dev[1:], sc[:, 1:]
        s = np.max(np.abs(sc), axis=0)
        s = np.where(s > 0.0, s, 1.0)
        rel = float(np.max(np.abs(dev) / s))
        if rel <= FINAL_STATE_RTOL and np.max(np.abs(cmds)) <= um:
            try:
                return verified_samples(move, cmds, dt, method, False, lower_bound_samples, continuous, None, t0)
            except SolverError:  # misses the common error scale: try one more sample
                continue
    raise SolverError(
        f"{method}: no sampled sequence at {rate_hz:g} Hz reaches rest within the bound; nothing is returned"
    )
