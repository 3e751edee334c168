"""Moves shorter than the resolution: answered "already there", for every method.

A goal equal to the current position re-sent at rest leaves a shifted state
of a few ulps (~4e-16); a goal of 1e-15 m is physically nothing.  Planning
such a move asks a solver for switch times of nanoseconds and a sampled
planner for commands below rounding; the answer is known in advance: hold.

*Shorter than the resolution* is decided by the same exact check every
sampled sequence passes (:func:`~flexmotion_ros.core.sampled.check.verified_samples`):
the empty sequence (hold, zero samples) is accepted iff the state is already
within :data:`~flexmotion_ros.core.tolerances.FINAL_STATE_RTOL` of the
target's rest state, relative to the error scale of one sample (how far the
actuator moves each state in ``dt``).  So "already there" means exactly what
"arrived" means for any other plan of that length: nothing is loosened.  The
resolution is the planning rate, or ``config.rate_hz`` (the node's) when no
rate is given.
"""

from __future__ import annotations

import time

import numpy as np

from ..config import PlannerConfig
from ..errors import SolverError
from ..results import BangBangProfile, Certificate, PlanResult, SolverPath
from ..sampled.check import verified_samples
from ..simulation.prepared import PreparedMove
from .common import planning_rate


def plan_already_there(config: PlannerConfig, move: PreparedMove, rate_hz: float | None) -> PlanResult | None:
    """The hold, if the move is shorter than the resolution; else None (plan it).

    Parameters
    ----------
    config : PlannerConfig
        The configuration (``method`` names the result; ``rate_hz`` is the
        resolution when ``rate_hz`` is None).
    move : PreparedMove
        The move.
    rate_hz : float or None
        Planning rate (Hz), validated; None: no sampled plan requested.

    Returns
    -------
    PlanResult or None
        A zero-duration continuous profile (certified: nothing is faster
        than not moving) and, with a rate, the empty command sequence, both
        after the exact final-state check; None if the state is not within
        the tolerance of one sample's reach (then it is a move to plan).
    """
    t0 = time.perf_counter()
    rate, _ = planning_rate(config, rate_hz)
    dt = 1.0 / rate
    try:
        hold = verified_samples(move, np.empty(0), dt, config.method, True, 0, None, {"already_there": True}, t0)
    except SolverError:
        return None
    message = (
        f"already there: every state within {hold.final_state_error_relative:.1e} (tolerance FINAL_STATE_RTOL) "
        f"of the target's rest state, relative to one sample's reach at {rate:g} Hz"
    )
    problem = move.problem
    certificate = Certificate(
        passed=True,
        costate_initial=np.zeros(move.response.n),
        costate_final=np.zeros(move.response.n),
        switch_residual=0.0,
        extra_zeros=0,
        unproved_cells=0,
        sign_consistent=True,
        min_margin=1.0,
        hamiltonian_max_abs=0.0,
        message=message,
    )
    continuous = BangBangProfile(
        problem=problem,
        switch_times=np.empty(0),
        levels=np.array([problem.u_max]),
        duration=0.0,
        final_state=hold.states[-1].copy(),
        final_state_error=hold.final_state_error,
        final_state_error_relative=hold.final_state_error_relative,
        certificate=certificate,
        solve_time_s=time.perf_counter() - t0,
        extra={"solver_path": SolverPath.AT_REST},
    )
    hold.continuous = continuous
    sampled = hold if rate_hz else None
    info = {"already_there": True, "plan_time_s": time.perf_counter() - t0}
    return PlanResult(method=config.method, problem=problem, continuous=continuous, sampled=sampled, info=info)
