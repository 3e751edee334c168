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
from .check import AugmentedSystem, verified_samples
from .zoh import search_samples

#: Sample counts tried above the continuous robust move's ``ceil(T / dt)``.
MAX_EXTRA_SAMPLES = 200


def plan_robust_time_optimal_zoh(
    problem: MoveProblem | PreparedMove, profile: BangBangProfile, order: int, rate_hz: float
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
    profile : BangBangProfile
        The continuous robust profile.
    order : int
        Derivative order of the robust constraints.
    rate_hz : float
        Command rate (Hz), ``> 0`` (not checked here: ``plan_move`` validates it).
    """
    t0 = time.perf_counter()
    move = prepare(problem)
    problem = move.problem
    dt = 1.0 / rate_hz
    um = problem.u_max
    system = RobustModalResponse(problem.model, order, problem.include_position)
    xa0 = system.augment(move.x0)
    aug = AugmentedSystem(A=system.A(), B=system.B(), x0=xa0)
    T = profile.duration
    if T / dt > 5e6:
        raise InputError("rate_hz", f"a {T:.3g} s move at {rate_hz:g} Hz needs over 5e6 samples; lower the rate")
    K_lo = max(1, math.ceil(T / dt * (1.0 - 1e-12)))
    # LP units: how large each augmented state gets (uniform and geometric
    # instants: on a long move 33 uniform ones missed a fast, damped mode's
    # derivative states, whose units then came out 1e-160: G overflowed)
    scale = state_scale(system, xa0, um, T)
    # the continuous robust optimum's dual direction guesses the saturated samples
    costate = np.asarray(profile.certificate.costate_final, dtype=float)
    nu = -costate * scale if costate.size == scale.size else None

    def finish(cmds: np.ndarray, minimal: bool, lower: int) -> SampledProfile:
        return verified_samples(move, cmds, dt, "robust_time_optimal", minimal, lower, profile, None, t0, augmented=aug)

    # the nominal planner's fewest-samples search on the augmented system:
    # windowed peak LPs accepted by their dual over every sample, each count
    # proved infeasible by weak duality, the sample vectors built once
    found = search_samples(system, xa0, um, scale, dt, K_lo, K_lo + MAX_EXTRA_SAMPLES, nu, finish)
    if found is None:
        raise SolverError(
            f"robust time-optimal: no sampled sequence at {rate_hz:g} Hz within {MAX_EXTRA_SAMPLES} samples of "
            "the continuous robust move; nothing is returned"
        )
    return found
