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
from enum import Enum

import numpy as np

from ..config import PlannerConfig
from ..errors import SolverError
from ..results import BangBangProfile, Certificate, PlanResult, SampledProfile, SolverPath
from ..sampled.check import verified_samples
from ..simulation.error_scale import relative_final_state_error
from ..simulation.prepared import PreparedMove
from ..tolerances import AT_REST_ULPS, FINAL_STATE_RTOL
from .common import planning_rate


class Nearness(str, Enum):
    """How far a state is from the target's rest state, at one sample's resolution (:func:`nearness`)."""

    MOVE = "move"  # certainly farther than the tolerance of one sample's reach: a move to plan
    ROUNDING = "rounding"  # differs by rounding only (AT_REST_ULPS): already there, at any rate
    WITHIN_REACH = "within_reach"  # maybe within the tolerance: the exact final-state check decides


def reach_bound(velocity_gains, dt: float, x0: np.ndarray, target: np.ndarray) -> np.ndarray:
    """An upper bound on how far the bounded inputs move each state from rest within ``dt`` (s), per state.

    The states come in (position-like, velocity-like) pairs: a rigid body's
    position and velocity, a mode's coordinate and its rate.  From rest, every
    velocity-like state grows at most at its gain (``|v(t)| <= g t`` with
    ``c <= 0``, ``|q'(t)| <= g t`` for a damped mode) and every position-like
    state is its integral (``<= g t^2 / 2``).  A state deviating from the
    target by more than ``FINAL_STATE_RTOL`` of this is certainly not
    "already there".  Plus the rounding size of the state itself, for the ulp
    test.  One input or several: the gain is what every input at its bound
    adds up to.

    Parameters
    ----------
    velocity_gains : array_like, shape ``(P,)``
        Per pair, ``sum_i |b_i| u_max_i``: the largest rate of its
        velocity-like state (state units / s^2: m/s^2 for a rigid body).
    dt : float
        One sample (s).
    x0, target : ndarray, shape ``(2 P,)``
        The state and the target's rest state (state units).

    Returns
    -------
    ndarray, shape ``(2 P,)``
        The bound (state units).
    """
    gains = np.repeat(np.abs(np.asarray(velocity_gains, dtype=float)), 2)
    per_order = np.tile([0.5 * dt * dt, dt], gains.size // 2)
    size = np.maximum(np.abs(np.asarray(x0, dtype=float)), np.abs(np.asarray(target, dtype=float)))
    return gains * per_order + AT_REST_ULPS * np.finfo(float).eps * size / FINAL_STATE_RTOL


def nearness(velocity_gains, dt: float, x0: np.ndarray, target: np.ndarray, kept) -> Nearness:
    """Whether the state ``x0`` is a move away from ``target`` at the resolution ``dt``, or maybe there.

    The cheap, rigorous test in front of every plan (most plans stop here,
    :attr:`Nearness.MOVE`): a state entry farther from the target than twice
    ``FINAL_STATE_RTOL`` of :func:`reach_bound` is a move.  Entries differing
    by at most :data:`~flexmotion_ros.core.tolerances.AT_REST_ULPS` units in the
    last place of the larger of the two, all of them, are
    :attr:`Nearness.ROUNDING`: the state is not known better than that.  Else
    :attr:`Nearness.WITHIN_REACH`: the caller's exact final-state check of
    the empty sequence decides.

    Parameters
    ----------
    velocity_gains, dt, x0, target
        As for :func:`reach_bound` (full state, absolute coordinates).
    kept : index array
        The state entries the move constrains (a stop drops the free positions).
    """
    x0, target = np.asarray(x0, dtype=float), np.asarray(target, dtype=float)
    dev = (x0 - target)[kept]
    size = np.maximum(np.abs(x0), np.abs(target))[kept]
    if np.any(np.abs(dev) > reach_bound(velocity_gains, dt, x0, target)[kept] * FINAL_STATE_RTOL * 2.0):
        return Nearness.MOVE
    if np.all(np.abs(dev) <= AT_REST_ULPS * np.finfo(float).eps * size):
        return Nearness.ROUNDING
    return Nearness.WITHIN_REACH


#: The hold's message when the goal and the state differ by rounding only.
ROUNDING_MESSAGE = f"already there: the goal differs from the state by rounding only (<= {AT_REST_ULPS} ulps)"


def within_reach_message(relative_error: float, rate_hz: float) -> str:
    """The hold's message when the exact check of the empty sequence passed at ``rate_hz`` (Hz)."""
    return (
        f"already there: every state within {relative_error:.1e} (tolerance "
        f"FINAL_STATE_RTOL) of the target's rest state, relative to one sample's reach at {rate_hz:g} Hz"
    )


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
    model = problem.model
    x0 = np.asarray(problem.x0, dtype=float)
    target = model.rest_state(problem.target if problem.target is not None else 0.0)
    gains = np.abs(model.B()[1::2]) * problem.u_max  # the velocity-like rows of B
    kept = np.arange(x0.size) if problem.target is not None else np.arange(1, x0.size)
    near = nearness(gains, dt, x0, target, kept)
    if near is Nearness.MOVE:
        return None  # a real move (the cheap, rigorous test: most plans stop here)
    extra = {"already_there": True}
    if near is Nearness.ROUNDING:
        # the goal and the state differ by rounding only: the state is not known better than that
        dev = (x0 - target)[kept]
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
        message = ROUNDING_MESSAGE
    else:
        try:
            hold = verified_samples(move, np.empty(0), dt, config.method, True, 0, None, extra, t0)
        except SolverError:
            return None
        message = within_reach_message(hold.final_state_error_relative, rate)
    certificate = Certificate.at_rest(move.response.n, message)
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
