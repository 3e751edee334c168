"""The command stream of ``flexmotion_planner``: its publisher, clock and events (a part of :class:`~.planner_node.PlannerNode`).

The stream itself is ROS-free (:class:`~flexmotion_ros.execution.CommandStream`);
here it gets the ``commands`` publisher, the node's clock under
``use_sim_time``, and the callbacks that report a move's first command and
its end on ``/diagnostics``.
"""

from __future__ import annotations

import time
from typing import Any

from ..core.multi_input.dispatch import positions_text
from ..execution import Segment
from ..execution.splice import StopPreparer
from .planner_goals import MoveRecord

#: Under ``use_sim_time``, the stream's sleep polls the ROS clock this often (wall s).
SIM_TIME_POLL_S = 0.0005


class StreamGlue:
    """The planner node's command stream (a mixin of :class:`~.planner_node.PlannerNode`)."""

    def _make_stream(self, v: dict[str, Any], rate: float) -> None:
        """The command stream on ``commands`` (stopped until activate) and the ready-stop preparer."""
        # use_sim_time: the node's ROS clock (it follows /clock); else the monotonic wall clock, as always
        self._ros_time_stream = bool(self.get_parameter("use_sim_time").value)
        clock_pair = self._ros_clock_pair() if self._ros_time_stream else {}
        # a CommandStream publishing the configured output (planner_output: stream or trajectory, the interface)
        self.stream = self._output_stream(
            rate,
            bool(v["publish_hold_when_idle"]),
            on_start=self._on_segment_start,
            on_finish=self._on_move_finished,
            priority=int(v["stream_priority"]),
            on_fault=self._on_stream_fault,
            after_sample=self._collector,
            **clock_pair,
        )
        # stops kept ready for the running move (started on activate)
        self._stops = StopPreparer(
            self._plan_stop,
            self.stream.snapshot,
            lambda: self._config,
            self._wants_ready_stops,
            rate,
            paused=self._planning_a_goal,
        )

    def _ros_clock_pair(self) -> dict[str, Any]:
        """``clock`` and ``sleep`` of the stream on the node's ROS clock (``use_sim_time``: /clock drives it).

        The sleep polls the ROS clock every :data:`SIM_TIME_POLL_S` wall
        seconds (a simulator may run slower or faster than real time, or
        pause) and returns early once the stream is stopping.
        """
        ros_clock = self.get_clock()

        def clock() -> float:
            return ros_clock.now().nanoseconds * 1e-9

        def sleep(seconds: float) -> None:
            end = clock() + seconds
            while True:
                left = end - clock()
                stream = getattr(self, "stream", None)
                if left <= 0.0 or stream is None or not stream.running:
                    return
                time.sleep(min(left, SIM_TIME_POLL_S))

        return {"clock": clock, "sleep": sleep}

    def _ros_time_of(self, k: int) -> float:
        """ROS time (s) at which global sample ``k`` is (or was) due."""
        if self._ros_time_stream:  # the stream runs on ROS time already
            return self.stream.time_of(k)
        now_ros = self.get_clock().now().nanoseconds * 1e-9
        return now_ros + (self.stream.time_of(k) - time.monotonic())

    def _on_segment_start(self, seg: Segment) -> None:
        self._identification_segment_started(seg)
        rec = seg.info
        if isinstance(rec, MoveRecord) and rec.from_idle:
            self._sent_at_start = self.stream.samples_sent - 1
        if isinstance(rec, MoveRecord):  # from idle, or a preemption / stop: request -> its first command
            self._status.first_command(seg.started_at - rec.requested_at)

    def _on_move_finished(self, seg: Segment) -> None:
        self._identification_move_ended()
        # called in the stream thread: the statistics, the log line and /diagnostics go to the status
        # thread (measured: done here, they delayed the next samples by tens of ms under load)
        n, sent = self.stream.samples_sent - self._sent_at_start, self.stream.samples_sent
        position = self._position

        def report() -> None:
            times, late = self.stream.recent_timing(n, before=self.stream.samples_sent - sent)
            self._status.finished(times, late)
            self.get_logger().info(f"move finished, at rest at {positions_text(position)}")
            self.publish_diagnostics()

        self._status.defer(report)
