"""Zero-order-hold robust time-optimal moves: the fewest samples keeping the robust constraints exact."""

from __future__ import annotations

import math
import time

import numpy as np
from scipy.optimize import linprog
from scipy.sparse import csr_matrix

from ..errors import FlexmotionError, SolverError
from ..model.boundary import MoveProblem
from ..results import BangBangProfile, SampledProfile
from ..simulation.exact import simulate_samples
from ..time_optimal.robust import RobustModalResponse
from ..tolerances import FINAL_STATE_RTOL
from .lp_tools import least_norm_correction


def plan_robust_time_optimal_zoh(
    problem: MoveProblem, profile: BangBangProfile, order: int, rate_hz: float
) -> SampledProfile:
    """Fewest zero-order-hold samples keeping the robust constraints exactly (nominal model and derivatives).

    Samples away from the continuous switches keep the continuous level; a
    linear program sets those in windows around the switches (windows grow,
    then the sample count, until feasible); an exact least-norm correction
    follows and the result is checked by the augmented matrix-exponential
    simulation.  ``K_lo = ceil(T / dt)`` is a proved lower bound (every
    sequence is a continuous input), so ``minimal`` holds if ``K_lo`` works.
    """
    t0 = time.perf_counter()
    dt = 1.0 / rate_hz
    um = problem.u_max
    system = RobustModalResponse(problem.model, order, problem.include_position)
    xa0 = system.augment(problem.shifted_initial())
    T = profile.duration
    if T / dt > 5e6:
        raise FlexmotionError("rate_hz", f"a {T:.3g} s move at {rate_hz:g} Hz needs over 5e6 samples; lower the rate")
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
            free = np.convolve(near.astype(float), np.ones(2 * width + 1), mode="same") > 0.0
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
        xa = simulate_samples((system.A(), system.B()), xa0, cmds, dt)
        sa = np.max(np.abs(xa), axis=0)
        sa = np.where(sa > 0.0, sa, 1.0)
        rel_aug = float(np.max(np.abs(xa[-1]) / sa))
        states = simulate_samples(problem.model, problem.x0, cmds, dt)
        target = problem.model.rest_state(problem.target if problem.target is not None else 0.0)
        dev = states[-1] - target
        if problem.target is None:
            dev = dev[1:]
        if rel_aug <= FINAL_STATE_RTOL and np.max(np.abs(cmds)) <= um:
            return SampledProfile(
                problem,
                cmds,
                dt,
                states,
                float(np.max(np.abs(dev))),
                rel_aug,
                K == K_lo,
                K_lo,
                profile,
                time.perf_counter() - t0,
                "robust_time_optimal",
                {"augmented_final_state_error_relative": rel_aug},
            )
    raise SolverError(f"robust time-optimal: no sampled sequence at {rate_hz:g} Hz found; nothing is returned")
