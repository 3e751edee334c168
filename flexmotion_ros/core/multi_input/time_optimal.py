"""Certified time-optimal multi-input moves, normal or not (seed eqs. 2.20-2.37 with ``m`` inputs).

Method
------
1. Split the model into decoupled parts (:func:`~.parts.decoupled_parts`):
   inputs sharing a rigid body or a mode, transitively.
2. Each part's minimum time ``T_c`` from the convex reachable-set dual (support
   function summed over the part's inputs), then Newton on every input's
   switch times (:mod:`.parts`).  The move's minimum time is ``T* = max T_c``:
   the whole reachable set is the product of the parts' sets.
3. The parts that do not set ``T*`` (their inputs are singular for the
   move's co-state: ``B_i^T lambda = 0``) follow ``sync``:

   * ``time`` (default): the lowest peak fraction ``rho_c = 1 / m_c(T*)``
     that arrives exactly at ``T*`` (bang-bang at ``rho_c u_max_i``); its dual
     ``nu`` proves that no input with a lower peak arrives then (weak duality,
     :class:`~.dual.DualityBound`\\ ``.ratio``).
   * ``none``: each part's own time-optimal move, then the hold (0).
   * ``phase``: see :mod:`.phase`.

4. Checks, independent of how the profile was found: the exact final state by
   matrix exponentials of the full ``(A, B)`` (:mod:`.exact`); per part the
   Pontryagin conditions (:mod:`.certificate`) with one co-state; and the
   weak-duality bound at ``T* (1 - GAP_RTOL)`` that proves no admissible input
   arrives sooner.  A profile whose final state misses is never returned; no
   level exceeds ``u_max_i``.

For a normal model (one part, every input alone controlling it) step 3 is
empty and the certificate is the one co-state ``lambda_0`` of the issue: every
``B_i^T e^{-A^T t} lambda_0`` vanishes exactly at input ``i``'s switches, with
the signs of (2.34) and a zero Hamiltonian.
"""

from __future__ import annotations

import time

from ..errors import ConfigError
from .assembly import assemble
from .parts import decoupled_parts, solve_lowest_peak, solve_min_time
from .phase import plan_phase
from .problem import MultiMoveProblem
from .results import MultiProfile, PartRole, SyncMode

#: Parts whose minimum times agree to this (relative) all set ``T*``.
TIE_RTOL = 1e-12


def check_sync(sync) -> SyncMode:
    """``sync`` as a :class:`SyncMode`, or :class:`ConfigError` naming the allowed values."""
    try:
        return SyncMode(str(sync))
    except ValueError:
        raise ConfigError("sync", f"must be one of {[s.value for s in SyncMode]}, got {sync!r}") from None


def plan_multi_time_optimal(problem: MultiMoveProblem, sync: str | SyncMode = SyncMode.TIME) -> MultiProfile:
    """The certified minimum-time move of a multi-input model.

    Parameters
    ----------
    problem : MultiMoveProblem
        Model, bounds (one per input), initial state, targets (``None``: free).
    sync : {"time", "none", "phase"}
        What the inputs that do not set the minimum time do (module notes).

    Returns
    -------
    MultiProfile

    Raises
    ------
    ConfigError
        Unknown ``sync``; ``phase`` where the dynamics do not allow a straight line.
    SolverError
        No profile passed the exact final-state check.
    """
    t0 = time.perf_counter()
    mode = check_sync(sync)
    if mode is SyncMode.PHASE:
        return plan_phase(problem, t0)
    parts = []
    for idx in decoupled_parts(problem.model):
        parts.append(solve_min_time(idx, problem.sub(*idx)))
    T_star = max(p.T for p in parts)
    final = []
    roles = []
    for p in parts:
        if p.T == 0.0 and p.extra.get("at_rest"):
            p.T = T_star
            final.append(p)
            roles.append(PartRole.AT_REST)
        elif p.T >= T_star * (1.0 - TIE_RTOL):
            final.append(p)
            roles.append(PartRole.CRITICAL)
        elif mode is SyncMode.TIME:
            final.append(solve_lowest_peak((p.inputs, p.bodies, p.modes), p.problem, T_star))
            roles.append(PartRole.LOWEST_PEAK)
        else:
            final.append(p)
            roles.append(PartRole.OWN_OPTIMUM)
    return assemble(problem, final, roles, T_star, mode, t0)
