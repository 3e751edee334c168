"""The output of ``flexmotion_planner``: ``output`` and ``command_interface`` (a part of :class:`~.planner_node.PlannerNode`).

``output: stream`` (default): one value per sample on ``commands``
(``std_msgs/Float64MultiArray``), the hold on every ending.
``output: trajectory``: the whole planned sequence as
``trajectory_msgs/JointTrajectory`` on ``trajectory.topic`` (reliable, depth
10), ``header.stamp`` = the first point's sample instant on the node's clock,
one point per sample (:mod:`flexmotion_ros.execution.trajectory`); every
preemption, stop or replan publishes the replacement from the sample being
played; every ending (shutdown, deactivation, fault) a one-point hold
trajectory.  A move from idle starts ``trajectory.start_delay_s`` ahead, and a
preemption is spliced at least that far ahead (the look-ahead grows by it):
the time a trajectory has to reach the receiver.

``command_interface``: ``effort`` (the force), ``velocity`` or ``position``
(the reference of a servo-driven joint, exact from the plan; the model's input
is then the joint's acceleration, ``model.c`` must be 0).  The logic is
:mod:`flexmotion_ros.execution.output`; this module creates the publisher
and the stream, and converts messages.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory as JointTrajectoryMsg

from ..core.model.modal_model import ModalModel
from ..core.multi_input.dispatch import AnyConfig, check_single_input_features, n_inputs
from ..execution.command_stream import CommandStream
from ..execution.output import OutputMode, OutputSettings, OutputStream, forward_hold, output_settings
from ..execution.trajectory import NS, JointTrajectory
from . import messages
from .trajectory_messages import trajectory_msg

#: Parameters that several inputs take at their default only (name, the default).

#: The trajectory topic: reliable, keep last 10 (a joint_trajectory_controller's subscription matches it).
TRAJECTORY_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)


def check_output(values: dict[str, Any], config: AnyConfig) -> OutputSettings:
    """The output settings for these parameter values (ConfigError names the bad one).

    Several inputs (``model.inputs``, issue 12) stream forces on ``commands``
    only: ``output: trajectory``, a velocity / position ``command_interface``
    and closed-loop replanning (``feedback.replan_period_s``) are one-input
    features for now and are refused at configure time.
    """
    if isinstance(config.model, ModalModel):
        return output_settings(values, config.model)
    check_single_input_features(config, values)  # the verdict flexmotion plan gives on the same file
    return OutputSettings()


class OutputGlue:
    """The planner node's output (a mixin of :class:`~.planner_node.PlannerNode`; before :class:`GoalHandling`)."""

    def _output_publisher(self, values: dict[str, Any], command_qos: QoSProfile):
        """Validate the output and create its lifecycle publisher (kept as ``commands_publisher``)."""
        self._output: OutputSettings = check_output(values, self._config)
        if self._output.mode is OutputMode.STREAM:
            return self.create_lifecycle_publisher(Float64MultiArray, "commands", command_qos)
        return self.create_lifecycle_publisher(JointTrajectoryMsg, self._output.topic, TRAJECTORY_QOS)

    def _output_stream(self, rate: float, hold_when_idle: bool, **kwargs: Any) -> CommandStream:
        """The command stream of the configured output (``kwargs``: as for :class:`CommandStream`)."""
        m = n_inputs(self._config)  # values per sample: one per input (fixed at start-up)
        if m > 1:  # several inputs: forces on 'commands', m values per sample (check_output refused the rest)
            msg = messages.command(0.0, m)
            hold = [0.0] * m

            def publish_row(value) -> None:
                self._record_sent(value)  # the commands actually sent, for identification (planner_identify.py)
                msg.data = hold if np.ndim(value) == 0 else value.tolist()  # a row, or the hold (HOLD: 0 on all)
                self.commands_publisher.publish(msg)

            return CommandStream(rate, publish_row, hold_when_idle, **kwargs)
        msg = messages.command(0.0)

        def publish(value: float) -> None:
            # the setpoint of the interface; identification records the model input (on_publish below)
            msg.data[0] = value
            self.commands_publisher.publish(msg)

        def publish_trajectory(traj: JointTrajectory) -> None:
            self.commands_publisher.publish(trajectory_msg(traj))

        return OutputStream(
            rate,
            publish,
            hold_when_idle,
            settings=self._output,
            model=self._config.model,
            joint_name=self._state.joint_name,
            publish_trajectory=publish_trajectory,
            ros_ns=self._ros_ns_of,
            on_sample=getattr(self, "_feedback_sample", None),
            on_publish=getattr(self, "_record_sent", None),  # the model inputs sent, for identification
            on_start_now=getattr(self, "_feedback_move_start", None),
            **kwargs,
        )

    def _ros_ns_of(self, t: float) -> int:
        """The node's clock (ns) at the stream clock's time ``t`` (s)."""
        if self._ros_time_stream:
            return round(t * NS)
        now_ros = self.get_clock().now().nanoseconds
        return now_ros + round((t - time.monotonic()) * NS)

    # ---- the delayed start of output: trajectory (the stream pads it with hold samples)
    def _start_delay(self) -> int:
        stream = getattr(self, "stream", None)
        return stream.splice_margin if isinstance(stream, OutputStream) else 0

    def _lead_samples(self) -> int:
        """The look-ahead of a preemption, plus the trajectory's transport margin."""
        return super()._lead_samples() + self._start_delay()

    def _idle_start_state(self, execute: bool) -> np.ndarray:
        """From idle: the state the machine reaches after the start delay's hold (the state itself at rest)."""
        x = super()._idle_start_state(execute)
        d = self._start_delay()
        return forward_hold(self._config.model, x, d, self.stream.dt) if d and execute else x

    def _idle_moving_state(self) -> np.ndarray | None:
        x = super()._idle_moving_state()
        d = self._start_delay()
        return forward_hold(self._config.model, x, d, self.stream.dt) if d and x is not None else x

    def _output_status(self) -> dict[str, Any]:
        """Values of the status on /diagnostics."""
        out = {"output": self._output.mode.value, "command_interface": self._output.interface.value}
        stream = getattr(self, "stream", None)
        if self._output.mode is OutputMode.TRAJECTORY and isinstance(stream, OutputStream):
            out["trajectory.topic"] = self.commands_publisher.topic_name
            out["trajectories_published"] = stream.trajectories_published
            out["hold_trajectories_published"] = stream.holds_published
        return out


__all__ = ["TRAJECTORY_QOS", "OutputGlue", "check_output"]
