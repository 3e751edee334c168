"""``flexmotion_planner``: goals in, a fixed-rate command stream out.

``ros2 run flexmotion_ros planner --ros-args --params-file config/wie_bernstein.yaml``

Interfaces (standard types only)
--------------------------------
``~/goal`` (std_msgs/Float64)
    Absolute target position (m or rad).
``~/joint_trajectory`` (trajectory_msgs/JointTrajectory)
    The joint trajectory controller's habit: the last point's ``positions[0]``
    is the target; an empty message (no points) stops.
``~/move`` (nav_msgs/srv/GetPlan)
    ``goal.pose.position.x`` is the target: plans, starts the move, answers the
    predicted path (one pose per sample, stamped with its predicted time).
``~/plan`` (nav_msgs/srv/GetPlan)
    The same, plan only: nothing moves.
    GetPlan has no error field: a refused request answers an **empty path
    whose header.frame_id is "error: <reason>"** (and logs the reason and
    publishes ERROR on /diagnostics).
``~/stop`` (std_srvs/Trigger)
    Time-optimal stop from the predicted moving, vibrating state; the final
    position is free.
``commands`` (std_msgs/Float64MultiArray, one element)
    The exact zero-order-hold plan at ``rate_hz`` from an absolute-deadline
    thread (:class:`~flexmotion_ros.execution.CommandStream`); one explicit hold sample (0) ends each move;
    ``publish_hold_when_idle`` keeps the hold going while idle.
``~/planned_trajectory`` (trajectory_msgs/JointTrajectory, transient local)
    Predicted position, velocity and command per sample (:mod:`.messages`).
``/diagnostics`` (diagnostic_msgs/DiagnosticArray)
    ``idle`` / ``moving`` / ``error: <reason>``; the last plan's duration,
    samples, method, certificate, planning time, stream timing
    (:mod:`.planner_status`).

Preemption: a goal (or stop) during a move is planned from the state the
timeline predicts at a sample ``k_s`` far enough ahead to cover the planning
time (``replan_lead_s``, at least 1.5 x the slowest recent plan + 20 ms); the
new sequence is spliced in at ``k_s``.  If planning overran (``k_s`` already
sent), it is planned again from a later sample.  Commands before and after
the splice are both within ``|u| <= u_max``, so the command never jumps by
more than ``2 u_max``.  The splice point and the look-ahead policy are
:mod:`flexmotion_ros.execution.splice`; this node only plans and logs.

The planner is open loop: it predicts the machine's state from its own
plans (it does not read ``joint_states``).

Bad goals (NaN, inf, outside the position limits) and solver failures are
refused with the reason (log, service answer, /diagnostics); nothing moves,
the node keeps serving.
"""

from __future__ import annotations

import gc
import sys
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from nav_msgs.srv import GetPlan
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64, Float64MultiArray
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from ..core.config import PlannerConfig
from ..core.errors import FlexmotionError, SolverError
from ..core.methods.table import plan_move
from ..core.model.boundary import state_to_rest
from ..core.results import PlanResult
from ..execution import (
    PLAN_TIME_WINDOW,
    SPLICE_ATTEMPTS,
    CommandStream,
    Segment,
    ended_at_rest,
    lead_samples,
    longer_lead,
    plan_summary,
    splice_point,
)
from . import messages
from .parameters import (
    PLANNER_NODE_ONLY,
    declare,
    declare_method_options,
    declared_values,
    planner_config,
    planner_specs,
    validating_callback,
)
from .planner_status import DIAGNOSTIC_NAME, StatusReporter
from .runner import run

NODE_NAME = "flexmotion_planner"

#: ``commands``: reliable and deep (10 s at 1 kHz), so that a lagging lockstep plant never loses a sample.
COMMAND_QOS = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
#: ``~/planned_trajectory``: late joiners get the current plan.
LATCHED_QOS = QoSProfile(
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
    history=HistoryPolicy.KEEP_LAST,
)


@dataclass
class MoveRecord:
    """What a segment on the stream came from."""

    result: PlanResult
    target: float | None
    source: str
    requested_at: float  # monotonic (s)
    from_idle: bool
    plan_time_s: float


@dataclass
class Outcome:
    """Answer to a goal, a plan request or a stop.

    Attributes
    ----------
    ok : bool
    reason : str
        Why it was refused, or a note ("already at rest").
    segment : Segment or None
        The plan (commands, predicted states); None if nothing to do.
    start_time : float
        ROS time (s) of its first command (predicted for ``~/plan``).
    """

    ok: bool
    reason: str = ""
    segment: Segment | None = None
    start_time: float = 0.0
    info: dict = field(default_factory=dict)


class PlannerNode(Node):
    """The planner; ``Node`` keyword arguments (``context``, ``parameter_overrides``, ``cli_args``) pass through.

    Raises
    ------
    FlexmotionError
        The start-up parameters are invalid (the node is destroyed).
    """

    def __init__(self, **node_kwargs: Any) -> None:
        super().__init__(NODE_NAME, **node_kwargs)
        try:
            self._setup()
        except BaseException:
            self.destroy_node()
            raise

    # ------------------------------------------------------------------ setup
    def _setup(self) -> None:
        specs = planner_specs()
        declare(self, specs)
        self._option_names = declare_method_options(self, [s.name for s in specs])
        self._param_names = [s.name for s in specs] + self._option_names
        self._config: PlannerConfig = planner_config(self._values())
        v = self._values()
        self._position = float(v["initial_position"])
        self._replan_lead_s = float(v["replan_lead_s"])
        self._max_points = int(v["max_trajectory_points"])
        self._frame_id = str(v["frame_id"])
        self.add_on_set_parameters_callback(validating_callback(self._values, self._validate))
        self.add_post_set_parameters_callback(self._apply_parameters)

        rate = self._config.rate_hz
        # The stream thread must get the GIL within a fraction of a period while
        # another thread plans (CPython's default switch interval is 5 ms).
        self._switch_interval = sys.getswitchinterval()
        sys.setswitchinterval(min(self._switch_interval, max(5e-5, 0.2 / rate)))

        self._plan_lock = threading.Lock()  # one plan at a time: the timeline stays consistent
        self._plan_times: deque[float] = deque(maxlen=PLAN_TIME_WINDOW)
        self._sent_at_start = 0
        self._move_requested_at = 0.0
        #: Recently installed segments, oldest first (start index, plan): for tests and the demo.
        self.installed: deque[Segment] = deque(maxlen=100)

        self.commands_publisher = self.create_publisher(Float64MultiArray, "commands", COMMAND_QOS)
        self._trajectory_pub = self.create_publisher(JointTrajectory, "~/planned_trajectory", LATCHED_QOS)
        # /diagnostics from its own thread (started last), not an executor timer
        self._status = StatusReporter(self, float(v["diagnostics_period_s"]), self._position, self._status_context)

        planning = MutuallyExclusiveCallbackGroup()
        self.create_subscription(Float64, "~/goal", self._on_goal, 10, callback_group=planning)
        self.create_subscription(
            JointTrajectory, "~/joint_trajectory", self._on_joint_trajectory, 10, callback_group=planning
        )
        self.create_service(GetPlan, "~/move", self._on_move, callback_group=planning)
        self.create_service(GetPlan, "~/plan", self._on_plan, callback_group=planning)
        self.create_service(Trigger, "~/stop", self._on_stop, callback_group=planning)

        msg = messages.command(0.0)

        def publish(value: float) -> None:
            msg.data[0] = value
            self.commands_publisher.publish(msg)

        self.stream = CommandStream(
            rate,
            publish,
            bool(v["publish_hold_when_idle"]),
            on_start=self._on_segment_start,
            on_finish=self._on_move_finished,
            priority=int(v["stream_priority"]),
        )
        # A full garbage collection over everything imported (rclpy, scipy, ...) takes
        # ~100 ms on a loaded machine and holds the GIL: measured as a 100 ms hole in
        # the stream.  Freezing the start-up heap leaves only new objects to scan.
        gc.collect()
        gc.freeze()
        self.stream.start()
        if self.stream.priority_error:
            self.get_logger().warning(self.stream.priority_error)
        m = self._config.model
        self.get_logger().info(
            f"ready: {m.n_modes} mode(s), u_max {self._config.u_max:g}, {rate:g} Hz, method {self._config.method}, "
            f"at {self._position:g}"
        )
        self.publish_diagnostics()
        self._status.start()

    def destroy_node(self) -> None:
        status = getattr(self, "_status", None)
        if status is not None:
            status.stop()
        stream = getattr(self, "stream", None)
        if stream is not None:
            stream.stop()
            sys.setswitchinterval(self._switch_interval)
        super().destroy_node()

    # ------------------------------------------------------------- parameters
    def _values(self) -> dict[str, Any]:
        return declared_values(
            self, self._param_names if hasattr(self, "_param_names") else [s.name for s in planner_specs()]
        )

    def _validate(self, candidate: dict[str, Any]) -> None:
        planner_config(candidate)

    def _apply_parameters(self, params) -> None:
        v = self._values()
        self._config = planner_config(v)  # validated by the on-set callback
        self._replan_lead_s = float(v["replan_lead_s"])
        self._max_points = int(v["max_trajectory_points"])
        self._frame_id = str(v["frame_id"])
        self.stream.hold_when_idle = bool(v["publish_hold_when_idle"])
        changed = ", ".join(f"{p.name}={messages._text(p.value)}" for p in params)
        self.get_logger().info(f"parameters set ({changed}); the next goal uses them")

    @property
    def config(self) -> PlannerConfig:
        """The configuration the next goal is planned with."""
        return self._config

    # -------------------------------------------------------------- interfaces
    def _on_goal(self, msg: Float64) -> None:
        self.request(msg.data, execute=True, source="~/goal")

    def _on_joint_trajectory(self, msg: JointTrajectory) -> None:
        try:
            target = messages.target_from_trajectory(msg)
        except ValueError as exc:
            self._refuse("~/joint_trajectory", str(exc))
            return
        if target is None:
            self.request(None, execute=True, source="~/joint_trajectory (empty: stop)")
        else:
            self.request(target, execute=True, source="~/joint_trajectory")

    def _on_move(self, request: GetPlan.Request, response: GetPlan.Response) -> GetPlan.Response:
        return self._answer_plan(request, response, execute=True)

    def _on_plan(self, request: GetPlan.Request, response: GetPlan.Response) -> GetPlan.Response:
        return self._answer_plan(request, response, execute=False)

    def _answer_plan(self, request: GetPlan.Request, response: GetPlan.Response, execute: bool) -> GetPlan.Response:
        out = self.request(request.goal.pose.position.x, execute=execute, source="~/move" if execute else "~/plan")
        if not out.ok:
            response.plan = messages.error_path(out.reason, self.get_clock().now().to_msg())
        elif out.segment is None:  # already there: a one-pose path
            states = self._config.model.rest_state(self._position)[None, :]
            response.plan = messages.path(states, self.stream.dt, out.start_time, self._frame_id, self._max_points)
        else:
            response.plan = messages.path(
                out.segment.states, self.stream.dt, out.start_time, self._frame_id, self._max_points
            )
        return response

    def _on_stop(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        out = self.request(None, execute=True, source="~/stop")
        response.success = out.ok
        if not out.ok:
            response.message = out.reason
        elif out.segment is None:
            response.message = out.reason or "already at rest"
        else:
            response.message = (
                f"stopping: {out.segment.samples} samples ({out.segment.samples * self.stream.dt:.6g} s), "
                f"at rest at {out.segment.states[-1, 0]:.9g}"
            )
        return response

    # ---------------------------------------------------------------- planning
    def request(self, target: float | None, execute: bool, source: str) -> Outcome:
        """Plan a move to ``target`` (None: stop) and, if ``execute``, stream it.

        Never raises for bad input: a refused request returns ``ok=False`` and
        the reason, logs it and publishes ERROR on /diagnostics.
        """
        t_req = time.monotonic()
        with self._plan_lock:
            self._status.set_planning(source)
            try:
                out = self._plan_locked(target, execute, source, t_req)
            except (FlexmotionError, SolverError) as exc:
                return self._refuse(source, str(exc))
            except Exception as exc:  # noqa: BLE001 -- keep serving whatever a method raises
                self.get_logger().error(f"{source}: unexpected {type(exc).__name__}")
                return self._refuse(source, f"{type(exc).__name__}: {exc}")
            finally:
                self._status.set_planning("")
        if out.ok and execute:
            self._status.set_error(None)
            self.publish_diagnostics()
        return out

    def _refuse(self, source: str, reason: str) -> Outcome:
        self.get_logger().error(f"{source}: refused: {reason}")
        self._status.set_error(reason)
        self.publish_diagnostics()
        return Outcome(False, reason)

    def _lead_samples(self) -> int:
        return lead_samples(self._plan_times, self._replan_lead_s, self._config.rate_hz)

    def _plan_locked(self, target: float | None, execute: bool, source: str, t_req: float) -> Outcome:
        config = self._config
        model = config.model
        if target is not None:
            target = config.check_goal(target)
        lead = self._lead_samples()
        for _attempt in range(SPLICE_ATTEMPTS):
            k_next, timeline = self.stream.snapshot()
            point = splice_point(timeline, k_next, lead, model.n_modes)  # None: idle
            if point is None:
                if target is None:
                    return Outcome(True, f"already at rest at {self._position:.9g}")
                at = None
                x0 = model.rest_state(self._position)
            else:
                at, x0 = point.sample, point.state
            problem = state_to_rest(model, config.u_max, x0, target)
            t0 = time.perf_counter()
            result = plan_move(config, problem, config.rate_hz)
            plan_time = time.perf_counter() - t0
            self._plan_times.append(plan_time)
            sampled = result.sampled
            if sampled is None:
                raise SolverError(f"method {config.method} returned no sampled command sequence")
            record = MoveRecord(result, target, source, t_req, at is None, plan_time)
            seg = Segment(np.asarray(sampled.commands, float), np.asarray(sampled.states, float), info=record)
            info = plan_summary(result, plan_time)
            if not execute:
                k0 = k_next if at is None else at
                return Outcome(True, "", seg, self._ros_time_of(k0), info)
            if at is None and seg.samples == 0:
                return Outcome(True, f"already at {self._position:.9g}", None, self._ros_time_of(k_next), info)
            if at is None or not self.stream.splice(seg, at):
                # the timeline ran out while planning: valid from rest only if x0 was the rest at its end
                if at is not None and not ended_at_rest(timeline, at, self.stream.idle):
                    # overran the look-ahead: plan again from a later sample
                    self.get_logger().warning(
                        f"{source}: planning took {plan_time * 1e3:.0f} ms, beyond the {lead} sample look-ahead; replanning"
                    )
                    lead = longer_lead(lead)
                    continue
                self._move_requested_at = t_req
                seg.info.from_idle = True
                self.stream.start_now(seg)
            self._installed(seg, target, info, source)
            return Outcome(True, "", seg, self._ros_time_of(seg.start), info)
        raise SolverError(
            f"planning overran its look-ahead {SPLICE_ATTEMPTS} times (last {lead} samples); the move continues unchanged"
        )

    def _installed(self, seg: Segment, target: float | None, info: dict, source: str) -> None:
        self.installed.append(seg)
        self._position = float(seg.states[-1, 0])
        self._status.moving(target if target is not None else self._position, info)
        stamp = messages.to_time(self._ros_time_of(seg.start))
        self._trajectory_pub.publish(
            messages.planned_trajectory(seg.states, seg.commands, self.stream.dt, stamp, self._max_points)
        )
        if seg.samples + 1 > self._max_points:
            self.get_logger().info(
                f"~/planned_trajectory decimated: {seg.samples + 1} samples > max_trajectory_points {self._max_points}"
            )
        what = f"to {target:.9g}" if target is not None else f"stop at {self._position:.9g}"
        self.get_logger().info(
            f"{source}: {what}: {info['samples']} samples ({info['duration_s']:.6g} s, certified {info['certified']}), "
            f"planned in {info['plan_time_s'] * 1e3:.1f} ms, from sample {seg.start}"
        )

    def _ros_time_of(self, k: int) -> float:
        """ROS time (s) at which global sample ``k`` is (or was) due."""
        now_ros = self.get_clock().now().nanoseconds * 1e-9
        return now_ros + (self.stream.time_of(k) - time.monotonic())

    # ----------------------------------------------------------- stream events
    def _on_segment_start(self, seg: Segment) -> None:
        rec = seg.info
        if isinstance(rec, MoveRecord) and rec.from_idle:
            self._sent_at_start = self.stream.samples_sent - 1
            self._status.first_command(seg.started_at - rec.requested_at)

    def _on_move_finished(self, seg: Segment) -> None:
        times, late = self.stream.recent_timing(self.stream.samples_sent - self._sent_at_start)
        self._status.finished(times, late)
        self.get_logger().info(f"move finished, at rest at {self._position:.9g}")
        self.publish_diagnostics()

    # -------------------------------------------------------------- diagnostics
    def _status_context(self) -> dict[str, Any]:
        """The node's own values of the status on /diagnostics (after state, planning, last_error, target)."""
        return {
            "position_at_rest": self._position,
            "rate_hz": self._config.rate_hz,
            "method": self._config.method,
            "u_max": self._config.u_max,
            "modes": self._config.model.n_modes,
            "command_subscribers": self.commands_publisher.get_subscription_count(),
            "replan_lead_samples": self._lead_samples(),
        }

    def status(self) -> tuple[int, str, dict[str, Any]]:
        """``(level, message, values)`` of the status on /diagnostics."""
        return self._status.status()

    def publish_diagnostics(self) -> None:
        """Publish the status on /diagnostics now."""
        self._status.publish()


def main(args: list[str] | None = None) -> int:
    """``ros2 run flexmotion_ros planner [--ros-args --params-file FILE]``.

    A single-threaded executor: goals and services are serialised by design
    (one plan at a time) and commands go out from the stream thread.  Jazzy's
    rclpy ``MultiThreadedExecutor`` re-queues callbacks that have not started
    and spins holding the GIL (ros2/rclpy#1452, fixed upstream by #1547):
    measured here, a 100 Hz subscription in it stalled for up to 5.5 s.
    """
    return run(PlannerNode, SingleThreadedExecutor, NODE_NAME, args)


__all__ = ["DIAGNOSTIC_NAME", "NODE_NAME", "PLANNER_NODE_ONLY", "PlannerNode", "main"]

if __name__ == "__main__":
    sys.exit(main())
