"""Zero-order-hold robust time-optimal moves: the fewest samples keeping the robust constraints exact."""

from __future__ import annotations

import math
import time

import numpy as np
from scipy.optimize import linprog
from scipy.sparse import csr_matrix

from ..errors import InputError, SolverError
from ..model.boundary import MoveProblem
from ..results import BangBangProfile, SampledProfile
from ..simulation.prepared import PreparedMove, prepare
from ..time_optimal.robust import RobustModalResponse
from .check import AugmentedSystem, verified_samples
from .lp_tools import least_norm_correction


def plan_robust_time_optimal_zoh(
    problem: MoveProblem | PreparedMove, profile: BangBangProfile, order: int, rate_hz: float
) -> SampledProfile:
    """Fewest zero-order-hold samples keeping the robust constraints exactly (nominal model and derivatives).

    Samples away from the continuous switches keep the continuous level; a
    linear program sets those in windows around the switches (windows grow,
    then the sample count, until feasible); an exact least-norm correction
    follows and the result is checked by the augmented matrix-exponential
    simulation.  ``K_lo = ceil(T / dt)`` is a proved lower bound (every
    sequence is a continuous input), so ``minimal`` holds if ``K_lo`` works.

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
    scale = np.abs(xa0) + um * np.max(np.abs(system.input_integral(np.linspace(0.0, T, 33))), axis=0)
    scale = np.where(scale > 0.0, scale, 1.0)
    gam = system.input_integral(np.array([dt]))[0]
    cont = profile.input()
    tight = um * (1.0 - 1e-6)  # leave room for the exact correction after the LP's tolerance
    for K in range(K_lo, K_lo + 50):
        G = system.expm_x_many(dt * np.arange(K)[::-1], gam) / scale
        w = -system.expm_x(K * dt, xa0) / scale
        mids = dt * (np.arange(K) + 0.5)
        fixed_level = np.where(cont(mids) >= 0.0, um, -um)
        near = np.zeros(K, dtype=bool)
        for ts in profile.switch_times:
            near[min(int(ts / dt), K - 1)] = True
        width = 2
        while True:
            free = _dilate(near, width)
            free[K - width :] = True
            F = np.flatnonzero(free)
            rhs = w - G[~free].T @ fixed_level[~free]
            res = linprog(
                np.zeros(F.size), A_eq=csr_matrix(G[F].T), b_eq=rhs, bounds=[(-tight, tight)] * F.size, method="highs"
            )
            if res.status == 0 or free.all():
                break
            width *= 4
        if res.status != 0:
            continue
        u = fixed_level.copy()
        u[F] = res.x
        cmds = least_norm_correction(G, w, u, um)
        if cmds is None:
            continue
        try:
            return verified_samples(
                move, cmds, dt, "robust_time_optimal", K == K_lo, K_lo, profile, None, t0, augmented=aug
            )
        except SolverError:  # misses the nominal or the augmented target: one more sample
            continue
    raise SolverError(f"robust time-optimal: no sampled sequence at {rate_hz:g} Hz found; nothing is returned")


def _dilate(mask: np.ndarray, width: int) -> np.ndarray:
    """``mask`` grown by ``width`` samples on each side, same length.

    (``np.convolve(..., mode="same")`` returns ``max(K, 2 width + 1)``
    entries: once the windows outgrew a short move, the mask no longer fitted.)
    """
    K = mask.size
    idx = np.flatnonzero(mask)
    edges = np.zeros(K + 1, dtype=int)
    np.add.at(edges, np.clip(idx - width, 0, K), 1)
    np.add.at(edges, np.clip(idx + width + 1, 0, K), -1)
    return np.cumsum(edges[:K]) > 0
