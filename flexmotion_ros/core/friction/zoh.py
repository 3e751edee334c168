"""Zero-order-hold moves under rigid-body Coulomb friction (sampled linear programs).

The zero-order-hold version of :mod:`.friction_time_optimal` is a linear
program for a fixed pattern of velocity signs (reversals on sample instants):
:func:`plan_time_optimal_friction_zoh`.  Every sequence is checked by the exact
event-located friction simulation of :mod:`.friction`.
"""

from __future__ import annotations

import math
import time

import numpy as np
from scipy.optimize import linprog

from ..errors import GoalError, SolverError
from ..model.boundary import MoveProblem
from ..model.modal_model import check_positive
from ..results import SampledProfile
from ..simulation.exact import PiecewiseConstant
from ..simulation.prepared import PreparedMove, prepare
from ..tolerances import FINAL_STATE_RTOL
from .contact import ClosedForm, FrictionSystem, simulate_coulomb
from .time_optimal import (
    FrictionProfile,
    check_coulomb_force,
    plan_time_optimal_friction,
)


def _velocity_pattern(K: int, dt: float, first: int, reversals: np.ndarray, stretch: float) -> np.ndarray:
    """Sign of ``v`` on each sample interval, reversals (times ``stretch``) moved to the nearest instant."""
    s = np.full(K, float(first))
    for tc in reversals:
        j = round(tc * stretch / dt)
        if 0 < j < K:
            s[j:] *= -1.0
    return s


def _window(K: int, centres: np.ndarray, width: int) -> np.ndarray:
    free = np.zeros(K, dtype=bool)
    for c in centres:
        free[max(0, c - width) : min(K, c + width + 1)] = True
    free[:width] = True
    free[K - width :] = True
    return free


def _friction_lp(problem: MoveProblem, F: float, K: int, dt: float, s: np.ndarray, sigma: np.ndarray, free: np.ndarray):
    """Least-peak commands reaching rest in ``K`` samples for a fixed velocity-sign pattern ``s``.

    Samples outside ``free`` are held at ``sigma_k t`` (the continuous
    levels); the free ones and the peak ``t`` are the unknowns.  Minimise
    ``t`` subject to ``|u_k| <= t``, the final state at rest (the friction
    on interval ``k`` is the known ``-F s_k``) and the velocity signs
    ``s_k v_k >= 0``, ``s_k v_{k+1} >= 0`` at every instant (with ``c <= 0``,
    ``v`` is monotone on a sample, so it keeps its sign between instants too;
    where the pattern changes sign, ``v = 0``).  Returns ``(u, t, G, w)`` or
    None; ``G^T u = w`` is the full final-state condition.
    """
    model = problem.model
    n = model.n_states
    cf = ClosedForm(model)
    Phi, Gam, Gg = cf.steps(dt)
    resp = cf.resp
    m = np.arange(K)[::-1]  # samples to go after sample k
    G = resp.expm_x_many(dt * m, Gam)  # (K, n): effect of u_k on x_K
    Hf = resp.expm_x_many(dt * m, Gg)  # effect of the friction on interval k (times -F s_k)
    xf = model.rest_state(problem.target if problem.target is not None else 0.0)
    x0 = problem.x0 - xf
    I = np.arange(n) if problem.include_position else np.arange(1, n)
    w_full = -resp.expm_x(K * dt, x0) + F * (s @ Hf)
    G, w = G[:, I], w_full[I]
    Fi = np.flatnonzero(free)
    fixed = ~free
    nF = Fi.size
    # equality: G_F^T u_F + t G_fixed^T sigma = w
    A_eq = np.column_stack([G[Fi].T, (G[fixed] * sigma[fixed, None]).sum(axis=0)])
    # velocities at instants 1..K-1: v_j = a_j + Dv_j . (u_F, t), by the exact recursion
    ev, gv, fv = Phi[1, 1], Gam[1], Gg[1]
    a = np.empty(K + 1)
    vt = np.empty(K + 1)  # response to the fixed samples at unit peak
    a[0], vt[0] = x0[1], 0.0
    sig_fixed = np.where(fixed, sigma, 0.0)
    for k in range(K):
        a[k + 1] = ev * a[k] - F * fv * s[k]
        vt[k + 1] = ev * vt[k] + gv * sig_fixed[k]
    j = np.arange(1, K)[:, None]
    lag = j - 1 - Fi[None, :]
    Dv = np.column_stack([np.where(lag >= 0, gv * ev ** np.maximum(lag, 0), 0.0), vt[1:K]])
    a = a[1:K]
    left, right = s[:-1], s[1:]  # signs of the intervals either side of instant j
    change = left != right
    ub_v = np.vstack([-left[:, None] * Dv, -(right[change])[:, None] * Dv[change]])  # -s v_j <= 0
    b_v = np.concatenate([left * a, right[change] * a[change]])
    ub_u = np.zeros((2 * nF, nF + 1))
    ub_u[np.arange(nF), np.arange(nF)] = 1.0
    ub_u[nF + np.arange(nF), np.arange(nF)] = -1.0
    ub_u[:, -1] = -1.0
    cost = np.zeros(nF + 1)
    cost[-1] = 1.0
    res = linprog(
        cost,
        A_ub=np.vstack([ub_u, ub_v]),
        b_ub=np.concatenate([np.zeros(2 * nF), b_v]),
        A_eq=A_eq,
        b_eq=w,
        bounds=[(None, None)] * nF + [(0.0, None)],
        method="highs",
    )
    if res.status != 0:
        return None
    t = float(res.x[-1])
    u = sigma * t
    u[Fi] = res.x[:nF]
    return u, t, G, w


def plan_time_optimal_friction_zoh(
    problem: MoveProblem | PreparedMove,
    coulomb_force: float,
    rate_hz: float,
    continuous: FrictionProfile | None = None,
    max_extra: int = 50,
) -> SampledProfile:
    """Zero-order-hold commands at ``rate_hz`` reaching rest exactly under rigid-body friction.

    The velocity-sign pattern of the continuous friction extremal is kept,
    with each reversal moved to the nearest sample instant; for that pattern
    the problem is a linear program (:func:`_friction_lp`).  Sample counts
    from ``ceil(T / dt)`` up are tried until the least peak is within
    ``u_max``; the commands are then made exact (least-norm correction of
    :mod:`.zoh`) and checked by the exact event-located friction simulation.

    The check is the one every sampled sequence passes,
    :func:`~flexmotion_ros.core.sampled.check.verified_samples` (final state
    against the move's error scale, bound ``u_max``), with the friction
    simulation injected as its exact simulator.  Before it, a sample count is
    accepted only if the final state is also within ``FINAL_STATE_RTOL`` of the
    friction trajectory's own excursion (the criterion this planner always
    used, kept so that routing through the common check loosens nothing).
    ``rate_hz`` (Hz, ``> 0``) is checked here: this is a public entry point.

    Returns
    -------
    SampledProfile
        ``states`` from the friction simulation; ``minimal`` False (fewest
        only within the fixed pattern); ``lower_bound_samples`` from the
        proved rigid-body bound when there is one.

    Raises
    ------
    SolverError
        No sequence within ``max_extra`` samples of the continuous move passes
        the exact check.
    """
    from ..sampled.check import verified_samples
    from ..sampled.zoh import correct_exactly

    t0 = time.perf_counter()
    rate = check_positive("rate_hz", rate_hz, "Hz")
    dt = 1.0 / rate
    move = prepare(problem)  # the error scale of the common check (responses reused if prepared)
    problem = move.problem
    F = check_coulomb_force(coulomb_force, problem.u_max)
    if continuous is None:
        continuous = plan_time_optimal_friction(problem, F)
    T = continuous.duration
    model, um = problem.model, problem.u_max
    if T == 0.0:
        states = simulate_coulomb(model, problem.x0, PiecewiseConstant([0.0], []), F, [0.0])
        return SampledProfile(
            problem, np.empty(0), dt, states, 0.0, 0.0, True, 0, None, time.perf_counter() - t0, "time_optimal_friction"
        )
    if T / dt > 5e6:
        raise GoalError("rate_hz", f"a {T:.3g} s move at {rate:g} Hz needs over 5e6 samples; lower the rate")
    check = FrictionSystem.for_model(model, F)
    xf = model.rest_state(problem.target if problem.target is not None else 0.0)
    I = np.arange(model.n_states) if problem.include_position else np.arange(1, model.n_states)
    first = int(np.sign(model.b0 * continuous.levels[0])) if problem.x0[1] == 0.0 else int(np.sign(problem.x0[1]))
    lb = continuous.lower_bound
    lower = math.ceil(lb / dt * (1.0 - 1e-12)) if lb is not None else 0
    K = max(1, math.ceil(T / dt * (1.0 - 1e-12)))
    last_reason = "no feasible linear program"
    K0 = K
    for K in range(K0, K0 + max_extra + 1):
        sol = None
        stretch = K * dt / T
        mids = (np.arange(K) + 0.5) * dt / stretch
        sigma = np.sign(continuous.input()(mids))
        sigma[sigma == 0.0] = float(continuous.levels[-1] > 0) * 2.0 - 1.0
        centres = np.round(np.concatenate([continuous.switch_times, continuous.reversals]) * stretch / dt).astype(int)
        patterns = [_velocity_pattern(K, dt, first, continuous.reversals, stretch)]
        if continuous.reversals.size:
            patterns.append(np.full(K, float(first)))  # a sequence without reversal may exist too
        for s in patterns:
            for width in (4, 16, 64):
                cand = _friction_lp(problem, F, K, dt, s, sigma, _window(K, centres, width))
                if cand is not None and cand[1] <= um * (1.0 + 1e-12):
                    sol = cand
                    break
                if cand is not None:
                    last_reason = f"least peak {cand[1]:.6g} > u_max"
            if sol is not None:
                break
        if sol is None:
            continue
        u, _t_star, G, w = sol
        # exact final state for this pattern (the friction term is a constant of w)
        u = correct_exactly(G, w, u, um)
        if u is None:
            continue
        states = check.run(problem.x0, PiecewiseConstant.from_samples(u, dt), dt * np.arange(K + 1)).states
        dev = (states[-1] - xf)[I]
        sc = np.max(np.abs(states - xf), axis=0)[I]
        sc = np.where(sc > 0.0, sc, 1.0)
        rel = float(np.max(np.abs(dev) / sc))
        if rel <= FINAL_STATE_RTOL and np.max(np.abs(u)) <= um:
            extra = {"coulomb_force": F, "peak_command": float(np.max(np.abs(u))), "extra_samples": K - K0}
            try:  # the one exact sampled check, with the friction simulation injected
                return verified_samples(
                    move,
                    u,
                    dt,
                    "time_optimal_friction",
                    K == lower,
                    lower,
                    None,
                    extra,
                    t0,
                    simulator=lambda _cmds, _dt, states=states: states,
                )
            except SolverError as exc:
                last_reason = str(exc)
                continue
        last_reason = f"exact friction simulation misses the target (relative error {rel:.2e})"
    raise SolverError(
        f"sampled friction planner: no sequence within {max_extra} samples of the continuous move ({last_reason})"
    )
