"""Assembly of a multi-input profile from its parts, with the exact checks and the certificate.

Shared by every continuous multi-input planner (:mod:`.time_optimal`, :mod:`.phase`,
:mod:`.fixed_time`): the parts' switch times and levels are merged, simulated
exactly (matrix exponentials of the full ``(A, B)``), and each part is
certified: Pontryagin conditions with one co-state, the weak-duality lower
bound on the minimum time, the dual bound of a lowest-peak part.
"""

from __future__ import annotations

import time

import numpy as np

from ..errors import SolverError
from ..tolerances import FINAL_STATE_RTOL, GAP_RTOL
from .certificate import pontryagin_checks
from .dual import duality_bound, multi_state_scale
from .exact import VectorPiecewise, simulate, system_of
from .parts import PartSolution
from .problem import MultiMoveProblem
from .response import MultiResponse
from .results import MultiCertificate, MultiProfile, PartRole, SyncMode

#: A lowest-peak part is certified when its dual bound is within this (relative) of its peak.
PEAK_GAP_RTOL = 1e-8


def _hold_after(sw: np.ndarray, lv: np.ndarray, T_part: float, T: float) -> tuple[np.ndarray, np.ndarray]:
    if T_part >= T:
        return sw, lv
    return np.append(sw, T_part), np.append(lv, 0.0)


def assemble(
    problem: MultiMoveProblem,
    parts: list[PartSolution],
    roles: list[PartRole],
    T: float,
    mode: SyncMode,
    t0: float,
    method: str = "time_optimal",
) -> MultiProfile:
    """Merge the parts into one profile, simulate it exactly, certify each part."""
    m = problem.model.m
    switch_times: list = [None] * m
    levels: list = [None] * m
    for p in parts:
        for a, i in enumerate(p.inputs):
            sw, lv = np.asarray(p.switch_times[a], float), np.asarray(p.levels[a], float)
            if p.extra.get("at_rest"):
                sw, lv = np.empty(0), np.zeros(1)
            elif roles[parts.index(p)] is PartRole.OWN_OPTIMUM:
                sw, lv = _hold_after(sw, lv, p.T, T)
            bound = problem.u_max[i]
            if np.any(np.abs(lv) > bound):  # rho <= 1 and levels = rho u_max sgn: only rounding can exceed
                lv = np.clip(lv, -bound, bound)
            switch_times[i], levels[i] = sw, lv
    final_state, err, rel = check_final_state(problem, switch_times, levels, T)
    cert = certify_parts(problem, parts, roles, T)
    return MultiProfile(
        problem=problem,
        switch_times=tuple(switch_times),
        levels=tuple(levels),
        duration=float(T),
        final_state=final_state,
        final_state_error=err,
        final_state_error_relative=rel,
        certificate=cert,
        sync=mode,
        method=method,
        solve_time_s=time.perf_counter() - t0,
        # the parts' extremals (co-states, peak fractions): the sampled planner starts from them
        extra={"parts": len(parts), "part_solutions": list(parts), "part_roles": list(roles)},
    )


def profile_input(switch_times, levels, T: float) -> VectorPiecewise:
    """Per-input switches and levels merged into one :class:`VectorPiecewise` on ``[0, T]``."""
    starts = [np.asarray(s, float) for s in switch_times]
    allt = np.unique(np.concatenate([np.empty(0), *starts]))
    breaks = np.concatenate([[0.0], allt[(allt > 0.0) & (allt < T)], [T]])
    mids = 0.5 * (breaks[:-1] + breaks[1:])
    rows = np.column_stack(
        [np.asarray(levels[i], float)[np.searchsorted(starts[i], mids, side="right")] for i in range(len(levels))]
    )
    return VectorPiecewise(breaks, rows)


def check_final_state(problem: MultiMoveProblem, switch_times, levels, T: float, rigid_only: bool = False):
    """Exact final state (full, absolute) and its errors; :class:`SolverError` if it misses.

    ``rigid_only``: judge the rigid bodies only (shapers that leave a designed
    residual vibration, e.g. EI); the modes' residual is the caller's to report.
    """
    A, B = system_of(problem.model)
    u = profile_input(switch_times, levels, T)
    xT = simulate(A, B, problem.x0, u, times=[T])[0] if T > 0.0 else problem.x0.copy()
    dev = (xT - problem.target_state())[problem.kept]
    resp = MultiResponse(problem)
    scale = multi_state_scale(resp, problem.shifted_initial(), problem.u_max, max(T, 1e-300))
    if rigid_only:
        dev, scale = dev[: resp.r], scale[: resp.r]
    err = float(np.max(np.abs(dev))) if dev.size else 0.0
    rel = float(np.max(np.abs(dev) / scale)) if dev.size else 0.0
    if not rel <= FINAL_STATE_RTOL:
        raise SolverError(
            f"multi-input planner missed the target: relative final-state error {rel:.3e} "
            f"(tolerance {FINAL_STATE_RTOL:.0e}); nothing is returned"
        )
    return xT, err, rel


def certify_parts(problem: MultiMoveProblem, parts: list[PartSolution], roles: list[PartRole], T: float):
    """Pontryagin checks per part, the weak-duality lower bound on ``T*``, the lowest-peak duals."""
    n_red = problem.kept.size
    lam0 = np.zeros(n_red)
    reasons: list[str] = []
    summaries = []
    sw_res, extra, unproved, sign_ok, spread = 0.0, 0, 0, True, 0.0
    lower = 0.0
    margin = np.inf
    offsets = _part_offsets(problem, parts)
    for p, role, off in zip(parts, roles, offsets):
        names = [problem.model.inputs[i] for i in p.inputs]
        summary = {"role": str(role), "inputs": names, "duration": float(p.T), "peak_fraction": float(p.rho)}
        if role is PartRole.AT_REST:
            summaries.append(summary)
            continue
        resp = MultiResponse(p.problem)
        A, B = p.system()
        x0 = p.problem.shifted_initial()
        stages = p.extra.get("stages", [])
        later = [i for st in stages[1:] for i in st["inputs"]]
        ck = pontryagin_checks(
            resp,
            A,
            B,
            x0,
            p.nu,
            p.T,
            p.switch_times,
            p.levels,
            free_time=role is not PartRole.LOWEST_PEAK,
            singular=later,
        )
        for k, st in enumerate(stages[1:], start=1):
            ok, note = _stage_proved(resp, A, B, x0, p, stages[:k], st)
            note["inputs"] = [problem.model.inputs[p.inputs[i]] for i in st["inputs"]]
            summary.setdefault("stages", []).append(note)
            if not ok:
                reasons.append(f"inputs {note['inputs']}: {note['proof']}")
        sw_res, extra, unproved = max(sw_res, ck.switch_residual), extra + ck.extra_zeros, unproved + ck.unproved_cells
        sign_ok = sign_ok and ck.sign_consistent
        spread = max(spread, ck.hamiltonian_spread)
        summary["pontryagin"] = "ok" if ck.passed else "; ".join(ck.reasons)
        if role is PartRole.LOWEST_PEAK:
            roots = ck.zeros_tau if ck.unproved_cells == 0 else None
            db = duality_bound(resp, A, B, x0, p.problem.u_max, p.nu, p.T, roots)
            summary["peak_lower_bound"] = float(db.ratio)
            ok = db.unproved == 0 and db.ratio >= p.rho * (1.0 - PEAK_GAP_RTOL)
            if not ok:
                reasons.append(f"inputs {names}: lowest peak {p.rho:.9g} not proved (dual bound {db.ratio:.9g})")
            elif not ck.passed:
                summary["pontryagin"] += " (peak proved by the dual bound)"
        else:
            T_lo = p.T * (1.0 - GAP_RTOL)
            roots = ck.zeros_tau if ck.unproved_cells == 0 else None
            db = duality_bound(resp, A, B, x0, p.problem.u_max, p.nu, T_lo, roots)
            proved = db.unproved == 0 and db.margin > 0.0
            summary["lower_bound"] = float(T_lo) if proved else 0.0
            if role is PartRole.CRITICAL:
                lam0[off] = ck.costate_initial
                if proved:
                    lower = max(lower, T_lo)
                    margin = min(margin, db.margin)
            if not proved:
                reasons.append(f"inputs {names}: the weak-duality bound at {T_lo:.9g} s does not hold")
            if not ck.passed and proved:
                summary["pontryagin"] += f" (optimal within {GAP_RTOL:.0e} by the duality bound)"
            elif not ck.passed:
                reasons.append(f"inputs {names}: " + "; ".join(ck.reasons))
        summaries.append(summary)
    if lower <= 0.0 and T > 0.0 and any(r in (PartRole.CRITICAL, PartRole.OWN_OPTIMUM) for r in roles):
        reasons.append("no proved lower bound on the minimum time")
    return MultiCertificate(
        passed=not reasons,
        costate_initial=lam0,
        switch_residual=sw_res,
        extra_zeros=extra,
        unproved_cells=unproved,
        sign_consistent=sign_ok,
        hamiltonian_spread=spread,
        lower_bound=lower,
        duality_margin=float(margin) if np.isfinite(margin) else 0.0,
        message="; ".join(reasons) or "ok",
        parts=tuple(summaries),
    )


def _stage_proved(resp, A, B, x0, p: PartSolution, before: list, st: dict) -> tuple[bool, dict]:
    """A later stage's lowest peak, proved by its own dual: the state the earlier stages leave, by exact simulation."""
    if st["rho"] == 0.0:  # nothing was left to do: no input has a lower peak than zero
        return True, {"inputs": list(st["inputs"]), "peak_fraction": 0.0, "peak_lower_bound": 0.0, "proof": "ok"}
    m = len(p.levels)
    done = {i for b in before for i in b["inputs"]}
    levels = [np.asarray(p.levels[i], float) if i in done else np.zeros_like(p.levels[i]) for i in range(m)]
    u = profile_input(p.switch_times, levels, p.T)
    w = -simulate(A, B, x0, u, times=[p.T])[0]
    db = duality_bound(resp, A, B, x0, p.problem.u_max, st["nu"], p.T, inputs=st["inputs"], w=w)
    ok = db.unproved == 0 and db.ratio >= st["rho"] * (1.0 - PEAK_GAP_RTOL)
    note = {"inputs": list(st["inputs"]), "peak_fraction": float(st["rho"]), "peak_lower_bound": float(db.ratio)}
    note["proof"] = "ok" if ok else f"lowest peak {st['rho']:.9g} not proved (dual bound {db.ratio:.9g})"
    return ok, note


def _part_offsets(problem: MultiMoveProblem, parts: list[PartSolution]) -> list[np.ndarray]:
    """Indices of each part's reduced state in the whole move's reduced state."""
    kept = list(problem.kept)
    k = problem.model.k
    out = []
    for p in parts:
        full = [s for j in p.bodies for s in (2 * j, 2 * j + 1)] + [
            s for l in p.modes for s in (2 * k + 2 * l, 2 * k + 2 * l + 1)
        ]
        full = [s for s in full if s in kept]
        out.append(np.array([kept.index(s) for s in full], dtype=int))
    return out
