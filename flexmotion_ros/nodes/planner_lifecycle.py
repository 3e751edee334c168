"""Lifecycle transitions of ``flexmotion_planner`` (a part of :class:`~.planner_node.PlannerNode`).

*configure* reads and validates the parameters and creates the interfaces (a
bad value: one line, the transition fails, nothing changes); *activate*
starts the stream and the stop preparer; *deactivate* cuts a move off with
the hold; *cleanup* destroys what configure created; *shutdown* ends like
deactivate; *error* sends the hold and returns to unconfigured.
"""

from __future__ import annotations

import gc
import sys
from typing import Any

from rclpy.lifecycle import LifecycleState, TransitionCallbackReturn

from ..core.errors import FlexmotionError
from ..execution.realtime import lower_threads, raise_threads
from ..execution.remote_stream import RemoteStream
from ..execution.stream_halt import StreamHalt

#: Python threads of the node that compute in-process: they keep normal scheduling.
NUMERIC_THREADS = ("flexmotion-learn", "flexmotion-identify")


class LifecycleTransitions:
    """The planner node's lifecycle callbacks (a mixin of :class:`~.planner_node.PlannerNode`)."""

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Read and validate the parameters, create the interfaces and the (stopped) stream."""
        self._configure_error = None
        before = self._entities()
        try:
            self._setup()
        except Exception as exc:  # noqa: BLE001 -- a bad parameter: one line, the node stays unconfigured
            self._configure_error = exc
            if isinstance(exc, FlexmotionError):
                self.get_logger().error(f"configure: {exc}")
            else:
                self.get_logger().error(f"configure: unexpected {type(exc).__name__}: {exc}")
            self._configured_entities = [e for e in self._entities() if e not in before]
            self._teardown()
            return TransitionCallbackReturn.FAILURE
        self._configured_entities = [e for e in self._entities() if e not in before]
        self._lifecycle = "inactive"
        self._status.set_lifecycle("inactive")
        return super().on_configure(state)

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Start streaming (``commands`` enabled first) and preparing stops."""
        ret = super().on_activate(state)
        if ret != TransitionCallbackReturn.SUCCESS:
            return ret
        self._raise_lock_sharers()
        self.stream.start()
        if self.stream.priority_error:
            self.get_logger().warning(self.stream.priority_error)
        elif isinstance(self.stream, RemoteStream) and self.stream.priority > 0:
            p = self.stream.priority
            self.get_logger().info(
                f"the command stream runs in process {self.stream.process.pid} under SCHED_FIFO {p} (its other "
                f"threads {max(1, p - 1)}); this process's threads "
                + (f"SCHED_FIFO {max(1, p - 2)}" if self._lock_sharers_raised else "keep normal scheduling")
                + (
                    f"; goal planning SCHED_FIFO {self._children.goal.boosted} for the first "
                    f"{self._children.goal.boost_budget_s * 1e3:.0f} ms of each plan"
                    if self._children is not None and self._children.goal.boosted
                    else ""
                )
            )
        self._stops.start()
        self._lifecycle = "active"
        self._status.set_lifecycle("active")
        self.get_logger().info(f"active: streaming 'commands' at {self._config.rate_hz:g} Hz")
        self.publish_diagnostics()
        return TransitionCallbackReturn.SUCCESS

    def _raise_lock_sharers(self) -> None:
        """With ``stream_priority`` p and planning in child processes: the node's other threads to SCHED_FIFO p-1.

        They share the interpreter lock with the stream; under normal scheduling any process could preempt
        one while it holds the lock (:mod:`~flexmotion_ros.execution.realtime`).  All threads of the process:
        ``ros2 run`` runs one node per process.  Deactivation lowers them again.  Threads that compute
        (identification, learning) stay under normal scheduling; planning happens in the children.
        """
        priority = self.stream.priority
        self._lock_sharers_raised = False
        if priority <= 0 or self._children is None:
            return
        # goals are planned at the start of a plan under SCHED_FIFO too (below every thread of the stream's),
        # for plan_process.BOOST_BUDGET_S of each: else any busy process delays the move's first command
        error = self._children.goal.boost(max(1, priority - 3))
        if error:
            self.get_logger().warning(f"goal planning keeps normal scheduling: {error}")
        if isinstance(self.stream, RemoteStream):
            # The stream shares no lock with this process: its threads go two steps below the stream (below the
            # stream process's own), so that a loaded machine does not delay a stop's answer and splice.
            error = raise_threads(max(1, priority - 2), keep_normal=NUMERIC_THREADS)
            if error:
                self.get_logger().warning(error)
            self._lock_sharers_raised = error is None
            return
        self._collector.enable()  # a collection holds the lock as well: collections in the stream's slack
        error = raise_threads(max(1, priority - 1), keep_normal=NUMERIC_THREADS)
        if error:
            self.get_logger().warning(error)
            return
        # a thread waiting for the lock asks its holder to drop it after the switch interval (5 ms by default):
        # a quarter of a period keeps a busy holder from costing the stream a sample
        switch_s = min(sys.getswitchinterval(), 0.25 / self._config.rate_hz)
        sys.setswitchinterval(switch_s)
        self._lock_sharers_raised = True
        self.get_logger().info(
            f"threads sharing the interpreter lock with the stream: SCHED_FIFO {max(1, priority - 1)}; "
            f"lock switch interval {switch_s * 1e3:.2g} ms; garbage collection in the stream's slack"
        )

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Cut a move off with the hold, stop streaming; then disable ``commands``."""
        self._lifecycle = "inactive"  # goals are refused from now on
        self._worker.cancel("the planner was deactivated")
        self._end_stream("deactivated")
        self._collector.disable()  # automatic collection again
        if self._lock_sharers_raised:  # no stream, no reason to outrank the machine's other processes
            lower_threads()
            self._lock_sharers_raised = False
        if self._children is not None:
            self._children.goal.boost(0)
        self._status.set_lifecycle("inactive")
        self.publish_diagnostics()
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Destroy what configure created; the parameters stay declared."""
        self._teardown()
        self._lifecycle = "unconfigured"
        self.get_logger().info("cleaned up: unconfigured")
        return super().on_cleanup(state)

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Whatever the state: the hold if streaming, then stop everything (the node is finalized)."""
        if self._lifecycle in ("inactive", "active"):
            self._end_stream("shutdown")
        self._collector.disable()
        self._lifecycle = "finalized"
        status = getattr(self, "_status", None)
        if status is not None:
            status.set_lifecycle("finalized")
            status.stop()
        return super().on_shutdown(state)

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        """A transition raised: the hold, then back to unconfigured."""
        if self._lifecycle in ("inactive", "active"):
            self._end_stream("lifecycle error")
        self._teardown()
        self._lifecycle = "unconfigured"
        return TransitionCallbackReturn.SUCCESS

    def _end_stream(self, why: str) -> StreamHalt | None:
        """Stop preparing stops, stop the stream with the hold, and say so in the log."""
        if self._stops is not None:
            self._stops.stop()
        stream = getattr(self, "stream", None)
        if stream is None:
            return None
        halt = stream.stop(why)
        self._log_halt(halt)
        return halt

    def _log_halt(self, halt: StreamHalt) -> None:
        try:
            log = self.get_logger()
            if not halt.held:
                log.error(halt.describe())
            elif halt.interrupted:
                log.warning(halt.describe())
            else:
                log.info(halt.describe())
        except Exception:  # noqa: BLE001, S110 -- the logger can be gone at interpreter exit
            pass

    def _on_stream_fault(self, halt: StreamHalt) -> None:
        """From the stream thread: a fault ended the stream (the hold already sent)."""
        self._log_halt(halt)
        self._status.set_error(f"{halt.describe()}; deactivate and activate to stream again")
        self.publish_diagnostics()

    def _entities(self) -> list[tuple[str, Any]]:
        return (
            [("subscription", e) for e in self.subscriptions]
            + [("service", e) for e in self.services]
            + [("publisher", e) for e in self.publishers]
            + [("timer", e) for e in self.timers]
            + [("guard", e) for e in self.guards]
        )

    def _teardown(self) -> None:
        """Undo configure: threads stopped, interfaces destroyed (the parameters stay)."""
        worker = getattr(self, "_worker", None)
        if worker is not None:
            worker.stop("the planner was cleaned up")
        self._feedback_close()
        if self._stops is not None:
            self._stops.stop()
            self._stops = None
        status = getattr(self, "_status", None)
        if status is not None:
            status.stop()
        stream = getattr(self, "stream", None)
        if stream is not None:
            stream.stop("cleanup")
            if isinstance(stream, RemoteStream):
                stream.close()
            sys.setswitchinterval(self._switch_interval)
            del self.stream
        listener = getattr(self, "_listener", None)
        if listener is not None:
            self._listener = None
            listener.close()
        self._close_identification()
        destroy = {
            "subscription": self.destroy_subscription,
            "service": self.destroy_service,
            "publisher": self.destroy_lifecycle_publisher,
            "timer": self.destroy_timer,
            "guard": self.destroy_guard_condition,
        }
        for kind, entity in self._configured_entities:
            destroy[kind](entity)
        self._configured_entities = []
        self._unfreeze_gc()

    def _unfreeze_gc(self) -> None:
        """Undo configure's ``gc.freeze()``: what it froze may be collected again (cleanup, destroy)."""
        if getattr(self, "_froze_gc", False):
            self._froze_gc = False
            gc.unfreeze()
