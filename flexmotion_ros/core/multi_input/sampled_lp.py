"""The stacked least-peak linear program of one decoupled part at a fixed rate, and the exact check.

Shared by the sampled multi-input planners (:mod:`.zoh`, :mod:`.fixed_time`,
:mod:`.fuel`, :mod:`.shaped`).  See :mod:`.zoh` for the method.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..errors import SolverError
from ..sampled.zoh import correct_exactly, dual_bound, solve_peak_lp, window_mask
from ..tolerances import BOUND_RTOL, FINAL_STATE_RTOL, LP_RTOL
from .dual import multi_state_scale
from .exact import simulate_samples, system_of
from .parts import PartSolution
from .response import MultiResponse
from .results import MultiSampledProfile, SyncMode

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
        """Signs of the continuous switching functions at the sample midpoints (samples to go), and the values.

        Inputs set by a later stage (singular for the part's co-state) take
        their signs from that stage's co-state.
        """
        tau = (np.arange(K) + 0.5) * self.dt
        S = self.resp.switching_all(self.part.nu, tau)[0]  # (m, K)
        for st in self.part.extra.get("stages", [])[1:]:
            S_st = self.resp.switching_all(st["nu"], tau)[0]
            S[st["inputs"]] = S_st[st["inputs"]]
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


def finish_samples(
    problem, commands, dt, minimal, lower, proof, bound, continuous, t0, extra, method: str = "time_optimal"
) -> MultiSampledProfile:
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
        sync=continuous.sync if continuous is not None else SyncMode.TIME,
        method=method,
        solve_time_s=time.perf_counter() - t0,
        extra=extra,
    )
