"""The exact check every sampled (zero-order-hold) command sequence passes before it is returned.

The sequence is propagated by matrix exponentials (no ODE integrator); its
final state must be the target's rest state to ``FINAL_STATE_RTOL``
relative to the planner's error scale
(:func:`~flexmotion_ros.core.simulation.error_scale.state_scale`: how large
each state can get in a move of that length, independent of the profile), and
no command may exceed ``u_max``.  Otherwise nothing is returned.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import SolverError
from ..model.boundary import MoveProblem
from ..results import BangBangProfile, SampledProfile
from ..simulation.error_scale import relative_final_state_error
from ..simulation.exact import simulate_samples
from ..simulation.prepared import PreparedMove, prepare
from ..tolerances import FINAL_STATE_RTOL


@dataclass(frozen=True, kw_only=True)
class AugmentedSystem:
    """A larger linear system the sequence must also bring to rest (e.g. frequency derivatives).

    Attributes
    ----------
    A, B : ndarray
        State matrix (1/s) and input vector of the augmented system.
    x0 : ndarray
        Its initial state (shifted: the target is the origin).
    """

    A: np.ndarray
    B: np.ndarray
    x0: np.ndarray


def verified_samples(
    problem: MoveProblem | PreparedMove,
    commands: np.ndarray,
    dt: float,
    method: str,
    minimal: bool,
    lower_bound_samples: int,
    continuous: BangBangProfile | None = None,
    extra: dict | None = None,
    t0: float | None = None,
    augmented: AugmentedSystem | None = None,
    simulator: Callable[[np.ndarray, float], np.ndarray] | None = None,
) -> SampledProfile:
    """A :class:`SampledProfile` after the exact final-state and bound checks.

    Parameters
    ----------
    problem : MoveProblem or PreparedMove
        The move (a :class:`PreparedMove` reuses its responses and scales).
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
    augmented : AugmentedSystem, optional
        A system the sequence must also bring to its origin (robust moves:
        the nominal model with the frequency derivatives of its modes).  Its
        final state is judged relative to the augmented trajectory's own
        excursion ``max_k |xa_k|`` (per entry): the derivative states have no
        reachable-set scale (:func:`state_scale` is defined for the modal
        structure only).  Recorded in ``extra["augmented_final_state_error_relative"]``.
    simulator : callable, optional
        ``simulator(commands, dt) -> states``: the exact simulation of the
        sequence, states (absolute coordinates) at the ``K + 1`` sample
        instants.  Default: the linear model by matrix exponentials
        (:func:`~flexmotion_ros.core.simulation.exact.simulate_samples`);
        Coulomb friction passes its event-located simulation.

    Raises
    ------
    SolverError
        If the sequence misses the target or exceeds ``u_max``.
    """
    move = prepare(problem)
    problem = move.problem
    commands = np.asarray(commands, dtype=float)
    if simulator is None:
        states = simulate_samples(problem.model, problem.x0, commands, dt)
    else:
        states = np.asarray(simulator(commands, dt), dtype=float)
    target = problem.model.rest_state(problem.target if problem.target is not None else 0.0)
    dev = states[-1] - target
    if problem.target is None:  # final position free
        dev = dev[1:]
    scale = move.error_scale(max(commands.size * dt, dt))
    err = float(np.max(np.abs(dev))) if dev.size else 0.0
    rel = relative_final_state_error(dev, scale)
    peak = float(np.max(np.abs(commands))) if commands.size else 0.0
    if not rel <= FINAL_STATE_RTOL:
        raise SolverError(
            f"{method}: sampled sequence misses the target (relative final-state error {rel:.3e}); nothing is returned"
        )
    extra = dict(extra or {})
    if augmented is not None:
        xa = simulate_samples((augmented.A, augmented.B), augmented.x0, commands, dt)
        sa = np.max(np.abs(xa), axis=0)
        rel_aug = relative_final_state_error(xa[-1], np.where(sa > 0.0, sa, 1.0))
        if not rel_aug <= FINAL_STATE_RTOL:
            raise SolverError(
                f"{method}: sampled sequence misses the augmented target (relative error {rel_aug:.3e}); "
                "nothing is returned"
            )
        extra["augmented_final_state_error_relative"] = rel_aug
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
        extra=extra,
    )
