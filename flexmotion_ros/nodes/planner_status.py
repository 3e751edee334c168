"""The planner's status on ``/diagnostics``: :class:`StatusReporter`.

Holds what the planner reports -- ``idle`` / ``moving`` / ``error: <reason>``
(``inactive`` / ``unconfigured`` / ``finalized`` while not active, lifecycle),
the request being planned, the target, the last plan's figures and its stream
timing -- behind one lock, builds the ``(level, message, values)`` of the
status, and publishes it on ``/diagnostics`` on request and periodically from
its own thread.  The thread, not an executor timer: the planner's executor is
single-threaded and a plan (seconds for a limited move at 1 kHz) would
otherwise leave the status stale exactly when it matters.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.node import Node

from ..core.multi_input.dispatch import bounds_text, positions_text
from . import messages

DIAGNOSTIC_NAME = "flexmotion_planner: motion"
#: The status thread's own period (s): the ``tick`` callback runs this often, whatever ``period_s``.
TICK_S = 0.05


class StatusReporter:
    """The planner's motion status and its publication on ``/diagnostics``.

    Creates the ``/diagnostics`` publisher on ``node`` and (not yet started)
    the periodic publishing thread; :meth:`start` starts it, :meth:`stop`
    ends it.  The state setters are thread-safe.

    Parameters
    ----------
    node : rclpy.node.Node
        The planner: publisher, clock, logger and hardware id.
    period_s : float
        Period (s) of the status published from the thread.
    target : float or None
        The initial target (the initial position).
    context : callable
        Returns the node's own values of the status (position at rest, the
        configuration's figures, subscribers, ...), in the order they appear
        after ``state``, ``planning``, ``last_error`` and ``target``.
    tick : callable, optional
        Called from the thread every :data:`TICK_S` (the planner checks its
        writer-side matches there).
    """

    def __init__(
        self,
        node: Node,
        period_s: float,
        target: float | None,
        context: Callable[[], Mapping[str, Any]],
        tick: Callable[[], None] | None = None,
    ) -> None:
        self._node = node
        self._context = context
        self._tick = tick
        self._lock = threading.Lock()
        self._state = "idle"
        self._lifecycle = "unconfigured"
        self._planning = ""  # the request being planned ("" if none)
        self._last_error: str | None = None
        self._last: dict[str, Any] = {}
        self._move: object | None = None  # the move _last describes (moving())
        self._first: tuple[object | None, float] = (None, float("nan"))  # the last first command reported
        self._target: float | None = target
        self._pub = node.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._period = float(period_s)
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._deferred: deque[Callable[[], None]] = deque()
        self._thread = threading.Thread(target=self._loop, name="flexmotion-diagnostics", daemon=True)

    # ------------------------------------------------------------------ thread
    def start(self) -> None:
        """Start publishing every ``period_s``."""
        self._thread.start()

    def stop(self) -> None:
        """End the periodic publishing (waits up to 2 s for the thread)."""
        self._stop.set()
        self._wake.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)

    def defer(self, work: Callable[[], None]) -> None:
        """Run ``work`` in the status thread soon (within :data:`TICK_S`): keeps it off the caller's thread.

        The stream thread hands its end-of-move report here: statistics, log and
        /diagnostics must not delay the next sample.
        """
        self._deferred.append(work)
        self._wake.set()

    def _loop(self) -> None:
        due = time.monotonic() + self._period
        while not self._stop.is_set():
            self._wake.wait(min(TICK_S, max(0.0, due - time.monotonic())))
            self._wake.clear()
            if self._stop.is_set():
                return
            try:
                while self._deferred:
                    self._deferred.popleft()()
                if self._tick is not None:
                    self._tick()
                if time.monotonic() >= due:
                    due += self._period
                    self.publish()
            except Exception as exc:  # noqa: BLE001 -- a shutdown race (context gone) ends the loop
                if not self._stop.is_set():
                    self._node.get_logger().warning(f"/diagnostics: {type(exc).__name__}: {exc}")
                return

    # ------------------------------------------------------------------- state
    def set_planning(self, source: str) -> None:
        """Mark the request being planned (``""``: none)."""
        with self._lock:
            self._planning = source

    def set_lifecycle(self, label: str) -> None:
        """The node's lifecycle state (``unconfigured``, ``inactive``, ``active``, ``finalized``).

        Not active: the message is the label; activating resets the motion state to ``idle``.
        """
        with self._lock:
            if label == "active" or self._lifecycle != label:
                self._state = "idle"
            self._lifecycle = label

    def set_error(self, reason: str | None) -> None:
        """Set (or, with None, clear) the error the status reports."""
        with self._lock:
            self._last_error = reason

    def moving(self, target: float | None, info: Mapping[str, Any], move: object | None = None) -> None:
        """A move was installed: state ``moving``, its target and plan figures.

        Parameters
        ----------
        target : float or None
            Where the move ends.
        info : mapping
            The plan's figures, reported as ``last_plan.<key>`` (replaces the previous ones).
        move : object, optional
            What identifies the move (its record): a first command reported for it before this call
            (:meth:`first_command`) is kept.
        """
        with self._lock:
            self._state = "moving"
            self._target = target
            self._last = dict(info)
            self._move = move
            first_move, delay = self._first
            if move is not None and first_move is move:
                self._last["goal_to_first_command_s"] = delay

    def first_command(self, delay_s: float, move: object | None = None) -> None:
        """Record the time (s) from the goal to its first command.

        ``move`` (the object later given to :meth:`moving`): the stream may send the first command before
        the installing thread reports the move (the stream runs apart); the delay then waits for it.
        """
        with self._lock:
            self._first = (move, float(delay_s))
            if move is None or self._move is move:
                self._last["goal_to_first_command_s"] = float(delay_s)

    def finished(self, times: np.ndarray, lateness: np.ndarray) -> None:
        """The move ended: state ``idle`` and its stream timing.

        Parameters
        ----------
        times : numpy.ndarray
            Monotonic send times (s) of the move's samples; the timing is
            recorded only for more than 2.
        lateness : numpy.ndarray
            Their lateness (s) against their deadlines.
        """
        with self._lock:
            self._state = "idle"
            if times.size > 2:
                periods = np.diff(times)
                self._last.update(
                    stream_samples=int(times.size),
                    stream_period_median_ms=float(np.median(periods) * 1e3),
                    stream_period_p99_ms=float(np.percentile(periods, 99) * 1e3),
                    stream_period_max_ms=float(np.max(periods) * 1e3),
                    stream_lateness_max_ms=float(np.max(lateness) * 1e3),
                )

    # ----------------------------------------------------------------- status
    def status(self) -> tuple[int, str, dict[str, Any]]:
        """``(level, message, values)`` of the status on /diagnostics."""
        with self._lock:
            state, err, last, target, planning, lifecycle = (
                self._state,
                self._last_error,
                dict(self._last),
                self._target,
                self._planning,
                self._lifecycle,
            )
        level = DiagnosticStatus.ERROR if err else DiagnosticStatus.OK
        level = level[0] if isinstance(level, (bytes, bytearray)) else int(level)
        message = f"error: {err}" if err else (state if lifecycle == "active" else lifecycle)
        values: dict[str, Any] = {
            "state": state,
            "planning": planning,  # the request being planned right now ("" if none)
            "last_error": err or "",
            "target": target if target is not None else float("nan"),
            "lifecycle": lifecycle,
        }
        values.update(self._context())
        values.update({f"last_plan.{k}": v for k, v in last.items()})
        return level, message, values

    def publish(self) -> None:
        """Publish the status on /diagnostics now."""
        level, message, values = self.status()
        node = self._node
        self._pub.publish(
            messages.diagnostics(
                DIAGNOSTIC_NAME,
                node.get_fully_qualified_name(),
                level,
                message,
                values,
                node.get_clock().now().to_msg(),
            )
        )


class StatusGlue:
    """The planner node's side of its status (a mixin of :class:`~.planner_node.PlannerNode`).

    The values only the node knows (configuration, subscribers, ready stops,
    goals superseded), the writer-side readiness check the status thread
    ticks, and the publishing entry points the other mixins call.
    """

    def _status_context(self) -> dict[str, Any]:
        """The node's own values of the status on /diagnostics (after state, planning, last_error, target)."""
        return {
            "position_at_rest": self._position if np.ndim(self._position) == 0 else positions_text(self._position),
            "rate_hz": self._config.rate_hz,
            "method": self._config.method,
            "u_max": self._config.u_max if np.ndim(self._config.u_max) == 0 else bounds_text(self._config),
            "modes": self._config.model.n_modes,
            "command_joints": ",".join(self._joint_names),  # the joints of 'commands', in order
            "command_subscribers": self.commands_publisher.get_subscription_count(),
            "streaming_ready": self._command_subscribers > 0,
            "replan_lead_samples": self._lead_samples(),
            "ready_stops": len(self._stops.ready()) if self._stops is not None else 0,
            "goals_superseded": self._worker.superseded,  # by a newer goal before they were planned
            "goals_cancelled": self._worker.cancelled,  # by a stop or a deactivation
            **self._output_status(),
            **self._collector_status(),
            **self._feedback_status(),
            **self._identification_values(),
        }

    def _collector_status(self) -> dict[str, Any]:
        """Garbage collections run in the stream's slack per generation, and how many were forced (if enabled)."""
        col = self._collector
        if not col.enabled:
            return {}
        return {
            "gc_in_slack": "/".join(str(n) for n in col.collections),
            "gc_forced": "/".join(str(n) for n in col.forced),
        }

    def _check_streaming_ready(self) -> None:
        """Say when ``commands`` gets (or loses) its first subscriber, judged on the writer side (status thread).

        A late joiner may be matched only seconds after it starts (Fast DDS
        announces every ~3.6 s): the writer's matched count, not the reader's,
        says when samples published from now on reach it.
        """
        stream = getattr(self, "stream", None)
        if stream is not None and stream.idle and not stream.hold_when_idle:
            self._collector.idle()  # a silent idle stream has no deadline: collect what is due here
        n = self.commands_publisher.get_subscription_count()
        before, self._command_subscribers = self._command_subscribers, n
        if n > 0 and before == 0:
            topic = self.commands_publisher.topic_name
            self.get_logger().info(f"streaming ready: '{topic}' matched by {n} subscriber(s) (writer side)")
            self.publish_diagnostics()
        elif n == 0 and before > 0:
            self.get_logger().warning("'commands' lost its last subscriber: goals are refused until one matches")
            self.publish_diagnostics()

    def status(self) -> tuple[int, str, dict[str, Any]]:
        """``(level, message, values)`` of the status on /diagnostics."""
        return self._status.status()

    def publish_diagnostics(self) -> None:
        """Publish the status on /diagnostics now."""
        self._status.publish()


__all__ = ["DIAGNOSTIC_NAME", "StatusGlue", "StatusReporter"]
