"""Where a replan starts: the estimate carried to the splice sample, and how far it is from the plan there (ROS-free).

Every ``feedback.replan_period_s`` during a move the node has an estimate of
the state (:mod:`flexmotion_ros.core.estimation`) at some sample ``k_e``.
:func:`replan_point` carries it forward with the commands the timeline will
send anyway, to the splice sample ``k_s = k_next + lead`` (the look-ahead of
:func:`~.splice.lead_samples`, which covers the planning time, as for a
preemption), and compares it with what the timeline predicts there
(:func:`relative_deviation`: what the difference would leave at the end if
nothing corrected it, as a fraction of the move).  :func:`~.replan.replan`
decides on that.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..core.errors import GoalError
from ..core.model.modal_model import ModalModel
from ..core.simulation.exact import modal_amplitudes, step_matrices
from .timeline import Segment, predicted_state
from .trajectory import timeline_commands


@dataclass(frozen=True, kw_only=True)
class ReplanPoint:
    """Where a replan would start, and how far the estimate is from the plan there.

    Attributes
    ----------
    sample : int
        The splice sample ``k_s`` (global index).
    state : ndarray
        The estimated state carried to ``k_s`` with the timeline's commands.
    predicted : ndarray
        What the timeline predicts at ``k_s``.
    deviation : float
        :func:`relative_deviation` of the two (fraction of the move).
    significance : float or None
        Mahalanobis distance squared of the deviation against the carried
        covariance (None without a covariance).
    lead : int
        ``k_s - k_next`` (samples).
    """

    sample: int
    state: np.ndarray
    predicted: np.ndarray
    deviation: float
    significance: float | None
    lead: int


def relative_deviation(model: ModalModel, deviation: np.ndarray, move_size: float, horizon_s: float) -> float:
    """How large a state deviation is, as a fraction of the move (dimensionless).

    ``max(|dp|, |dv| horizon_s, amplitude of each mode's deviation) / move_size``:
    what it would leave at the end if nothing corrected it -- a velocity error
    drifts for ``horizon_s`` (the rest of the timeline), a mode's error
    vibrates with its amplitude.
    """
    d = np.asarray(deviation, dtype=float)
    amps = modal_amplitudes(model, d) if model.n_modes else np.zeros(0)
    worst = max(abs(d[0]), abs(d[1]) * max(horizon_s, 0.0), *(amps.tolist() or [0.0]))
    return float(worst / move_size)


def timeline_move_size(timeline: Sequence[Segment]) -> float:
    """The size of the timeline's move (m): how far its predicted position travels (1 if it does not)."""
    if not timeline:
        return 1.0
    p = np.concatenate([seg.states[:, 0] for seg in timeline])
    span = float(np.max(p) - np.min(p))
    return span if span > 0.0 else 1.0


def carry(model: ModalModel, dt: float, x, P, commands) -> tuple[np.ndarray, np.ndarray | None]:
    """State (and covariance, if given) carried over ``commands`` (exact ZOH, no process noise)."""
    Phi, Gam = step_matrices(model.A(), model.B(), dt)
    x = np.array(x, dtype=float)
    P = None if P is None else np.array(P, dtype=float)
    for u in commands:
        x = Phi @ x + Gam * u
        if P is not None:
            P = Phi @ P @ Phi.T
    return x, P


def replan_point(
    timeline: Sequence[Segment],
    k_next: int,
    lead: int,
    estimate,
    estimate_sample: int,
    *,
    model: ModalModel,
    dt: float,
    covariance=None,
    move_size: float | None = None,
) -> ReplanPoint | None:
    """The splice sample, the estimated state carried there, and its deviation from the plan.

    Parameters
    ----------
    timeline : sequence of Segment
        The stream's queued segments (empty: idle).
    k_next : int
        The sample the stream sends next.
    lead : int
        Look-ahead (samples) covering the planning time (:func:`~.splice.lead_samples`).
    estimate : array_like
        The estimated state before command ``estimate_sample`` (``[p, v, q_1, q_1', ...]``).
    estimate_sample : int
        Its global sample index (``<= k_next + lead``).
    model : ModalModel
    dt : float
        Sample period (s).
    covariance : array_like, optional
        The estimate's covariance (enables the significance test).
    move_size : float, optional
        Default: :func:`timeline_move_size`.

    Returns
    -------
    ReplanPoint or None
        None when idle.

    Raises
    ------
    GoalError
        The estimate is later than the splice, or has the wrong size.
    """
    if not timeline:
        return None
    k_s = k_next + lead
    if estimate_sample > k_s:
        raise GoalError("estimate_sample", f"the estimate (sample {estimate_sample}) is later than the splice ({k_s})")
    x = np.asarray(estimate, dtype=float).ravel()
    if x.size != model.n_states:
        raise GoalError("estimate", f"must have {model.n_states} entries, got {x.size}")
    commands = timeline_commands(timeline, estimate_sample, k_s)
    xs, Ps = carry(model, dt, x, covariance, commands)
    pred = predicted_state(timeline, k_s)
    d = xs - pred
    horizon = max(timeline[-1].end - k_s, 1) * dt
    dev = relative_deviation(model, d, move_size or timeline_move_size(timeline), horizon)
    sig = None
    if Ps is not None:
        sig = float(d @ np.linalg.lstsq(Ps, d, rcond=1e-12)[0])
    return ReplanPoint(sample=k_s, state=xs, predicted=pred, deviation=dev, significance=sig, lead=lead)


__all__ = ["ReplanPoint", "carry", "relative_deviation", "replan_point", "timeline_move_size"]
