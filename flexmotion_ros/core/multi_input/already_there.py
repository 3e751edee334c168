"""Moves shorter than the resolution with several inputs: answered "already there", for every method.

The single-input rule (:mod:`~flexmotion_ros.core.methods.already_there`) for
``m`` inputs: a goal within the resolution of the current state (a goal of
1e-15 m, a goal equal to the current position re-sent at rest a few ulps
off, a stop from a state moving at 1e-18) is the ``m``-input hold: zero
samples ``(0, m)``, zero duration, certified (nothing is faster than not
moving).  The same tests decide it
(:func:`~flexmotion_ros.core.methods.already_there.nearness`, with the gain of
each state summed over the inputs at their bounds):

* a state entry farther than twice ``FINAL_STATE_RTOL`` of one sample's reach
  bound is a move (the cheap, rigorous test: most plans stop here);
* entries differing by rounding only (``AT_REST_ULPS``) are already there, at
  any rate;
* else the empty sequence is checked by the multi-input exact final-state
  check every sampled plan passes (:func:`~.sampled_lp.finish_samples`:
  matrix exponentials of the full model, the error relative to one sample's
  reach): it passes, already there; it misses, a move to plan.

The resolution is the planning rate, or the configured rate (the node's) when
no rate is given.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from ..errors import SolverError
from ..methods.already_there import ROUNDING_MESSAGE, Nearness, nearness, within_reach_message
from ..results import SolverPath
from .dual import multi_state_scale
from .problem import MultiMoveProblem
from .response import MultiResponse
from .results import MultiCertificate, MultiProfile, MultiSampledProfile, SyncMode
from .sampled_lp import finish_samples


def multi_already_there(
    problem: MultiMoveProblem,
    method: str,
    rate_hz: float | None,
    resolution_hz: float | None,
    sync: SyncMode,
) -> tuple[MultiProfile, MultiSampledProfile | None] | None:
    """The ``m``-input hold, if the move is shorter than the resolution; else None (plan it).

    Parameters
    ----------
    problem : MultiMoveProblem
    method : str
        Names the result.
    rate_hz : float or None
        Planning rate (Hz), ``> 0``; None: no sampled plan requested.
    resolution_hz : float or None
        The resolution (Hz) when ``rate_hz`` is None (the configured rate);
        both None: no resolution, a move is planned.
    sync : SyncMode
        Reported on the profiles.

    Returns
    -------
    (MultiProfile, MultiSampledProfile or None) or None
        A zero-duration certified profile holding every input at 0 and, with a
        rate, the empty sequence ``(0, m)`` (the hold), both after the exact
        final-state check; None if the state is not within the tolerance of
        one sample's reach (a move to plan).
    """
    rate = rate_hz or resolution_hz
    if not rate:
        return None
    t0 = time.perf_counter()
    dt = 1.0 / float(rate)
    model, m = problem.model, problem.model.m
    x0, target, kept = problem.x0, problem.target_state(), problem.kept
    gains = np.abs(model.B()[1::2]) @ problem.u_max  # the velocity-like rows of B, every input at its bound
    near = nearness(gains, dt, x0, target, kept)
    if near is Nearness.MOVE:
        return None
    extra = {"already_there": True}
    if near is Nearness.ROUNDING:
        # the goal and the state differ by rounding only: the state is not known better than that
        dev = (x0 - target)[kept]
        scale = multi_state_scale(MultiResponse(problem), problem.shifted_initial(), problem.u_max, dt)
        hold = MultiSampledProfile(
            problem=problem,
            commands=np.zeros((0, m)),
            dt=dt,
            states=x0[None, :].copy(),
            final_state_error=float(np.max(np.abs(dev), initial=0.0)),
            final_state_error_relative=float(np.max(np.abs(dev) / scale, initial=0.0)),
            minimal=True,
            lower_bound_samples=0,
            proof="already there",
            method=method,
            solve_time_s=time.perf_counter() - t0,
            extra=extra,
        )
        message = ROUNDING_MESSAGE
    else:
        try:
            hold = finish_samples(
                problem, np.zeros((0, m)), dt, True, 0, "already there", math.nan, None, t0, extra, method
            )
        except SolverError:
            return None
        message = within_reach_message(hold.final_state_error_relative, float(rate))
    certificate = MultiCertificate(
        passed=True,
        costate_initial=np.zeros(kept.size),
        switch_residual=0.0,
        extra_zeros=0,
        unproved_cells=0,
        sign_consistent=True,
        hamiltonian_spread=0.0,
        lower_bound=0.0,
        duality_margin=0.0,
        message=message,
    )
    continuous = MultiProfile(
        problem=problem,
        switch_times=tuple(np.empty(0) for _ in range(m)),
        levels=tuple(np.zeros(1) for _ in range(m)),
        duration=0.0,
        final_state=x0.copy(),
        final_state_error=hold.final_state_error,
        final_state_error_relative=hold.final_state_error_relative,
        certificate=certificate,
        sync=sync,
        method=method,
        solve_time_s=time.perf_counter() - t0,
        extra={"solver_path": SolverPath.AT_REST, "already_there": True},
    )
    sampled = replace(hold, continuous=continuous, sync=sync) if rate_hz else None
    return continuous, sampled
