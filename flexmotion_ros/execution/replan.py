"""Closed-loop replanning from an estimated state, spliced ahead of the planning time (ROS-free).

Every ``feedback.replan_period_s`` during a move the node has an estimate of
the state (:mod:`flexmotion_ros.core.estimation`) at some sample ``k_e``;
:func:`~.replan_point.replan_point` carries it to the splice sample ``k_s``
ahead of the planning time and measures its deviation from the plan there.
:func:`replan` then decides:

* the estimate agrees with the prediction (deviation below ``min_deviation``
  of the move, or not significant against the estimate's covariance): the
  plan goes on unchanged -- with an exact model and no disturbance the
  closed loop is the open-loop plan, sample for sample;
* otherwise it plans from the predicted state to the same target (or a
  stop), with the node's planner (certified and verified like every plan),
  and returns the segment to splice at ``k_s``; the plan being executed
  there is the planner's warm start (:func:`warm_start_at`: the rest of its
  certified continuous optimum -- the same switch structure, nearby switch
  times -- so the switch-time Newton starts next to the answer; the planner
  solves cold if it does not converge, and the answer is the same);
* if planning fails, the current plan goes on and the outcome says why.

The node wiring (a later wave) calls :func:`replan` from its planning
thread and splices the segment as it splices a preemption.
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import Enum

import numpy as np
from scipy.stats import chi2

from ..core.config import PlannerConfig
from ..core.errors import FlexmotionError
from ..core.methods.table import plan_move
from ..core.model.boundary import state_to_rest
from ..core.model.modal_model import ModalModel
from ..core.results import BangBangProfile, PlanResult
from ..core.simulation.exact import modal_amplitudes
from ..core.time_optimal.warm_start import WarmStart, remainder
from .replan_point import ReplanPoint, replan_point
from .timeline import Segment
from .trajectory import timeline_commands

#: Replan only if the deviation exceeds this fraction of the move (see :func:`.replan_point.relative_deviation`).
MIN_DEVIATION = 1e-6
#: ... and is significant against the estimate's covariance: its Mahalanobis distance squared exceeds
#: this chi-square quantile (a deviation the noise explains is not corrected).
GATE_PROBABILITY = 0.999
#: A correction after arrival (the timeline sends only holds from the splice on) is planned at the bound
#: that does it in about this fraction of the slowest mode's period (:func:`correction_bound`), not at full force.
CORRECTION_PERIODS = 0.5
#: ... with this margin on the bound (the estimate of :func:`correction_bound` is rough: the plan then takes
#: about ``CORRECTION_PERIODS / CORRECTION_MARGIN**0.5`` periods).
CORRECTION_MARGIN = 2.0
#: A plan with less than this fraction of the slowest mode's period left is not replanned for a deviation a
#: gentle correction can take (it finishes, and what it leaves is corrected after arrival: see :func:`replan`).
FINISH_PERIODS = 0.25


class ReplanStatus(Enum):
    """What :func:`replan` decided (values: the strings diagnostics show)."""

    REPLANNED = "replanned"  # a new plan to splice at the sample given
    ON_PLAN = "on_plan"  # the estimate agrees with the timeline: nothing changes
    IDLE = "idle"  # no timeline: nothing to correct
    FAILED = "failed"  # the planner refused: the current plan goes on


@dataclass(frozen=True, kw_only=True)
class ReplanOutcome:
    """The decision and, if replanned, the segment to splice.

    Attributes
    ----------
    status : ReplanStatus
    point : ReplanPoint or None
    segment : Segment or None
        The new plan, ``start = point.sample`` (REPLANNED only).
    result : PlanResult or None
    reason : str
        Why (for diagnostics).
    plan_time_s : float
        Planning wall time (s), 0 if not planned.
    """

    status: ReplanStatus
    point: ReplanPoint | None = None
    segment: Segment | None = None
    result: PlanResult | None = None
    reason: str = ""
    plan_time_s: float = 0.0


@functools.lru_cache(maxsize=64)
def chi_square_gate(probability: float, dof: int) -> float:
    """The chi-square quantile the significance is gated at (cached: ``chi2.ppf`` costs more than a replan decision)."""
    return float(chi2.ppf(probability, dof))


def correction_bound(model: ModalModel, deviation: np.ndarray, u_max: float, duration_s: float) -> float:
    """The input bound (N) for a correction of ``deviation`` from rest that takes about ``duration_s``.

    Why: a time-optimal correction is bang-bang at the bound; at full force a
    small correction swings every mode by as much as the whole move did, and
    a model a few per cent off leaves a residual of that swing, not of the
    deviation -- the next correction is then no smaller, and the closed loop
    limit-cycles (5 % frequency error, replanning 0.4 s late: corrections for
    30-50 s).  At a bound proportional to the deviation the swing, and the
    residual the model error leaves, are proportional to it too: each
    correction shrinks what is left by about ``eps omega duration_s`` (model
    error ``eps``), and the loop converges.

    The estimate: the rigid body covers ``dp`` and loses ``dv`` in
    ``duration_s`` at ``(4 |dp| / T + 2 |dv|) / (|b0| T)``; a mode's amplitude
    ``a_i`` is cancelled in ``T`` at about ``a_i omega_i / (|b_i| T)``; the
    largest, times :data:`CORRECTION_MARGIN`, at most ``u_max``.
    """
    d = np.asarray(deviation, dtype=float)
    T = max(float(duration_s), 1e-9)
    need = (4.0 * abs(d[0]) / T + 2.0 * abs(d[1])) / (abs(model.b0) * T) if model.b0 else 0.0
    if model.n_modes:
        amps = modal_amplitudes(model, d)
        gains = np.maximum(np.abs(np.asarray(model.b, dtype=float)), 1e-300)
        need = max(need, float(np.max(amps * np.asarray(model.omega, dtype=float) / (gains * T))))
    return float(min(u_max, CORRECTION_MARGIN * need)) if need > 0.0 else float(u_max)


def plan_of(info) -> PlanResult | None:
    """The plan a segment's ``info`` records: a :class:`PlanResult`, or a record with one as ``result`` (a node's)."""
    if isinstance(info, PlanResult):
        return info
    result = getattr(info, "result", None)
    return result if isinstance(result, PlanResult) else None


def warm_start_at(timeline: Sequence[Segment], sample: int, dt: float) -> WarmStart | None:
    """The rest of the plan being executed at ``sample`` (global index), as a planner's warm start.

    The segment playing ``sample`` must record its plan (:func:`plan_of`)
    with a certified continuous optimum; its remainder after ``(sample -
    start) dt`` seconds is the guess (:func:`~flexmotion_ros.core.time_optimal.warm_start.remainder`).
    None otherwise (a shaped plan, a short move planned sampled-first, the hold).
    """
    for seg in timeline:
        if seg.start <= sample < seg.end:
            plan = plan_of(seg.info)
            profile = plan.continuous if plan is not None else None
            if not isinstance(profile, BangBangProfile):
                return None
            return remainder(profile, (sample - seg.start) * dt)
    return None


def replan(
    timeline: Sequence[Segment],
    k_next: int,
    lead: int,
    estimate,
    estimate_sample: int,
    *,
    config: PlannerConfig,
    target: float | None,
    covariance=None,
    move_size: float | None = None,
    min_deviation: float = MIN_DEVIATION,
    gate_probability: float = GATE_PROBABILITY,
    planner: Callable[..., PlanResult] = plan_move,
    warm_start: bool = False,
    gentle: bool = False,
) -> ReplanOutcome:
    """Decide whether to replan from the estimate, and plan if so (module docstring).

    Parameters
    ----------
    timeline, k_next, lead, estimate, estimate_sample, covariance, move_size
        As for :func:`~.replan_point.replan_point`.
    config : PlannerConfig
        The node's configuration (model, bound, rate, method).
    target : float or None
        The move's target (m); None: a stop (final position free).
    min_deviation : float
        Replan only above this deviation (fraction of the move).
    gate_probability : float
        With a covariance, replan only if the deviation's Mahalanobis
        distance squared exceeds this chi-square quantile (``n`` degrees of freedom).
    planner : callable
        ``planner(config, problem, rate_hz) -> PlanResult`` (default :func:`plan_move`);
        with a warm start, called ``planner(config, problem, rate_hz, warm_start=...)``.
    warm_start : bool
        Pass the rest of the plan being executed at the splice as the
        planner's warm start (:func:`warm_start_at`), if there is one.  Off
        by default (the node's choice too): the same optimum, but the
        bench's kicks change the optimum's structure in most states, and a
        failed warm attempt costs about what a hit saves.  Since the warm
        start gives up after one stalled Newton run
        (:data:`~flexmotion_ros.core.time_optimal.warm_start.NEAR_RESIDUAL`)
        the warm replan's median CPU time is 0.88-0.95x the cold one for one
        mode and 1.01-1.07x for two and three (it was up to 1.5x for three;
        ``bench/replan_latency.py --clock cpu``, seeds 0 and 1, 2026-12-05).
    gentle : bool
        After arrival (the timeline sends nothing but holds from the splice
        on), plan the correction at :func:`correction_bound` (at most
        ``u_max``): the time-optimal correction at that bound, certified as
        every plan, taking about :data:`CORRECTION_PERIODS` of the slowest
        mode's period; a plan with less than :data:`FINISH_PERIODS` of it
        left finishes first if the deviation is gently correctable; a
        correction is replanned at its own bound (or more if needed).
        False (default, what the node does for now): every replan at
        ``u_max``.  ROS-free, with a 15 % model error and a 0.4 s look-ahead
        it converges where full force limit-cycles
        (``test/execution/test_closed_loop.py``); in the lockstep node test
        under load (readings 0.2-0.8 s late) it kept correcting for over
        60 s: not yet the node's default.
    """
    model = config.model
    dt = 1.0 / config.rate_hz
    point = replan_point(
        timeline,
        k_next,
        lead,
        estimate,
        estimate_sample,
        model=model,
        dt=dt,
        covariance=covariance,
        move_size=move_size,
    )
    if point is None:
        return ReplanOutcome(status=ReplanStatus.IDLE, reason="no move to correct")
    if point.deviation <= min_deviation:
        return ReplanOutcome(
            status=ReplanStatus.ON_PLAN, point=point, reason=f"deviation {point.deviation:.2e} of the move"
        )
    if point.significance is not None:
        gate = chi_square_gate(gate_probability, model.n_states)
        if point.significance <= gate:
            return ReplanOutcome(
                status=ReplanStatus.ON_PLAN,
                point=point,
                reason=f"deviation {point.deviation:.2e} of the move is within the estimate's noise "
                f"(Mahalanobis^2 {point.significance:.3g} <= {gate:.3g})",
            )
    t0 = time.perf_counter()
    u_bound = config.u_max
    if gentle and model.n_modes:
        period = 2.0 * math.pi / min(model.omega)
        ahead = np.flatnonzero(timeline_commands(timeline, point.sample, max(seg.end for seg in timeline)))
        left_s = (int(ahead[-1]) + 1) * dt if ahead.size else 0.0
        if left_s == 0.0:
            # arrived: the correction at a bound proportional to it, so that a model error leaves a residual
            # proportional to it too (correction_bound's docstring)
            rest = model.rest_state(target if target is not None else float(point.state[0]))  # a stop: anywhere
            u_bound = correction_bound(model, point.state - rest, config.u_max, CORRECTION_PERIODS * period)
        elif left_s < FINISH_PERIODS * period and correction_bound(
            model, point.state - point.predicted, config.u_max, CORRECTION_PERIODS * period
        ) < float(config.u_max):
            # the plan's last part: a full-force replan this close to the end swings the modes as much as the
            # move and leaves a model error's residual of that swing; the plan finishes, what is left is
            # corrected (gently) after arrival
            return ReplanOutcome(
                status=ReplanStatus.ON_PLAN,
                point=point,
                reason=f"deviation {point.deviation:.2e} of the move: the plan arrives in {left_s:.3g} s, "
                "corrected after arrival",
            )
        else:
            # the rest of the plan at its own bound (a correction's stays gentle while it is replanned), or
            # more if the deviation needs it
            plan = plan_of(next((seg.info for seg in reversed(timeline) if seg.start <= point.sample), None))
            if plan is not None and plan.problem is not None:
                rest = model.rest_state(target if target is not None else float(point.state[0]))
                need = correction_bound(model, point.state - rest, config.u_max, CORRECTION_PERIODS * period)
                u_bound = min(float(config.u_max), max(float(plan.problem.u_max), need))
    problem = state_to_rest(model, u_bound, point.state, target)
    warm = warm_start_at(timeline, point.sample, dt) if warm_start else None
    try:
        if warm is None:
            result = planner(config, problem, config.rate_hz)
        else:
            result = planner(config, problem, config.rate_hz, warm_start=warm)
    except FlexmotionError as exc:
        took = time.perf_counter() - t0
        return ReplanOutcome(
            status=ReplanStatus.FAILED, point=point, reason=f"replan refused, the plan goes on: {exc}", plan_time_s=took
        )
    took = time.perf_counter() - t0
    s = result.sampled
    if s is None or not math.isfinite(float(s.final_state_error_relative)):
        return ReplanOutcome(
            status=ReplanStatus.FAILED, point=point, reason="the planner gave no sampled plan", plan_time_s=took
        )
    seg = Segment(np.asarray(s.commands, float), np.asarray(s.states, float), start=point.sample, info=result)
    return ReplanOutcome(
        status=ReplanStatus.REPLANNED,
        point=point,
        segment=seg,
        result=result,
        reason=f"deviation {point.deviation:.2e} of the move",
        plan_time_s=took,
    )


__all__ = [
    "GATE_PROBABILITY",
    "MIN_DEVIATION",
    "ReplanOutcome",
    "ReplanStatus",
    "CORRECTION_MARGIN",
    "CORRECTION_PERIODS",
    "FINISH_PERIODS",
    "chi_square_gate",
    "correction_bound",
    "plan_of",
    "replan",
    "warm_start_at",
]
