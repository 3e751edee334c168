"""Solving one decoupled part of a multi-input move: minimum time, or lowest peak at a fixed time.

A part (:func:`decoupled_parts`) is a
set of inputs with the rigid bodies and modes they reach.  Its minimum time
comes from the convex dual of :mod:`.dual` (smoothed warm start, bracketed
Newton on ``T``), then Newton on every input's switch times
(:mod:`.newton`).  The lowest peak that arrives exactly at a given ``T`` is
the same problem with the peak fraction ``rho`` unknown instead of ``T``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import SolverError
from ..model.modal_model import ModalModel
from ..time_optimal.rigid_body import rigid_profile
from ..tolerances import AT_REST, GAP_RTOL
from .dual import FINER, multi_state_scale, smoothed_time
from .exact import system_of
from .model import MultiModel
from .newton import Extremal, Setting, signs_of
from .problem import MultiMoveProblem
from .response import MultiResponse
from .singular import (
    min_time_at_rigid_bound,
    min_time_near_rigid_bound,
    min_time_with_singular,
    near_singular_candidates,
    peak_stages,
    singular_inputs,
)
from .structure import structure_newton


def decoupled_parts(model: MultiModel) -> list[tuple[tuple[int, ...], tuple[int, ...], tuple[int, ...]]]:
    """The model's decoupled parts: ``(inputs, rigid bodies, modes)`` index tuples.

    Two inputs belong to one part when some rigid body or mode is reached by
    both (a non-zero gain), transitively.  Parts move independently: each has
    its own minimum time, and the inputs of a part that does not set the
    move's time are free within it (``sync``).
    """
    B0, Bm = model.B0, model.Bm
    parent = list(range(model.m))

    def find(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for row in list(B0) + list(Bm):
        hit = np.flatnonzero(row)
        for i in hit[1:]:
            parent[find(int(i))] = find(int(hit[0]))
    roots = sorted({find(i) for i in range(model.m)})
    out = []
    for r in roots:
        inputs = tuple(i for i in range(model.m) if find(i) == r)
        bodies = tuple(j for j in range(model.k) if np.any(B0[j, list(inputs)]))
        modes = tuple(l for l in range(model.n_modes) if np.any(Bm[l, list(inputs)]))
        out.append((inputs, bodies, modes))
    return out


def mode_free_push(model: MultiModel) -> bool:
    """Whether some combination of the inputs moves the rigid bodies while its drives on every mode cancel.

    Such moves are degenerate for the switch-time Newton (switches coincide, a
    family of co-states): the one physical trait shared by the moves it still
    refuses (issue 15), named in the refusal.
    """
    B0, Bm = model.B0, model.Bm
    if not B0.size or not np.any(B0):
        return False
    if not Bm.size:
        return False
    _, sv, vt = np.linalg.svd(Bm)
    rank = int(np.count_nonzero(sv > 1e-12 * float(sv[0]))) if sv.size else 0
    null = vt[rank:]  # combinations with no drive on any mode
    return bool(null.size) and float(np.max(np.abs(B0 @ null.T))) > 1e-9 * float(np.max(np.abs(B0)))


@dataclass
class PartSolution:
    """One part's extremal (forward time).

    Attributes
    ----------
    inputs, bodies, modes : tuple of int
        Indices in the whole model.
    problem : MultiMoveProblem
        The part's own move.
    T : float
        Its duration (s).
    rho : float
        Peak fraction: each input at ``rho u_max_i`` (1 for a minimum-time part).
    nu : ndarray
        ``-lambda(T)`` (reduced part state), any positive scale.
    switch_times, levels : list of ndarray
        Per input of the part.
    """

    inputs: tuple
    bodies: tuple
    modes: tuple
    problem: MultiMoveProblem
    T: float
    rho: float
    nu: np.ndarray
    switch_times: list
    levels: list
    extra: dict = field(default_factory=dict)

    @property
    def response(self) -> MultiResponse:
        return MultiResponse(self.problem)

    def system(self) -> tuple[np.ndarray, np.ndarray]:
        """``(A, B)`` of the part's reduced state (full matrices, for the exact checks)."""
        return system_of(self.problem.model, self.problem.kept)


def rigid_lower_bound(problem: MultiMoveProblem) -> float:
    """A proved lower bound on the part's minimum time (s): each rigid body alone with all inputs pushing it.

    Rigid body ``j`` cannot accelerate faster than ``sum_i |b0[j, i]| u_max_i``;
    its single-input time-optimal move at that bound (closed form) is a lower bound.
    """
    model = problem.model
    x = problem.x0 - problem.target_state()
    best = 0.0
    for j in range(model.k):
        a = float(np.abs(model.B0[j]) @ problem.u_max)
        rb = ModalModel(b0=a, c=model.c[j])
        has = problem.targets[j] is not None
        xj = np.array([x[2 * j], x[2 * j + 1]]) if has else np.array([x[2 * j + 1]])
        best = max(best, rigid_profile(rb, 1.0, xj, has).duration)
    return best


def parallel_groups(problem: MultiMoveProblem) -> list[list[tuple[int, float]]]:
    """Inputs with parallel columns of ``B`` grouped: ``[(j, alpha_j), ...]`` with ``B_j = alpha_j B_rep``.

    Parallel inputs act as one: ``sum_j B_j u_j = B_rep sum_j alpha_j u_j``, with
    the bound ``sum_j |alpha_j| u_max_j``; their switching functions are
    proportional, so they switch together.
    """
    B = problem.model.B()
    groups: list[list[tuple[int, float]]] = []
    for j in range(B.shape[1]):
        for g in groups:
            r = B[:, g[0][0]]
            alpha = float(B[:, j] @ r) / float(r @ r)
            if np.max(np.abs(B[:, j] - alpha * r)) <= 1e-12 * float(np.max(np.abs(B[:, j]))):
                g.append((j, alpha))
                break
        else:
            groups.append([(j, 1.0)])
    return groups


def merged_problem(problem: MultiMoveProblem, groups) -> MultiMoveProblem:
    """The same move with each group of parallel inputs as one input (its representative)."""
    model = problem.model
    reps = [g[0][0] for g in groups]
    sub = model.submodel(reps, range(model.k), range(model.n_modes))
    bound = [sum(abs(a) * problem.u_max[j] for j, a in g) for g in groups]
    return MultiMoveProblem(sub, bound, problem.x0, problem.targets)


def split_levels(groups, switch_times: list, levels: list, u_max: np.ndarray, m: int) -> tuple[list, list]:
    """Per-input switch times and levels from the merged solution (``u_j = sgn(alpha_j) u_max_j s(t)``)."""
    sw_out: list = [None] * m
    lv_out: list = [None] * m
    for g, sw, lv in zip(groups, switch_times, levels):
        U_rep = sum(abs(a) * u_max[j] for j, a in g)
        for j, a in g:
            sw_out[j] = sw
            lv_out[j] = np.asarray(lv, float) * (np.sign(a) * u_max[j] / U_rep)
    return sw_out, lv_out


def _at_rest(x0: np.ndarray) -> bool:
    return not np.any(np.abs(x0) > AT_REST)


def _forward(ext: Extremal, u_max: np.ndarray, rho: float) -> tuple[list, list]:
    sw, lv = [], []
    for i, (r, s0) in enumerate(zip(ext.roots, ext.sign0)):
        sw.append(np.clip(np.sort(ext.T - r), 0.0, ext.T))
        lv.append(rho * u_max[i] * signs_of(s0, r.size)[::-1])
    return sw, lv


def _combine(T: float, u_max: np.ndarray, stages: list, s: np.ndarray) -> tuple[list, list, list]:
    """Per-input forward switch times and levels from stages ``(inputs, roots, sign0, rho, nuh)``; stage summaries."""
    m = u_max.size
    sw: list = [np.empty(0)] * m
    lv: list = [np.zeros(1)] * m
    info = []
    for inputs, roots, sign0, rho, nuh in stages:
        for i in inputs:
            sw[i] = np.clip(np.sort(T - roots[i]), 0.0, T)
            lv[i] = rho * u_max[i] * signs_of(sign0[i], roots[i].size)[::-1]
        info.append({"inputs": [int(i) for i in inputs], "rho": float(rho), "nu": nuh / s})
    return sw, lv, info


def zero_part(indices, problem: MultiMoveProblem) -> PartSolution:
    """A part already at rest: nothing to do."""
    n = problem.kept.size
    m = problem.model.m
    return PartSolution(
        *indices, problem, 0.0, 0.0, np.zeros(n), [np.empty(0)] * m, [np.zeros(1)] * m, {"at_rest": True}
    )


def _with_singular(resp: MultiResponse, x0, U, s, nuh, T: float, J: list[int] | None):
    """``(extremal, stages)`` with the inputs ``J`` singular, or None if Newton fails or ``J`` would exceed its bound.

    ``J = None``: the rigid-body bound hypothesis (:func:`~.singular.min_time_at_rigid_bound`).
    A ``J`` that needs a peak above 1 was only nearly singular (the optimal
    co-state sees it after all): the caller goes on with the plain extremal.
    """
    try:
        if J is None:
            out = min_time_at_rigid_bound(resp, x0, U, s, nuh, T)
        else:
            out = min_time_with_singular(resp, x0, U, s, nuh, T, J)
    except SolverError:
        return None
    if out is None or not all(st.rho <= 1.0 + 1e-9 for st in out[1]):
        return None
    ext, stages = out
    if J is None:
        J = [i for i in range(resp.m) if not np.any(resp.B0[:, i])]
    C = [i for i in range(resp.m) if i not in J]
    return (
        ext,
        [(C, ext.roots, ext.sign0, 1.0, ext.nuh)]
        + [(st.inputs, st.roots, st.sign0, min(st.rho, 1.0), st.nuh) for st in stages],
    )


def _solve_min_time(indices, problem: MultiMoveProblem) -> PartSolution:
    """Minimum-time extremal of one part (not yet checked: the caller certifies)."""
    resp = MultiResponse(problem)
    x0 = problem.shifted_initial()
    U = problem.u_max
    if _at_rest(x0):
        return zero_part(indices, problem)
    T_low = rigid_lower_bound(problem)
    w_min = min(problem.model.omega) if problem.model.n_modes else 0.0
    T_init = T_low + (0.5 * math.pi / w_min if w_min else 0.0)
    if T_init <= 0.0:
        T_init = 1.0
    s = multi_state_scale(resp, x0, U, T_init)
    T_lb = T_low * (1.0 - 1e-12)
    nuh, T = smoothed_time(resp, x0, U, s, T_lb, T_init)
    tried = 0
    found = None
    for levels in ((), *FINER):
        if levels:
            nuh, T = smoothed_time(resp, x0, U, s, T_lb, T, levels=levels, nuh=nuh)
        nu = nuh / s
        s = multi_state_scale(resp, x0, U, T)
        nuh = nu * s
        tried += 1
        J = singular_inputs(resp, nu, T, np.ones(resp.m, dtype=bool))
        if J:  # inputs the optimal co-state does not see: they do not set the time
            found = _with_singular(resp, x0, U, s, nuh, T, J)
            if found is not None:
                break
        ext = structure_newton(resp, x0, U, s, nuh, T, 1.0, True)
        if ext is not None:
            found = (ext, [(list(range(resp.m)), ext.roots, ext.sign0, 1.0, ext.nuh)])
            break
    if found is None:
        # the smoothed co-state may only be approaching a singular one (T* the rigid-body bound, the
        # modes finished by inputs the optimum does not see): that hypothesis, then the weak inputs as J
        for J_near in [None, *near_singular_candidates(resp, s, nu, T)]:
            if J_near != J and (found := _with_singular(resp, x0, U, s, nuh, T, J_near)) is not None:
                break
    if found is None:
        # a family of co-states (inputs switching together with cancelling mode drives): a singular
        # Jacobian, minimum-norm Newton steps
        every = Setting(np.ones(resp.m, dtype=bool), min_norm_steps=True)
        ext = structure_newton(resp, x0, U, s, nuh, T, 1.0, True, setting=every)
        if ext is not None:
            found = (ext, [(list(range(resp.m)), ext.roots, ext.sign0, 1.0, ext.nuh)])
    if found is None:
        # T* a hair above the rigid-body bound, the modes finished by blips too short for the warm start
        ext = min_time_near_rigid_bound(resp, x0, U, s, nuh, T, T_low, GAP_RTOL)
        if ext is not None:
            found = (ext, [(list(range(resp.m)), ext.roots, ext.sign0, 1.0, ext.nuh)])
    if found is None:
        why = (
            ": a degenerate move, a combination of the inputs pushes the rigid bodies without exciting any mode"
            if mode_free_push(problem.model)
            else ""
        )
        raise SolverError(
            f"multi-input time-optimal planner: no extremal converged for inputs "
            f"{[problem.model.inputs[i] for i in range(problem.model.m)]} (near T = {T:.6g} s){why}; nothing is returned"
        )
    ext, stages = found
    sw, lv, info = _combine(ext.T, U, stages, s)
    extra = {"T_low": T_low, "warm_starts": tried}
    if len(stages) > 1:
        extra["stages"] = info
    return PartSolution(*indices, problem, float(ext.T), 1.0, ext.nuh / s, sw, lv, extra)


def _solve_lowest_peak(indices, problem: MultiMoveProblem, T: float) -> PartSolution:
    """The extremal with the lowest peak fraction ``rho`` that arrives exactly at ``T`` (s)."""
    resp = MultiResponse(problem)
    x0 = problem.shifted_initial()
    U = problem.u_max
    if _at_rest(x0):
        sol = zero_part(indices, problem)
        sol.T = T
        return sol
    s = multi_state_scale(resp, x0, U, T)
    stages = peak_stages(resp, x0, U, s, T, np.ones(resp.m, dtype=bool))
    rho = stages[0].rho
    if rho > 1.0 + 1e-9:
        raise SolverError(
            f"multi-input planner: the lowest peak arriving at T = {T:.6g} s is {rho:.6g} > 1 for inputs "
            f"{list(problem.model.inputs)}; nothing is returned"
        )
    clipped = [(st.inputs, st.roots, st.sign0, min(st.rho, 1.0), st.nuh) for st in stages]
    sw, lv, info = _combine(T, U, clipped, s)
    extra = {"stages": info} if len(stages) > 1 else {}
    return PartSolution(*indices, problem, float(T), min(rho, 1.0), stages[0].nuh / s, sw, lv, extra)


def _with_merged_inputs(indices, problem: MultiMoveProblem, solve) -> PartSolution:
    groups = parallel_groups(problem)
    if len(groups) == problem.model.m:
        return solve(problem)
    sol = solve(merged_problem(problem, groups))
    sw, lv = split_levels(groups, sol.switch_times, sol.levels, problem.u_max, problem.model.m)
    sol.switch_times, sol.levels, sol.problem = sw, lv, problem
    sol.inputs = tuple(indices[0])
    sol.extra["parallel_groups"] = [[j for j, _ in g] for g in groups]
    for st in sol.extra.get("stages", []):  # merged input indices -> the original inputs of their groups
        st["inputs"] = [j for g_idx in st["inputs"] for j, _ in groups[g_idx]]
    return sol


def solve_min_time(indices, problem: MultiMoveProblem) -> PartSolution:
    """Minimum-time extremal of one part (not yet checked: the caller certifies); parallel inputs merged."""
    return _with_merged_inputs(indices, problem, lambda p: _solve_min_time(indices, p))


def solve_lowest_peak(indices, problem: MultiMoveProblem, T: float) -> PartSolution:
    """The extremal with the lowest peak fraction ``rho`` arriving exactly at ``T`` (s); parallel inputs merged."""
    return _with_merged_inputs(indices, problem, lambda p: _solve_lowest_peak(indices, p, T))
