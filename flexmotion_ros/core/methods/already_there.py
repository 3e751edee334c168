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

A goal that differs from the state by rounding only (at most
:data:`~flexmotion_ros.core.tolerances.AT_REST_ULPS` units in the last place
of the larger of the two, state by state: a position of 2 m re-sent as the
goal after a round trip through a message) is also already there, at any
rate: the state is not known better than that.
"""

from __future__ import annotations

import time

import numpy as np

from ..config import PlannerConfig
from ..errors import SolverError
from ..results import BangBangProfile, Certificate, PlanResult, SampledProfile, SolverPath
from ..sampled.check import verified_samples
from ..simulation.error_scale import relative_final_state_error
from ..simulation.prepared import PreparedMove
from ..tolerances import AT_REST_ULPS, FINAL_STATE_RTOL
from .common import planning_rate


def _reach_bound(problem, dt: float) -> np.ndarray:
    """An upper bound on how far ``u_max`` moves each state from rest within ``dt`` (s), per state.

    From rest, every velocity-like state grows at most at its gain times
    ``u_max`` (``|v(t)| <= |b0| u_max t`` with ``c <= 0``, ``|q'(t)| <= |b_i|
    u_max t`` for a damped mode) and every position-like state is its
    integral (``<= gain u_max t^2 / 2``).  A state deviating from the target by
    more than ``FINAL_STATE_RTOL`` of this is certainly not "already there".
    Plus the rounding size of the state itself, for the ulp test.
    """
    model = problem.model
    gains = np.concatenate([[model.b0, model.b0], np.repeat(np.asarray(model.b, dtype=float), 2)])
    per_order = np.tile([0.5 * dt * dt, dt], 1 + model.n_modes)  # (position-like, velocity-like) pairs
    bound = np.abs(gains) * problem.u_max * per_order
    x0 = np.asarray(problem.x0, dtype=float)
    target = model.rest_state(problem.target if problem.target is not None else 0.0)
    bound = bound + AT_REST_ULPS * np.finfo(float).eps * np.maximum(np.abs(x0), np.abs(target)) / FINAL_STATE_RTOL
    return bound if problem.target is not None else bound[1:]


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
    problem = move.problem
    x0 = np.asarray(problem.x0, dtype=float)
    target = problem.model.rest_state(problem.target if problem.target is not None else 0.0)
    dev, size = x0 - target, np.maximum(np.abs(x0), np.abs(target))
    if problem.target is None:
        dev, size = dev[1:], size[1:]
    if np.any(np.abs(dev) > _reach_bound(problem, dt) * FINAL_STATE_RTOL * 2.0):
        return None  # a real move (the cheap, rigorous test: most plans stop here)
    extra = {"already_there": True}
    if np.all(np.abs(dev) <= AT_REST_ULPS * np.finfo(float).eps * size):
        # the goal and the state differ by rounding only: the state is not known better than that
        scale = move.error_scale(dt)
        hold = SampledProfile(
            problem=problem,
            commands=np.empty(0),
            dt=dt,
            states=x0[None, :].copy(),
            final_state_error=float(np.max(np.abs(dev), initial=0.0)),
            final_state_error_relative=relative_final_state_error(dev, scale),
            minimal=True,
            lower_bound_samples=0,
            solve_time_s=time.perf_counter() - t0,
            method=config.method,
            extra=extra,
        )
        message = f"already there: the goal differs from the state by rounding only (<= {AT_REST_ULPS} ulps)"
    else:
        try:
            hold = verified_samples(move, np.empty(0), dt, config.method, True, 0, None, extra, t0)
        except SolverError:
            return None
        message = (
            f"already there: every state within {hold.final_state_error_relative:.1e} (tolerance "
            f"FINAL_STATE_RTOL) of the target's rest state, relative to one sample's reach at {rate:g} Hz"
        )
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
