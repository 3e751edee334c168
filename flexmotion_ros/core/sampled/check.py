"""The exact check every sampled (zero-order-hold) command sequence passes before it is returned.

The sequence is propagated by matrix exponentials (no ODE integrator); its
final state must be the target's rest state to ``FINAL_STATE_RTOL``
relative to the planner's error scale
(:func:`~flexmotion_ros.core.reachable_set.state_scale`: how large each state
can get in a move of that length, independent of the profile), and no
command may exceed ``u_max``.  Otherwise nothing is returned.
"""

from __future__ import annotations

import time

import numpy as np

from ..errors import SolverError
from ..model.boundary import MoveProblem
from ..results import BangBangProfile, SampledProfile
from ..simulation.exact import simulate_samples
from ..simulation.modal_response import ModalResponse
from ..time_optimal.reachable_set import state_scale
from ..tolerances import FINAL_STATE_RTOL


def verified_samples(
    problem: MoveProblem,
    commands: np.ndarray,
    dt: float,
    method: str,
    minimal: bool,
    lower_bound_samples: int,
    continuous: BangBangProfile | None = None,
    extra: dict | None = None,
    t0: float | None = None,
) -> SampledProfile:
    """A :class:`SampledProfile` after the exact final-state and bound checks.

    Parameters
    ----------
    problem : MoveProblem
        The move.
    commands : ndarray
        Command per sample (N), applied for ``dt`` each.
    dt : float
        Sample period (s).
    method : str
        Planner name, for the profile and the error message.
    minimal, lower_bound_samples :
        What the planner proved about the sample count.
    continuous : BangBangProfile, optional
        The continuous profile the sequence came from.
    extra : dict, optional
        Method-specific figures for the profile.
    t0 : float, optional
        ``time.perf_counter()`` at the start of planning (for ``solve_time_s``).

    Raises
    ------
    SolverError
        If the sequence misses the target or exceeds ``u_max``.
    """
    commands = np.asarray(commands, dtype=float)
    states = simulate_samples(problem.model, problem.x0, commands, dt)
    target = problem.model.rest_state(problem.target if problem.target is not None else 0.0)
    dev = states[-1] - target
    if problem.target is None:  # final position free
        dev = dev[1:]
    system = ModalResponse(problem.model, problem.include_position)
    scale = state_scale(system, problem.shifted_initial(), problem.u_max, max(commands.size * dt, dt))
    err = float(np.max(np.abs(dev))) if dev.size else 0.0
    rel = float(np.max(np.abs(dev) / scale)) if dev.size else 0.0
    peak = float(np.max(np.abs(commands))) if commands.size else 0.0
    if not rel <= FINAL_STATE_RTOL:
        raise SolverError(
            f"{method}: sampled sequence misses the target (relative final-state error {rel:.3e}); nothing is returned"
        )
    if peak > problem.u_max:
        raise SolverError(f"{method}: sampled command {peak} exceeds u_max = {problem.u_max}; nothing is returned")
    return SampledProfile(
        problem=problem,
        commands=commands,
        dt=dt,
        states=states,
        final_state_error=err,
        final_state_error_relative=rel,
        minimal=minimal,
        lower_bound_samples=int(lower_bound_samples),
        continuous=continuous,
        solve_time_s=(time.perf_counter() - t0) if t0 is not None else 0.0,
        method=method,
        extra=dict(extra or {}),
    )
