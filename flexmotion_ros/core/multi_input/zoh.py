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

import numpy as np

from ..errors import GoalError, SolverError
from ..model.modal_model import check_positive
from ..sampled.zoh import plan_time_optimal_zoh
from ..tolerances import MAX_SAMPLES
from .parts import PartSolution
from .problem import MultiMoveProblem
from .results import MultiProfile, MultiSampledProfile, PartRole, SyncMode
from .sampled_lp import MAX_EXTRA_SAMPLES, PartSamples, fewest_samples, finish_samples, lowest_peak_samples
from .time_optimal import plan_multi_time_optimal


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
        return finish_samples(problem, np.zeros((0, m)), dt, True, 0, "at rest", math.nan, continuous, t0, {})
    if mode is SyncMode.PHASE:
        path = continuous.extra["path_problem"]
        d = continuous.extra["path_direction"]
        sp = plan_time_optimal_zoh(path, rate, continuous=continuous.extra["path_profile"])
        cmds = np.clip(np.outer(sp.commands, d), -problem.u_max, problem.u_max)
        return finish_samples(
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
    return finish_samples(
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
