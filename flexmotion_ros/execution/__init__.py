"""Execution of plans, ROS-free: the command stream and preemption.

What the planner node does between a plan and the ``commands`` topic,
without rclpy or messages (the node keeps parameters, messages, publishing
and logging):

* :mod:`.timeline` -- :class:`Segment` (a planned command sequence at a
  global sample index) and the state a timeline predicts at a sample;
* :mod:`.splice` -- where a goal during a move is spliced in (the splice
  sample, the predicted state there), the look-ahead policy, and the
  :class:`StopPreparer` that keeps verified stops ready for the current move;
* :mod:`.command_stream` -- :class:`CommandStream`, the absolute-deadline
  loop with the clock, the sleep and the publisher injected; every halt
  (stop, fault) sends the hold and says why (:class:`StreamHalt`);
* :mod:`.requests` -- the planning thread's requests: the newest goal wins
  (superseded goals counted), a stop cancels the goal being planned, plan-only
  queries wait in a bounded queue;
* :mod:`.measured_state` -- the machine's measured state: settings, the
  state vector from joint names, staleness;
* :mod:`.summary` -- the plan's figures the planner reports;
* :mod:`.trajectory` -- a plan as ``JointTrajectory`` data a
  ``joint_trajectory_controller`` plays exactly, and the replacement after a splice;
* :mod:`.jtc` -- the JTC's sampling rule and update loop, re-implemented;
* :mod:`.replan` -- closed-loop replanning from an estimated state (:mod:`.replan_point`: where it starts).
"""

from .command_stream import CommandStream
from .jtc import HeldPiece, TrajectoryPlayer, held_pieces, sample, started
from .measured_state import MeasuredState, StateSettings, StateSource, state_settings, state_vector
from .replan import ReplanOutcome, ReplanStatus, replan
from .replan_point import ReplanPoint, replan_point
from .requests import Request, RequestKind, RequestWorker
from .splice import (
    DEFAULT_PLAN_TIME_S,
    PLAN_TIME_FACTOR,
    PLAN_TIME_MARGIN_S,
    PLAN_TIME_WINDOW,
    SPLICE_ATTEMPTS,
    ReadyStop,
    SplicePoint,
    StopPreparer,
    ended_at_rest,
    lead_samples,
    longer_lead,
    splice_point,
)
from .stream_halt import HaltCause, StreamHalt, StreamStep
from .summary import plan_summary
from .timeline import HOLD, Segment, predicted_state
from .trajectory import (
    Interpolation,
    JointTrajectory,
    ReceiverSettings,
    SampleClock,
    TrajectoryPoint,
    encode,
    timeline_commands,
    timeline_trajectory,
)

__all__ = [
    "DEFAULT_PLAN_TIME_S",
    "HOLD",
    "PLAN_TIME_FACTOR",
    "PLAN_TIME_MARGIN_S",
    "PLAN_TIME_WINDOW",
    "SPLICE_ATTEMPTS",
    "CommandStream",
    "HaltCause",
    "MeasuredState",
    "ReadyStop",
    "Request",
    "RequestKind",
    "RequestWorker",
    "StateSettings",
    "StateSource",
    "StopPreparer",
    "StreamHalt",
    "Segment",
    "SplicePoint",
    "StreamStep",
    "ended_at_rest",
    "lead_samples",
    "longer_lead",
    "plan_summary",
    "predicted_state",
    "splice_point",
    "state_settings",
    "state_vector",
    # trajectory output, the JTC's rule, replanning (issue 14)
    "HeldPiece",
    "Interpolation",
    "JointTrajectory",
    "ReceiverSettings",
    "ReplanOutcome",
    "ReplanPoint",
    "ReplanStatus",
    "SampleClock",
    "TrajectoryPlayer",
    "TrajectoryPoint",
    "encode",
    "held_pieces",
    "replan",
    "replan_point",
    "sample",
    "started",
    "timeline_commands",
    "timeline_trajectory",
]
