"""Input shaping on a multi-input model: the same shaper applied to every input.

The rigid bodies alone (the model without its modes) get their certified
minimum-time multi-input move; every input's command is convolved with one
shaper designed for all the model's modes.  The shaper cancels each mode
whatever ``B`` is: mode ``l`` is driven by ``sum_i b[l, i] (A * u_i) =
A * (sum_i b[l, i] u_i)``, a shaped signal.  With ``sum A_j = 1`` the rigid
bodies end where the unshaped command leaves them, at rest.  Positive
shapers keep every ``|u_i| <= u_max_i``; shapers with negative impulses get a
lowered rigid-body bound until they do (:func:`~flexmotion_ros.core.shaping.shaped_profile.largest_level`).

Only from rest (shaping cannot cancel vibration already present, and a moving
start would shift the rigid bodies' arrival); refused otherwise.  The sampled
version (:func:`sample_profile`) averages every input over each sample and
removes the remaining final-state error with a least-norm change of the
samples with slack; it is checked by exact simulation.  Neither claims
optimality.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..errors import GoalError, SolverError
from ..sampled.lp_tools import least_norm_correction
from ..sampled.zoh import correct_exactly
from ..shaping.shaped_profile import largest_level, shape
from ..shaping.shapers import Shaper
from ..simulation.exact import PiecewiseConstant
from ..tolerances import FINAL_STATE_RTOL
from .assembly import check_final_state
from .dual import multi_state_scale
from .exact import VectorPiecewise, simulate, simulate_samples, system_of
from .model import MultiModel
from .problem import MultiMoveProblem
from .response import MultiResponse
from .results import MultiCertificate, MultiProfile, MultiSampledProfile, SyncMode
from .time_optimal import plan_multi_time_optimal


def unique_modes(model: MultiModel) -> tuple[list[float], list[float]]:
    """Design frequencies (rad/s) and damping ratios: one per distinct eigenvalue."""
    groups = model.mode_groups()
    return [model.omega[g[0]] for g in groups], [model.zeta[g[0]] for g in groups]


def rigid_only(problem: MultiMoveProblem, scale: float) -> tuple[MultiMoveProblem, list[int]]:
    """The rigid bodies alone, driven by the inputs that reach them (bounds times ``scale``)."""
    model = problem.model
    used = [i for i in range(model.m) if np.any(model.B0[:, i])]
    sub = MultiModel(
        inputs=tuple(model.inputs[i] for i in used),
        rigid_bodies=model.rigid_bodies,
        b0=tuple(tuple(model.B0[j, i] for i in used) for j in range(model.k)),
        c=model.c,
    )
    x0 = problem.x0[: 2 * model.k]
    return MultiMoveProblem(sub, problem.u_max[used] * scale, x0, problem.targets), used


def _no_claim(problem: MultiMoveProblem, message: str) -> MultiCertificate:
    return MultiCertificate(
        passed=False,
        costate_initial=np.zeros(problem.kept.size),
        switch_residual=math.nan,
        extra_zeros=0,
        unproved_cells=0,
        sign_consistent=False,
        hamiltonian_spread=math.nan,
        lower_bound=0.0,
        duality_margin=0.0,
        message=message,
    )


def plan_multi_shaped(problem: MultiMoveProblem, shaper: Shaper, method: str = "shaped") -> MultiProfile:
    """Shape the rigid bodies' minimum-time move with ``shaper`` on every input; ``|u_i| <= u_max_i`` always.

    Raises
    ------
    GoalError
        Not at rest at the start.
    SolverError
        The exact final state misses (nothing is returned).
    """
    t0 = time.perf_counter()
    model = problem.model
    if np.any(problem.x0[1 : 2 * model.k : 2]) or np.any(problem.x0[2 * model.k :]):
        raise GoalError(
            "initial_state",
            f"method {method} on a multi-input model needs the machine at rest at the start "
            "(shaping cannot cancel vibration already present); use time_optimal",
        )
    m = model.m
    if problem.is_at_rest():
        zero = [np.empty(0)] * m
        xT, err, rel = check_final_state(problem, zero, [np.zeros(1)] * m, 0.0)
        return MultiProfile(
            problem=problem,
            switch_times=tuple(zero),
            levels=tuple([np.zeros(1)] * m),
            duration=0.0,
            final_state=xT,
            final_state_error=err,
            final_state_error_relative=rel,
            certificate=_no_claim(problem, "already at rest"),
            method=method,
        )

    def shaped_at(level: float):
        base_problem, used = rigid_only(problem, level)
        base = plan_multi_time_optimal(base_problem)
        cmds = []
        for a in range(len(used)):
            u = PiecewiseConstant.from_switches(base.switch_times[a], base.levels[a], base.duration)
            cmds.append(shape(u, shaper))
        peak = max(c.max_abs() / problem.u_max[i] for c, i in zip(cmds, used))
        return peak, (base, cmds, used)

    level, (base, cmds, used) = largest_level(shaped_at, 1.0, 1.0 / shaper.abs_sum)
    T = max(c.duration for c in cmds)
    switch_times: list = [np.empty(0)] * m
    levels: list = [np.zeros(1)] * m
    for c, i in zip(cmds, used):
        b = c.breaks
        sw = b[1:-1]
        lv = np.clip(c.levels, -problem.u_max[i], problem.u_max[i])
        if c.duration < T:
            sw, lv = np.append(b[1:], []), np.append(lv, 0.0)
        switch_times[i], levels[i] = sw, lv
    xT, err, rel = check_final_state(problem, switch_times, levels, T, rigid_only=True)
    k = model.k
    q, qd = xT[2 * k :: 2], xT[2 * k + 1 :: 2]
    w = np.asarray(model.omega)
    sig = w * np.asarray(model.zeta)
    residual = np.hypot(q, (qd + sig * q) / model.omega_d) if model.n_modes else np.zeros(0)
    return MultiProfile(
        problem=problem,
        switch_times=tuple(switch_times),
        levels=tuple(levels),
        duration=float(T),
        final_state=xT,
        final_state_error=err,
        final_state_error_relative=rel,
        certificate=_no_claim(problem, f"input-shaped ({shaper.name}): no optimality claim"),
        sync=SyncMode.TIME,
        method=method,
        solve_time_s=time.perf_counter() - t0,
        extra={
            "shaper": shaper.to_dict(),
            "rigid_level": float(level),
            "rigid_duration": float(base.duration),
            "residual_amplitude": [float(v) for v in residual],  # per mode, modal coordinate
        },
    )


def sample_profile(problem: MultiMoveProblem, profile: MultiProfile, rate_hz: float) -> MultiSampledProfile:
    """A continuous profile at ``rate_hz``: per-sample averages, made exact by a least-norm correction.

    The averages of values within the bounds stay within them; the correction
    moves only samples with slack.  Checked by exact simulation; no minimality claim.
    """
    t0 = time.perf_counter()
    dt = 1.0 / float(rate_hz)
    if profile.duration == 0.0:  # nothing to do: no sample
        return _checked(problem, np.zeros((0, problem.model.m)), dt, profile, t0, np.zeros(problem.kept.size))
    u = profile.input()
    resp = MultiResponse(problem)
    x0 = problem.shifted_initial()
    U = problem.u_max
    K = max(1, math.ceil(profile.duration / dt * (1.0 - 1e-12)))
    # the sequence must reach what the continuous profile reaches (a designed residual vibration included)
    A, B = system_of(problem.model)
    x_end = simulate(A, B, problem.x0, u, times=[profile.duration])[0]
    for _ in range(20):
        avg = _averages(u, dt, K)  # (K, m)
        s = multi_state_scale(resp, x0, U, K * dt)
        gam = resp.input_integral(np.array([dt]))[0]
        tau = dt * np.arange(K)
        G = np.concatenate([U[i] * resp.expm_x_many(tau, gam[:, i]) / s for i in range(resp.m)])  # samples to go
        # target: the continuous end state, carried on with zero input to K dt
        end = resp.expm_x(K * dt - profile.duration, (x_end - problem.target_state())[problem.kept])
        w = (end - resp.expm_x(K * dt, x0)) / s
        v = (avg[::-1] / U).T.ravel()  # fractions, input-major, samples to go
        if G.shape[0] < G.shape[1]:  # fewer commands than states: no exact correction yet
            K += 1
            continue
        # slack-weighted least-norm change (samples at the bound stay), else the plain least-norm one
        for fixed in (least_norm_correction(G, w, v, 1.0), correct_exactly(G, w, v, 1.0)):
            if fixed is not None and np.max(np.abs(G.T @ fixed - w)) <= 1e-12 * max(float(np.max(np.abs(w))), 1.0):
                cmds = np.clip(fixed.reshape(resp.m, K)[:, ::-1].T * U, -U, U)
                return _checked(problem, cmds, dt, profile, t0, end)
        K += 1
    raise SolverError(f"{profile.method}: no exact sampled sequence at {rate_hz:g} Hz; nothing is returned")


def _averages(u: VectorPiecewise, dt: float, K: int) -> np.ndarray:
    edges = dt * np.arange(K + 1)
    pts = np.unique(np.concatenate([edges, u.breaks[(u.breaks > 0) & (u.breaks < K * dt)]]))
    vals = u(0.5 * (pts[:-1] + pts[1:]))
    integ = np.vstack([np.zeros((1, vals.shape[1])), np.cumsum(vals * np.diff(pts)[:, None], axis=0)])
    at = np.array([integ[np.searchsorted(pts, e)] for e in edges])
    return np.diff(at, axis=0) / dt


def _checked(problem, cmds, dt, profile, t0, end) -> MultiSampledProfile:
    A, B = system_of(problem.model)
    states = simulate_samples(A, B, problem.x0, cmds, dt)
    dev = (states[-1] - problem.target_state())[problem.kept] - end
    scale = multi_state_scale(MultiResponse(problem), problem.shifted_initial(), problem.u_max, cmds.shape[0] * dt)
    rel = float(np.max(np.abs(dev) / scale)) if dev.size else 0.0
    if not rel <= FINAL_STATE_RTOL or np.any(np.abs(cmds) > problem.u_max):
        raise SolverError(f"{profile.method}: sampled sequence misses the target or the bound; nothing is returned")
    return MultiSampledProfile(
        problem=problem,
        commands=cmds,
        dt=dt,
        states=states,
        final_state_error=float(np.max(np.abs(dev))) if dev.size else 0.0,
        final_state_error_relative=rel,
        minimal=False,
        lower_bound_samples=0,
        proof="",
        continuous=profile,
        sync=profile.sync,
        method=profile.method,
        solve_time_s=time.perf_counter() - t0,
    )
