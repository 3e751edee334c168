"""Closed-loop replanning of ``flexmotion_planner`` (a part of :class:`~.planner_node.PlannerNode`).

``feedback.replan_period_s > 0``: during a move, a thread wakes every period,
asks the state estimator (:class:`~flexmotion_ros.execution.feedback.StreamEstimator`:
a Kalman filter on the planner's model, fed by the stream with every command
sent and by an internal reliable subscription to the plant's ``measurements``
-- physical coordinates ``measurement.names`` through ``measurement.map``,
which must observe every mode) for the state before the next sample, and calls
:func:`~flexmotion_ros.execution.replan.replan`: on plan (the estimate agrees
with the timeline: nothing changes -- with an exact model and no disturbance
the move is the open-loop plan, sample for sample), or a new plan to the same
target from the state predicted at the splice ``k_next + lead`` (the
look-ahead of a preemption), certified and verified like every plan, spliced
there if the timeline has not changed meanwhile.  A replan that fails leaves
the current plan running; ``/diagnostics`` says why (``feedback.*``).  No
replan while a goal is being planned (the goal replaces the move anyway).

A reading is paired with the command sent last before its stamp (a lockstep
plant stamps each reading with its command's send time: exact; a real-time
plant stamps its own ticks: within one sample).  Closed-loop replanning needs
``output: stream`` for now (the commands' send times); each plan then keeps
holding for a settle window (two periods + 0.2 s) in which the loop can still
correct what it left.
"""

from __future__ import annotations

import math
import threading
import time
from typing import Any

import numpy as np
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import JointState

from ..core.errors import ConfigError, ModelError
from ..core.model.measurement import measurement_map
from ..execution.feedback import FeedbackSettings, StreamEstimator, feedback_settings, stale_reason
from ..execution.output import OutputMode
from ..execution.replan import ReplanStatus, replan
from ..execution.splice import PLAN_TIME_WINDOW, lead_samples
from ..execution.summary import plan_summary
from ..execution.timeline import Segment
from .planner_moves import MoveRecord
from .plant_measurements import MEASUREMENT_QOS
from .plant_measurements import TOPIC as MEASUREMENTS_TOPIC

#: The settle window after each plan: two replanning periods and this (s), see :meth:`FeedbackGlue._feedback_setup`.
SETTLE_EXTRA_S = 0.2


class FeedbackGlue:
    """The planner node's closed-loop replanning (a mixin of :class:`~.planner_node.PlannerNode`)."""

    _estimator: StreamEstimator | None = None

    def _feedback_setup(self, values: dict[str, Any]) -> None:
        """Validate ``feedback.*``; with a period, the estimator, its subscription and the replanning thread."""
        self._fb: FeedbackSettings = feedback_settings(values)
        self._estimator = None
        self._fb_counts = {"replanned": 0, "on_plan": 0, "failed": 0, "skipped": 0}
        self._fb_last = ""
        self._fb_last_failure = ""
        self._fb_plan_times: list[float] = []
        self._fb_thread: threading.Thread | None = None
        self._fb_stop = threading.Event()
        if not self._fb.enabled:
            return
        if self._output.mode is not OutputMode.STREAM:
            raise ConfigError(
                "feedback.replan_period_s",
                "closed-loop replanning needs output: stream for now (the filter pairs each measured state with "
                "the command that produced it); set it to 0.0 with output: trajectory",
            )
        model = self._config.model
        self._fb_map = measurement_map(values, model.n_modes)
        C, D = self._fb_map.for_model(model)
        try:
            self._estimator = StreamEstimator(model, 1.0 / self._config.rate_hz, self._fb, C, D)
        except ModelError as exc:
            raise ConfigError(
                "measurement.map",
                f"closed-loop replanning needs measurements that observe every mode: {exc.reason} "
                f"(measured: {list(self._fb_map.names)})",
            ) from None
        # every plan keeps holding for two periods and 0.2 s after its last command: the window in which the
        # loop still sees the machine and can correct it (otherwise the move would end with what it left)
        self.stream.settle_samples = math.ceil((2.0 * self._fb.replan_period_s + SETTLE_EXTRA_S) * self._config.rate_hz)
        self._fb_node = Node(
            f"{self.get_name()}_feedback",
            namespace=self.get_namespace(),
            context=self.context,
            use_global_arguments=False,
            start_parameter_services=False,
        )
        self._fb_topic = self.resolve_topic_name(MEASUREMENTS_TOPIC)
        self._fb_node.create_subscription(JointState, self._fb_topic, self._on_reading, MEASUREMENT_QOS)
        self._fb_executor = SingleThreadedExecutor(context=self.context)
        self._fb_executor.add_node(self._fb_node)
        self._fb_spin = threading.Thread(target=self._fb_spin_loop, name="flexmotion-feedback-sub", daemon=True)
        self._fb_spin.start()
        self._fb_thread = threading.Thread(target=self._feedback_loop, name="flexmotion-feedback", daemon=True)
        self._fb_thread.start()

    def feedback_subscribed(self) -> bool:
        """The feedback's ``measurements`` subscription is matched by a publisher (the plant)."""
        node = getattr(self, "_fb_node", None)
        if node is None:
            return False
        return node.count_publishers(self._fb_topic) > 0

    def _fb_spin_loop(self) -> None:
        try:
            self._fb_executor.spin()
        except Exception:  # noqa: BLE001, S110 -- the context was shut down under us
            pass

    def _feedback_close(self) -> None:
        """Stop the thread and the subscription (destroy, cleanup; nothing if never set up)."""
        stop = getattr(self, "_fb_stop", None)
        if stop is None:
            return
        stop.set()
        thread = getattr(self, "_fb_thread", None)
        if thread is not None:
            thread.join(timeout=5.0)
            self._fb_thread = None
        executor = getattr(self, "_fb_executor", None)
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)
            self._fb_spin.join(timeout=2.0)
            self._fb_node.destroy_node()
            self._fb_executor = None
        self._estimator = None

    # ------------------------------------------------------------- the filter
    def _feedback_sample(self, k: int, u: float, t_ns: int) -> None:
        """The stream thread: command ``u`` sent at sample ``k``, at system time ``t_ns``."""
        est = self._estimator
        if est is not None:
            est.command(k, u, t_ns)

    def _feedback_move_start(self, seg: Segment) -> None:
        """A move from idle is installed: the filter restarts at its start state when its first command goes out."""
        est = self._estimator
        if est is not None:
            est.restart(seg.start if seg.start >= 0 else self.stream.snapshot()[0], seg.states[0])
            # the deviation is judged against the whole move (the stream forgets the segments it has played)
            self._fb_move_size = float(np.ptp(seg.states[:, 0])) or 1.0

    def _on_reading(self, msg: JointState) -> None:
        """One reading of ``measurements`` (its channels put in ``measurement.names`` order)."""
        est = self._estimator
        if est is None:
            return
        names = list(msg.name)
        try:
            y = [msg.position[names.index(n)] for n in self._fb_map.names]
        except (ValueError, IndexError):
            return  # not our channels
        est.measurement(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec, y)

    # ------------------------------------------------------------- replanning
    def _feedback_loop(self) -> None:
        period = self._fb.replan_period_s
        next_at = time.monotonic() + period
        while not self._fb_stop.wait(max(0.0, next_at - time.monotonic())):
            # a replan that overran its period is not followed by a burst of catch-up replans (each from an
            # estimate a few samples newer, each splicing over the last): the next one is a period from now
            next_at = max(next_at + period, time.monotonic() + 0.5 * period)

            if self._lifecycle != "active" or self.stream.idle or self._planning_a_goal():
                continue
            try:
                self._replan_once()
            except Exception as exc:  # noqa: BLE001 -- keep the loop (and the move) going whatever a method raises
                self._feedback_failed(f"{type(exc).__name__}: {exc}")

    def _replan_once(self) -> None:
        """One closed-loop step: estimate, decide, plan, splice (module docstring)."""
        # the timeline first: the stream drops the segments it has played, so the estimate must be at least as
        # recent as the snapshot's first segment (it is predicted with every command sent, k_next - 1 at least)
        k_next, timeline, version = self.stream.versioned_snapshot()
        if not timeline:
            return
        est = self._estimator.estimate() if self._estimator is not None else None
        if est is None or est.sample < timeline[0].start:
            self._fb_counts["skipped"] += 1
            self._fb_last = "no estimate yet" if est is None else "the estimate is older than the timeline"
            return
        stale = stale_reason(est, self._fb.replan_period_s, self._config.rate_hz)
        if stale is not None:  # a stale state is not guessed from: the plan goes on until readings come
            self._fb_counts["skipped"] += 1
            self._fb_last = stale
            return
        rec = timeline[-1].info
        target = rec.target if isinstance(rec, MoveRecord) else None
        config = self._config
        # the look-ahead of replans from their own planning times (from a moving, vibrating state they take
        # longer than goals from rest: with the goals' look-ahead most replans overran it under load)
        lead = max(
            self._lead_samples(),
            lead_samples(self._fb_plan_times[-PLAN_TIME_WINDOW:], self._replan_lead_s, self._config.rate_hz),
        )
        out = replan(
            timeline,
            max(k_next, est.sample),
            lead,
            est.x,
            est.sample,
            config=config,
            target=target,
            covariance=est.P,
            move_size=getattr(self, "_fb_move_size", None),
            min_deviation=self._fb.min_deviation,
            # replan(warm_start=True) would pass the plan being executed as the planner's warm start: off (replan.py)
            planner=lambda c, problem, rate, **warm: self._planner_for(problem)(c, problem, rate, **warm),
        )
        self._fb_last = f"{out.status.value}: {out.reason}"
        if out.status is ReplanStatus.FAILED:
            self._feedback_failed(out.reason)
            return
        if out.status is not ReplanStatus.REPLANNED:
            self._fb_counts["on_plan" if out.status is ReplanStatus.ON_PLAN else "skipped"] += 1
            return
        self._plan_times.append(out.plan_time_s)
        self._fb_plan_times.append(out.plan_time_s)
        seg = out.segment
        seg.info = MoveRecord(out.result, target, "feedback", time.monotonic(), False, out.plan_time_s)
        with self._install_lock:
            if self.stream.version != version:
                self._fb_counts["skipped"] += 1
                self._fb_last = "skipped: the timeline changed while replanning (a goal or a stop)"
                return
            if not self.stream.splice(seg, seg.start):
                if self.stream.idle:
                    self._fb_counts["skipped"] += 1
                    self._fb_last = "skipped: the move ended while replanning"
                    return
                self._feedback_failed(
                    f"replanning took {out.plan_time_s * 1e3:.0f} ms, beyond the {lead} sample look-ahead; "
                    "the plan goes on"
                )
                return
            self._installed(seg, target, plan_summary(out.result, out.plan_time_s), "feedback")
            self._predicted_end = seg.states[-1].copy()
        self._fb_counts["replanned"] += 1

    def _feedback_failed(self, reason: str) -> None:
        self._fb_counts["failed"] += 1
        self._fb_last_failure = reason
        self.get_logger().warning(f"feedback: replan failed, the current plan goes on: {reason}")
        self.publish_diagnostics()

    def _feedback_status(self) -> dict[str, Any]:
        """Values of the status on /diagnostics."""
        fb = getattr(self, "_fb", None)
        if fb is None or not fb.enabled:
            return {}
        times = sorted(self._fb_plan_times[-100:])
        return {
            "feedback.replan_period_s": fb.replan_period_s,
            **{f"feedback.{k}": v for k, v in self._fb_counts.items()},
            "feedback.last": self._fb_last,
            "feedback.last_failure": self._fb_last_failure,
            "feedback.median_replan_ms": times[len(times) // 2] * 1e3 if times else 0.0,
        }


__all__ = ["FeedbackGlue"]
