"""Exact zero-order-hold optimum with ``m`` inputs at a fixed rate, and the proof that one sample fewer cannot work.

A node streams rows ``u_k = (u_1k, ..., u_mk)``, each held for ``dt``.  With
``g_{i,j} = e^{A j dt} Gamma_i(dt)`` (``j`` samples to go) the final state is
zero iff ``sum_{i,j} g_{i,j} u_{i,j} = w_K := -e^{A K dt} x0``.  Per decoupled
part, the linear program::

    t*(K) = min t   s.t.   sum g_{i,j} u_{i,j} = w_K,   |u_{i,j}| <= t u_max_i

is the least peak fraction arriving in ``K`` samples: ``K`` is feasible iff
``t*(K) <= 1`` (monotone in ``K``: hold zero after arriving).  It is the
single-input LP of :mod:`~flexmotion_ros.core.sampled.zoh` with the rows of
every input stacked (scaled by ``u_max_i``), solved with the same windows
around the continuous switches and the same dual test (any ``nu`` gives
``t*(K) >= nu^T w_K / sum |nu^T u_max_i g_{i,j}|``; above 1 proves ``K``
infeasible).  Lower bound: ``K dt >= T*`` (the certified continuous optimum).

The parts that do not set the sample count follow ``sync`` as the continuous
plan does: ``time``, the lowest peak at exactly ``K`` samples (the same LP at
fixed ``K``); ``none``, their own fewest samples, then zeros; ``phase``, the
single-input path problem's ZOH optimum times the input direction.  The
sequence is checked by exact matrix-exponential simulation of the full model.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..errors import GoalError, SolverError
from ..model.modal_model import check_positive
from ..sampled.zoh import correct_exactly, dual_bound, plan_time_optimal_zoh, solve_peak_lp, window_mask
from ..tolerances import BOUND_RTOL, FINAL_STATE_RTOL, GAP_RTOL, LP_RTOL, MAX_SAMPLES
from .dual import multi_state_scale
from .exact import simulate_samples, system_of
from .parts import PartSolution
from .problem import MultiMoveProblem
from .response import MultiResponse
from .results import MultiProfile, MultiSampledProfile, PartRole, SyncMode
from .time_optimal import plan_multi_time_optimal

MAX_EXTRA_SAMPLES = 200


@dataclass
class PartSamples:
    """One part's sequence: ``commands`` ``(K, m_part)`` (N), the fewest-samples proof."""

    commands: np.ndarray
    peak_fraction: float
    lower_bound_samples: int
    proof: str
    dual_bound: float


class PartLP:
    """The stacked sample vectors of one part (rows ``u_max_i g_{i,j} / s``, input-major)."""

    def __init__(self, part: PartSolution, dt: float, T_ref: float) -> None:
        self.part = part
        self.resp = MultiResponse(part.problem)
        self.x0 = part.problem.shifted_initial()
        self.U = part.problem.u_max
        self.dt = dt
        self.s = multi_state_scale(self.resp, self.x0, self.U, max(T_ref, dt))
        self.gam = self.resp.input_integral(np.array([dt]))[0]  # (n, m)
        self._rows: np.ndarray | None = None

    def rows(self, K: int) -> np.ndarray:
        """``(m K, n)``: row ``i K + j`` is ``u_max_i g_{i,j} / s``."""
        if self._rows is None or self._rows.shape[0] < K:
            Kc = max(K, 2 * (0 if self._rows is None else self._rows.shape[0]))
            tau = self.dt * np.arange(Kc)
            self._rows = np.stack(
                [self.U[i] * self.resp.expm_x_many(tau, self.gam[:, i]) / self.s for i in range(self.resp.m)]
            )  # (m, Kc, n)
        return self._rows[:, :K, :].reshape(self.resp.m * K, self.resp.n)

    def target(self, K: int) -> np.ndarray:
        return -self.resp.expm_x(K * self.dt, self.x0) / self.s

    def signs(self, K: int) -> np.ndarray:
        S = self.resp.switching_all(self.part.nu, (np.arange(K) + 0.5) * self.dt)[0]  # (m, K)
        return np.where(S >= 0.0, 1.0, -1.0), S

    def solve(self, K: int, nu_hint: np.ndarray | None = None):
        """``(u, t*, dual bound, nu)`` of the LP at ``K`` samples (windows grown until decided), or None."""
        G = self.rows(K)
        w = self.target(K)
        if nu_hint is None:
            signs, S = self.signs(K)
        else:
            S = (G @ nu_hint).reshape(self.resp.m, K)
            signs = np.where(S >= 0.0, 1.0, -1.0)
        width = 4
        while True:
            free = np.concatenate([window_mask(S[i], width) for i in range(self.resp.m)]) if width < K else None
            if free is None:
                free = np.ones(G.shape[0], dtype=bool)
            sol = solve_peak_lp(G, w, signs.ravel(), free)
            if sol is not None:
                u, t_star, nu = sol
                bound = dual_bound(G, w, nu)
                if t_star <= 1.0 + LP_RTOL or bound > 1.0 + BOUND_RTOL or free.all():
                    return u, t_star, bound, nu
            if free.all():
                return None
            width *= 4

    def exact(self, K: int, u: np.ndarray, t_star: float) -> np.ndarray | None:
        """Commands ``(K, m)`` (N) reaching the target exactly, or None."""
        G = self.rows(K)
        w = self.target(K)
        u_in = u * (1.0 / max(t_star, 1.0))
        for cand in (correct_exactly(G, w, u_in, 1.0), np.clip(u_in, -1.0, 1.0)):
            if cand is not None and np.max(np.abs(G.T @ cand - w)) <= 1e-12 * max(float(np.max(np.abs(w))), 1.0):
                cmds = cand.reshape(self.resp.m, K)[:, ::-1].T * self.U  # samples to go -> forward
                return np.clip(cmds, -self.U, self.U)
        return None


def fewest_samples(part: PartSolution, dt: float, T_lower: float) -> PartSamples:
    """The fewest samples that bring the part exactly to rest, with the proof for one fewer.

    ``T_lower``: a proved lower bound on the part's minimum time (s), or 0:
    every ``K`` with ``K dt <= T_lower`` is infeasible.
    """
    lp = PartLP(part, dt, part.T)
    K_lo = max(1, math.ceil(part.T / dt * (1.0 - 1e-12)))
    proved_below, proof, bound_km1 = 1, "", math.nan  # every K < proved_below is proved infeasible
    if T_lower > 0.0:
        proved_below, proof = max(1, math.floor(T_lower / dt) + 1), "continuous"
    K = K_lo
    nu = None
    while K <= K_lo + MAX_EXTRA_SAMPLES:
        res = lp.solve(K, nu)
        if res is None:
            K += 1
            continue
        u, t_star, bound, nu = res
        if t_star <= 1.0 + LP_RTOL:
            cmds = lp.exact(K, u, t_star)
            if cmds is not None:
                if proved_below < K and K > 1:
                    # prove K - 1 infeasible: the LP at K - 1, its dual bound over every sample
                    prev = lp.solve(K - 1, nu)
                    if prev is not None and prev[2] > 1.0 + BOUND_RTOL:
                        proved_below, proof, bound_km1 = K, "dual", float(prev[2])
                return PartSamples(cmds, float(min(t_star, 1.0)), proved_below, proof, bound_km1)
        if bound > 1.0 + BOUND_RTOL:
            proved_below, proof, bound_km1 = K + 1, "dual", float(bound)
        K += 1
    raise SolverError(f"multi-input sampled planner: no feasible sequence within {MAX_EXTRA_SAMPLES} samples of T*")


def lowest_peak_samples(part: PartSolution, dt: float, K: int) -> PartSamples:
    """The lowest peak fraction that brings the part exactly to rest in exactly ``K`` samples."""
    lp = PartLP(part, dt, K * dt)
    res = lp.solve(K)
    if res is None or res[1] > 1.0 + LP_RTOL:
        raise SolverError(f"multi-input sampled planner: the lowest-peak LP at {K} samples failed")
    u, t_star, bound, _ = res
    cmds = lp.exact(K, u, t_star)
    if cmds is None:
        raise SolverError(f"multi-input sampled planner: no exact lowest-peak sequence at {K} samples")
    return PartSamples(cmds, float(t_star), 0, "", float(bound))


def plan_multi_time_optimal_zoh(
    problem: MultiMoveProblem,
    rate_hz: float,
    continuous: MultiProfile | None = None,
    sync: str | SyncMode = SyncMode.TIME,
) -> MultiSampledProfile:
    """Fewest zero-order-hold samples at ``rate_hz`` that bring every part exactly to rest.

    Parameters
    ----------
    problem : MultiMoveProblem
    rate_hz : float
        Command rate (Hz), ``> 0``.
    continuous : MultiProfile, optional
        The certified continuous plan of ``problem`` with the same ``sync``.
    sync : {"time", "none", "phase"}

    Returns
    -------
    MultiSampledProfile
        ``minimal`` when ``samples - 1`` is proved infeasible (``proof``).

    Raises
    ------
    SolverError
        If no sequence passes the exact final-state and bound checks.
    """
    t0 = time.perf_counter()
    rate = check_positive("rate_hz", rate_hz, "Hz")
    dt = 1.0 / rate
    if continuous is None:
        continuous = plan_multi_time_optimal(problem, sync)
    mode = continuous.sync
    if continuous.duration / dt > MAX_SAMPLES:
        raise GoalError(
            "rate_hz", f"a {continuous.duration:.3g} s move at {rate:g} Hz needs over {MAX_SAMPLES} samples"
        )
    m = problem.model.m
    if continuous.duration == 0.0:
        return _finish(problem, np.zeros((0, m)), dt, True, 0, "at rest", math.nan, continuous, t0, {})
    if mode is SyncMode.PHASE:
        path = continuous.extra["path_problem"]
        d = continuous.extra["path_direction"]
        sp = plan_time_optimal_zoh(path, rate, continuous=continuous.extra["path_profile"])
        cmds = np.clip(np.outer(sp.commands, d), -problem.u_max, problem.u_max)
        return _finish(
            problem,
            cmds,
            dt,
            sp.minimal,
            sp.lower_bound_samples,
            "path (single-input ZOH optimum)",
            math.nan,
            continuous,
            t0,
            {},
        )
    parts: list[PartSolution] = continuous.extra["part_solutions"]
    roles: list[PartRole] = continuous.extra["part_roles"]
    lower = {id(p): float(s.get("lower_bound", 0.0)) for p, s in zip(parts, continuous.certificate.parts)}
    own: dict[int, PartSamples] = {}
    for p, role in zip(parts, roles):
        if role in (PartRole.CRITICAL, PartRole.OWN_OPTIMUM):
            own[id(p)] = fewest_samples(p, dt, lower.get(id(p), 0.0) if continuous.certified else 0.0)
    critical = [own[id(p)] for p, r in zip(parts, roles) if r is PartRole.CRITICAL]
    K = max((s.commands.shape[0] for s in own.values()), default=0)
    info = []
    for _ in range(MAX_EXTRA_SAMPLES):
        out = np.zeros((K, m))
        info.clear()
        try:
            for p, role in zip(parts, roles):
                if role is PartRole.AT_REST:
                    continue
                ps = own.get(id(p))
                if role is PartRole.LOWEST_PEAK or (ps.commands.shape[0] < K and mode is SyncMode.TIME):
                    ps = lowest_peak_samples(p, dt, K)
                out[: ps.commands.shape[0], list(p.inputs)] = ps.commands
                info.append(
                    {
                        "inputs": [problem.model.inputs[i] for i in p.inputs],
                        "samples": ps.commands.shape[0],
                        "peak_fraction": ps.peak_fraction,
                    }
                )
            break
        except SolverError:  # a lowest-peak part needs more samples than the critical one (near tie)
            K += 1
    best = max(critical, key=lambda s: s.lower_bound_samples) if critical else None
    minimal = best is not None and best.lower_bound_samples >= K
    return _finish(
        problem,
        out,
        dt,
        minimal,
        best.lower_bound_samples if best else 0,
        best.proof if best else "",
        best.dual_bound if best else math.nan,
        continuous,
        t0,
        {"parts": info},
    )


def _finish(problem, commands, dt, minimal, lower, proof, bound, continuous, t0, extra) -> MultiSampledProfile:
    """Exact check of the whole sequence (full model, matrix exponentials) and the bound."""
    A, B = system_of(problem.model)
    states = simulate_samples(A, B, problem.x0, commands, dt)
    dev = (states[-1] - problem.target_state())[problem.kept]
    resp = MultiResponse(problem)
    scale = multi_state_scale(resp, problem.shifted_initial(), problem.u_max, max(commands.shape[0] * dt, dt))
    err = float(np.max(np.abs(dev))) if dev.size else 0.0
    rel = float(np.max(np.abs(dev) / scale)) if dev.size else 0.0
    if not rel <= FINAL_STATE_RTOL:
        raise SolverError(
            f"multi-input sampled sequence misses the target (relative final-state error {rel:.3e}); nothing is returned"
        )
    if commands.size and np.any(np.abs(commands) > problem.u_max):
        raise SolverError("multi-input sampled command exceeds u_max; nothing is returned")
    return MultiSampledProfile(
        problem=problem,
        commands=commands,
        dt=dt,
        states=states,
        final_state_error=err,
        final_state_error_relative=rel,
        minimal=bool(minimal),
        lower_bound_samples=int(lower),
        proof=proof,
        dual_bound=float(bound),
        continuous=continuous,
        sync=continuous.sync,
        solve_time_s=time.perf_counter() - t0,
        extra=extra,
    )


__all__ = ["GAP_RTOL", "plan_multi_time_optimal_zoh"]
