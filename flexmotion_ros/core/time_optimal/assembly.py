"""Every candidate of every time-optimal stage, simulated exactly and certified: :func:`assemble`.

A bang-bang candidate (switches in time-to-go, their signs, a co-state
direction) becomes a :class:`~flexmotion_ros.core.results.BangBangProfile`
only through here: the final state by matrix-exponential simulation
(:func:`~flexmotion_ros.core.simulation.exact.simulate`), optimality by the
Pontryagin certificate (:mod:`.certificate`).  A candidate whose final state
misses the target raises :class:`~flexmotion_ros.core.errors.SolverError`:
it is never returned.  The planner (:mod:`.solver`) hands this function to
its warm start and fallbacks.
"""

from __future__ import annotations

import time

import numpy as np

from ..errors import SolverError
from ..model.boundary import MoveProblem
from ..results import BangBangProfile, Certificate
from ..simulation.error_scale import relative_final_state_error
from ..simulation.exact import PiecewiseConstant, simulate
from ..tolerances import FINAL_STATE_RTOL
from .certificate import certify
from .reachable_set import state_scale


def assemble(problem, system, nu, T, roots_tau, signs_tau, t0, evaluations, T_low=None) -> BangBangProfile:
    """The profile with switches at times-to-go ``roots_tau`` (s) and signs ``signs_tau``, simulated and certified.

    ``nu``: the co-state direction for the certificate; ``T`` the duration
    (s); ``t0`` the ``perf_counter`` at the start of planning; ``T_low`` a
    proved lower bound (s) for the gap certificate.  Raises
    :class:`SolverError` if the exact final state misses the target.
    """
    um = problem.u_max
    switch_times = np.clip(np.sort(T - roots_tau), 0.0, T)
    levels = um * signs_tau[::-1]
    u = PiecewiseConstant.from_switches(switch_times, levels, T)
    x0s = problem.shifted_initial()
    states = simulate((system.A(), system.B()), x0s, u)
    xT = states[-1]
    scale = state_scale(system, x0s, um, T) if T > 0.0 else np.ones(xT.size)
    err = float(np.max(np.abs(xT))) if xT.size else 0.0
    rel = relative_final_state_error(xT, scale)
    if T > 0.0:
        cert = certify(system, nu, T, um, switch_times, levels, states, lower_bound=T_low)
    else:
        cert = Certificate.at_rest(system.n)
    final_abs = absolute_final(problem, u)
    profile = BangBangProfile(
        problem=problem,
        switch_times=switch_times,
        levels=levels,
        duration=float(T),
        final_state=final_abs,
        final_state_error=err,
        final_state_error_relative=rel,
        certificate=cert,
        solve_time_s=time.perf_counter() - t0,
        iterations=evaluations,
    )
    if not rel <= FINAL_STATE_RTOL:
        miss = SolverError(
            f"time-optimal planner missed the target: relative final-state error {rel:.3e} "
            f"(tolerance {FINAL_STATE_RTOL:.0e}); nothing is returned"
        )
        miss.relative_error = rel  # for a caller that words the refusal by its cause
        raise miss
    return profile


def absolute_final(problem: MoveProblem, u: PiecewiseConstant) -> np.ndarray:
    """Final full state in absolute coordinates, by exact simulation."""
    return simulate(problem.model, problem.x0, u, times=[u.duration])[0]
