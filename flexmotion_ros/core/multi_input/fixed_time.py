"""Arrive at a requested time ``T_req >= T*``: every part with its lowest peak that arrives exactly then.

For each decoupled part, the inputs at ``rho u_max_i`` with the smallest
``rho`` whose reachable set at ``T_req`` contains the start:
``rho = 1 / m(T_req)`` from the dual of :mod:`.dual`, bang-bang, certified by
its dual bound (no input with a lower peak fraction arrives at ``T_req``).
The sampled version is the least-peak LP of :mod:`.zoh` at exactly
``round(T_req rate_hz)`` samples.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..errors import InputError, SolverError
from ..time_optimal.fixed_time import check_arrival_time
from .assembly import assemble
from .parts import decoupled_parts, solve_lowest_peak
from .problem import MultiMoveProblem
from .results import MultiProfile, MultiSampledProfile, PartRole, SyncMode
from .sampled_lp import finish_samples, lowest_peak_samples
from .time_optimal import plan_multi_time_optimal


def plan_multi_fixed_time(problem: MultiMoveProblem, arrival_time: float) -> MultiProfile:
    """Every part arrives at rest at ``arrival_time`` (s) with its lowest peak; refused below ``T*``."""
    t0 = time.perf_counter()
    best = plan_multi_time_optimal(problem)
    T_req = check_arrival_time(arrival_time, best.duration)
    if T_req == best.duration:
        return best
    parts, roles = [], []
    for idx in decoupled_parts(problem.model):
        p = solve_lowest_peak(idx, problem.sub(*idx), T_req)
        parts.append(p)
        roles.append(PartRole.AT_REST if p.extra.get("at_rest") else PartRole.LOWEST_PEAK)
    prof = assemble(problem, parts, roles, T_req, SyncMode.TIME, t0, method="fixed_time")
    prof.extra["time_optimal_duration"] = best.duration
    return prof


def plan_multi_fixed_time_zoh(problem: MultiMoveProblem, arrival_time: float, rate_hz: float) -> MultiSampledProfile:
    """The lowest-peak sequence of exactly ``round(arrival_time rate_hz)`` samples per part."""
    t0 = time.perf_counter()
    cont = plan_multi_fixed_time(problem, arrival_time)
    dt = 1.0 / float(rate_hz)
    K = max(1, round(cont.duration / dt))
    out = np.zeros((K, problem.model.m))
    for p, role in zip(cont.extra["part_solutions"], cont.extra["part_roles"]):
        if role is PartRole.AT_REST:
            continue
        try:
            ps = lowest_peak_samples(p, dt, K)
        except SolverError:
            raise InputError(
                "arrival_time",
                f"{K} samples at {rate_hz:g} Hz ({K * dt:.6g} s) cannot reach rest within the bounds; ask for a later time",
            ) from None
        out[:, list(p.inputs)] = ps.commands
    return finish_samples(problem, out, dt, False, 0, "", math.nan, cont, t0, {}, method="fixed_time")
