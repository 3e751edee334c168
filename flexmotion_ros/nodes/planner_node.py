"""``flexmotion_planner``: goals in, a fixed-rate command stream out.

``ros2 run flexmotion_ros planner --ros-args --params-file config/wie_bernstein.yaml``

Interfaces (standard types only)
--------------------------------
``~/goal`` (std_msgs/Float64)
    Absolute target position (m or rad).
``~/joint_trajectory`` (trajectory_msgs/JointTrajectory)
    ``joint_names`` must be ``[joint_name]`` (another name is refused, with
    the closest valid one); the last point's position is the target, its
    ``time_from_start`` the requested arrival (method ``fixed_time``, counted
    from the move's first command; 0: as fast as possible; before the
    time-optimal arrival: refused, or the optimum, as
    ``trajectory.early_arrival`` says); an empty message (no points) stops.
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

Start state: a move from idle starts from the machine's measured state
(``state.source: measured``, the default: the last ``state.topic``
joint_states message, ``joint_name`` then ``state.mode_joint_names``;
:mod:`.measured_state`), moving or not; a state missing or older than
``state.timeout_s`` (after waiting that long for one) refuses the goal with
the reason.  ``~/plan`` (nothing moves) uses the measured state if fresh,
else the believed one.  ``state.source: assumed`` is the old open loop: at
rest at ``initial_position``, then where the last plan ended.  During a move,
goals are planned from the predicted timeline (the splice below).

Clock: with ``use_sim_time: true`` (read at start-up) the stream runs on the
node's ROS clock, so a simulator's ``/clock`` drives it (no sample goes out
while ``/clock`` stands still); otherwise on the monotonic wall clock.

Bad goals (NaN, inf, outside the position limits) and solver failures are
refused with the reason (log, service answer, /diagnostics); nothing moves,
the node keeps serving.

Lifecycle (a managed ``rclpy.lifecycle`` node; ``~/change_state``,
``~/get_state``): *configure* reads and validates the parameters and creates
the interfaces (a bad value: one line naming it, the transition fails,
nothing changes); *activate* starts the command stream and the stop
preparer; *deactivate* cuts a move off with the hold (0) and stops
streaming (goals are then refused; ``~/plan`` still answers); *cleanup*
destroys the interfaces; *shutdown* ends like deactivate.  ``PlannerNode()``
(``autostart=True``, what ``ros2 run`` and the tests use) configures and
activates itself.

Safety: whatever ends the stream -- deactivation, shutdown (Ctrl-C,
SIGTERM, ``destroy_node``), a fault in the stream thread -- the last command
on ``commands`` is the hold (0.0), sent before the context goes away, and the
log says so (:class:`~flexmotion_ros.execution.command_stream.StreamHalt`).
``~/stop`` splices a stop planned in advance (verified like every plan,
:class:`~flexmotion_ros.execution.splice.StopPreparer`: from the state
predicted at checkpoints just ahead of the stream) a few samples after the
request; without a usable one it plans the stop as a preemption.
"""

from __future__ import annotations

import gc
import sys
import threading
import time
from collections import deque
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from nav_msgs.srv import GetPlan
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.executors import SingleThreadedExecutor
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64, Float64MultiArray
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from ..core.config import PlannerConfig
from ..core.errors import FlexmotionError, GoalError, InputError, SolverError
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
from ..execution.command_stream import StreamHalt
from ..execution.measured_state import EarlyArrival, StateSource, at_rest, state_settings
from ..execution.splice import StopPreparer
from . import messages
from .measured_state import StateListener
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
#: Under ``use_sim_time``, the stream's sleep polls the ROS clock this often (wall s).
SIM_TIME_POLL_S = 0.0005

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


class PlannerNode(LifecycleNode):
    """The planner, a managed (lifecycle) node; ``Node`` keyword arguments (``context``, ``parameter_overrides``, ``cli_args``) pass through.

    Parameters
    ----------
    autostart : bool
        Configure and activate at once (``ros2 run``, the tests); False: stay
        unconfigured until ``~/change_state`` (or :meth:`trigger_configure`).

    Raises
    ------
    FlexmotionError
        The start-up parameters are invalid (the node is destroyed).
    """

    def __init__(self, *, autostart: bool = True, **node_kwargs: Any) -> None:
        super().__init__(NODE_NAME, **node_kwargs)
        self._lifecycle = "unconfigured"  # unconfigured / inactive / active / finalized
        self._configure_error: BaseException | None = None
        self._configured_entities: list[tuple[str, Any]] = []
        self._stops: StopPreparer | None = None
        try:
            self._declare_parameters()
            if autostart:
                self.bring_up()
        except BaseException:
            self.destroy_node()
            raise

    def _declare_parameters(self) -> None:
        specs = planner_specs()
        declare(self, specs)
        self._option_names = declare_method_options(self, [s.name for s in specs])
        self._param_names = [s.name for s in specs] + self._option_names
        self.add_on_set_parameters_callback(validating_callback(self._values, self._validate))
        self.add_post_set_parameters_callback(self._apply_parameters)

    def bring_up(self) -> None:
        """Configure and activate (what the executable does).

        Raises
        ------
        FlexmotionError
            The parameters are invalid (the node stays unconfigured).
        RuntimeError
            A transition failed otherwise.
        """
        if self.trigger_configure() != TransitionCallbackReturn.SUCCESS:
            err = self._configure_error
            raise err if err is not None else RuntimeError("configure failed")
        if self.trigger_activate() != TransitionCallbackReturn.SUCCESS:
            raise RuntimeError("activate failed")

    @property
    def stop_preparer(self) -> StopPreparer | None:
        """The ready stops for the running move (None while unconfigured)."""
        return self._stops

    @property
    def lifecycle_state(self) -> str:
        """``unconfigured``, ``inactive``, ``active`` or ``finalized``."""
        return self._lifecycle

    # ------------------------------------------------------------------ setup
    def _setup(self) -> None:
        self._config: PlannerConfig = planner_config(self._values())
        v = self._values()
        self._position = float(v["initial_position"])
        self._state = state_settings(v)  # ConfigError names a bad state.* / joint_name / trajectory.* value
        self._state_joints = self._state.state_joint_names(self._config.model.n_modes)
        self._replan_lead_s = float(v["replan_lead_s"])
        self._max_points = int(v["max_trajectory_points"])
        self._frame_id = str(v["frame_id"])

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

        # a lifecycle publisher: nothing goes out unless active (the hold is sent before deactivating it)
        self.commands_publisher = self.create_lifecycle_publisher(Float64MultiArray, "commands", COMMAND_QOS)
        self._trajectory_pub = self.create_publisher(JointTrajectory, "~/planned_trajectory", LATCHED_QOS)
        # /diagnostics from its own thread (started last), not an executor timer
        self._status = StatusReporter(self, float(v["diagnostics_period_s"]), self._position, self._status_context)

        self._listener: StateListener | None = None
        #: The state this planner's own last move ends in (None before its first): what the measurement should show.
        self._predicted_end: np.ndarray | None = None
        if self._state.source is StateSource.MEASURED:
            self._listener = StateListener(self, self._state.topic)

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

        # use_sim_time: the node's ROS clock (it follows /clock); else the monotonic wall clock, as always
        self._ros_time_stream = bool(self.get_parameter("use_sim_time").value)
        clock_pair = self._ros_clock_pair() if self._ros_time_stream else {}
        self.stream = CommandStream(
            rate,
            publish,
            bool(v["publish_hold_when_idle"]),
            on_start=self._on_segment_start,
            on_finish=self._on_move_finished,
            priority=int(v["stream_priority"]),
            on_fault=self._on_stream_fault,
            **clock_pair,
        )
        # stops kept ready for the running move (started on activate)
        self._stops = StopPreparer(
            self._plan_stop, self.stream.snapshot, lambda: self._config, self._wants_ready_stops, rate
        )
        # A full garbage collection over everything imported (rclpy, scipy, ...) takes
        # ~100 ms on a loaded machine and holds the GIL: measured as a 100 ms hole in
        # the stream.  Freezing the start-up heap leaves only new objects to scan.
        gc.collect()
        gc.freeze()
        self._froze_gc = True
        m = self._config.model
        self.get_logger().info(
            f"ready: {m.n_modes} mode(s), u_max {self._config.u_max:g}, {rate:g} Hz, method {self._config.method}, "
            f"joint {self._state.joint_name!r}, "
            + (
                f"start state measured on {self._listener.topic}"
                if self._listener is not None
                else f"at {self._position:g} (state.source: assumed)"
            )
            + (", stream on ROS time (use_sim_time)" if self._ros_time_stream else "")
        )
        self.publish_diagnostics()
        self._status.start()

    def destroy_node(self) -> None:
        if getattr(self, "_lifecycle", "finalized") in ("inactive", "active"):
            self._end_stream("shutdown")  # the hold first, while the context is valid
            self._lifecycle = "finalized"
        status = getattr(self, "_status", None)
        if status is not None:
            status.stop()
        stream = getattr(self, "stream", None)
        if stream is not None:
            stream.stop("shutdown")
            sys.setswitchinterval(self._switch_interval)
        listener = getattr(self, "_listener", None)
        if listener is not None:
            self._listener = None
            listener.close()
        super().destroy_node()
        # Jazzy's LifecycleNode leaves its state machine alive, and it holds the rcl node: the node, and
        # with the last node of a context its DDS participant, lived on until the garbage collector found
        # the cycle -- never, once gc.freeze() had frozen it.  41 leaked participants in one test process
        # put new ones beyond Fast DDS's 32 localhost discovery ports (maxInitialPeersRange): unseen.
        state_machine = getattr(self, "_state_machine", None)
        if state_machine is not None:
            state_machine.destroy_when_not_in_use()
        self._unfreeze_gc()

    def _unfreeze_gc(self) -> None:
        """Undo configure's ``gc.freeze()``: what it froze may be collected again (cleanup, destroy)."""
        if getattr(self, "_froze_gc", False):
            self._froze_gc = False
            gc.unfreeze()

    # --------------------------------------------------------------- lifecycle
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
        self.stream.start()
        if self.stream.priority_error:
            self.get_logger().warning(self.stream.priority_error)
        self._stops.start()
        self._lifecycle = "active"
        self._status.set_lifecycle("active")
        self.get_logger().info(f"active: streaming 'commands' at {self._config.rate_hz:g} Hz")
        self.publish_diagnostics()
        return TransitionCallbackReturn.SUCCESS

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Cut a move off with the hold, stop streaming; then disable ``commands``."""
        self._lifecycle = "inactive"  # goals are refused from now on
        self._end_stream("deactivated")
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
        )

    def _teardown(self) -> None:
        """Undo configure: threads stopped, interfaces destroyed (the parameters stay)."""
        if self._stops is not None:
            self._stops.stop()
            self._stops = None
        status = getattr(self, "_status", None)
        if status is not None:
            status.stop()
        stream = getattr(self, "stream", None)
        if stream is not None:
            stream.stop("cleanup")
            sys.setswitchinterval(self._switch_interval)
            del self.stream
        listener = getattr(self, "_listener", None)
        if listener is not None:
            self._listener = None
            listener.close()
        destroy = {
            "subscription": self.destroy_subscription,
            "service": self.destroy_service,
            "publisher": self.destroy_lifecycle_publisher,
            "timer": self.destroy_timer,
        }
        for kind, entity in self._configured_entities:
            destroy[kind](entity)
        self._configured_entities = []
        self._unfreeze_gc()

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

    # ------------------------------------------------------------- parameters
    def _values(self) -> dict[str, Any]:
        return declared_values(
            self, self._param_names if hasattr(self, "_param_names") else [s.name for s in planner_specs()]
        )

    def _validate(self, candidate: dict[str, Any]) -> None:
        planner_config(candidate)

    def _apply_parameters(self, params) -> None:
        if self._lifecycle not in ("inactive", "active"):
            return  # configure reads them
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
            goal = messages.trajectory_goal(msg, self._state.joint_name)
        except FlexmotionError as exc:
            self._refuse("~/joint_trajectory", str(exc))
            return
        if goal.target is None:
            self.request(None, execute=True, source="~/joint_trajectory (empty: stop)")
        else:
            self.request(goal.target, execute=True, source="~/joint_trajectory", arrival_time=goal.arrival_time)

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
        out = self._ready_stop("~/stop")
        if out is None:  # none usable: plan the stop now (a preemption with the look-ahead)
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
    def request(self, target: float | None, execute: bool, source: str, arrival_time: float | None = None) -> Outcome:
        """Plan a move to ``target`` (None: stop) and, if ``execute``, stream it.

        ``arrival_time`` (s, from the move's first command): arrive at rest
        then (method ``fixed_time``); None: the configured method.  From idle,
        the move starts from the measured state (``state.source``).

        Never raises for bad input: a refused request returns ``ok=False`` and
        the reason, logs it and publishes ERROR on /diagnostics.
        """
        t_req = time.monotonic()
        if execute and self._lifecycle != "active":
            return self._refuse(source, f"the planner is {self._lifecycle} (lifecycle): activate it to move")
        with self._plan_lock:
            self._status.set_planning(source)
            try:
                out = self._plan_locked(target, execute, source, t_req, arrival_time)
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

    def _idle_start_state(self, execute: bool) -> np.ndarray:
        """The state a move from idle starts from: measured (refused if missing or stale), or assumed at rest.

        ``~/plan`` (not ``execute``: nothing moves) takes a fresh measured
        state without waiting, else the believed one.
        """
        model = self._config.model
        if self._listener is None:
            return model.rest_state(self._position)
        st = self._state
        if not execute:
            try:
                return self._listener.store.fresh(self._state_joints, st.timeout_s, self._listener.topic, wait=False)
            except GoalError:
                return model.rest_state(self._position)
        return self._listener.store.fresh(
            self._state_joints, st.timeout_s, self._listener.topic, expect=self._predicted_end
        )

    def _idle_moving_state(self) -> np.ndarray | None:
        """A stop while idle: the measured state if the machine is moving (after a restart), else None.

        Waits up to ``state.timeout_s`` for a fresh state; none: nothing to stop (the planner sends nothing).
        """
        if self._listener is None:
            return None
        try:
            x = self._listener.store.fresh(
                self._state_joints, self._state.timeout_s, self._listener.topic, expect=self._predicted_end
            )
        except GoalError:
            return None
        return None if at_rest(self._config.model, x) else x

    def _plan_to(self, config: PlannerConfig, problem, arrival_time: float | None) -> PlanResult:
        """``plan_move``; with ``arrival_time`` (s) method ``fixed_time`` (``trajectory.early_arrival`` if too early)."""
        if arrival_time is None:
            return plan_move(config, problem, config.rate_hz)
        timed = replace(config, method="fixed_time", options={**config.options, "arrival_time": float(arrival_time)})
        try:
            return plan_move(timed, problem, config.rate_hz)
        except InputError as exc:
            if exc.parameter != "arrival_time":
                raise
            if self._state.early_arrival is EarlyArrival.OPTIMUM:
                self.get_logger().info(
                    f"time_from_start {arrival_time:.6g} s is before the optimum: arriving as fast as possible "
                    "(trajectory.early_arrival: optimum)"
                )
                return plan_move(config, problem, config.rate_hz)
            raise GoalError(
                "joint_trajectory.points[-1].time_from_start",
                f"{arrival_time:.9g} s is before the fastest arrival ({exc.reason}); refused "
                "(trajectory.early_arrival: refuse; 'optimum' arrives as fast as possible instead)",
            ) from None

    def _plan_locked(
        self, target: float | None, execute: bool, source: str, t_req: float, arrival_time: float | None = None
    ) -> Outcome:
        config = self._config
        model = config.model
        if target is not None:
            target = config.check_goal(target)
        lead = self._lead_samples()
        for _attempt in range(SPLICE_ATTEMPTS):
            k_next, timeline = self.stream.snapshot()
            point = splice_point(timeline, k_next, lead, model.n_modes)  # None: idle
            if point is None:
                at = None
                if target is None:
                    x0 = self._idle_moving_state()  # a machine moving after a restart: stop it
                    if x0 is None:
                        return Outcome(True, f"already at rest at {self._position:.9g}")
                else:
                    x0 = self._idle_start_state(execute)
            else:
                at, x0 = point.sample, point.state
            problem = state_to_rest(model, config.u_max, x0, target)
            t0 = time.perf_counter()
            result = self._plan_to(config, problem, arrival_time)
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
                self._position = float(x0[0])  # measured there, at rest
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
            self._predicted_end = np.array(seg.states[-1], float)
            return Outcome(True, "", seg, self._ros_time_of(seg.start), info)
        raise SolverError(
            f"planning overran its look-ahead {SPLICE_ATTEMPTS} times (last {lead} samples); the move continues unchanged"
        )

    # ------------------------------------------------------------- ready stops
    def _plan_stop(self, x0: np.ndarray, config: PlannerConfig) -> Segment:
        """The stop from ``x0`` (final position free), planned and verified like every plan (preparer thread)."""
        t0 = time.perf_counter()
        result = plan_move(config, state_to_rest(config.model, config.u_max, x0, None), config.rate_hz)
        sampled = result.sampled
        if sampled is None:
            raise SolverError(f"method {config.method} returned no sampled command sequence")
        record = MoveRecord(result, None, "~/stop", 0.0, False, time.perf_counter() - t0)
        return Segment(np.asarray(sampled.commands, float), np.asarray(sampled.states, float), info=record)

    @staticmethod
    def _wants_ready_stops(timeline: list[Segment]) -> bool:
        """Prepare stops unless the timeline already ends in a stop."""
        rec = timeline[-1].info if timeline else None
        return isinstance(rec, MoveRecord) and rec.target is not None

    def _ready_stop(self, source: str) -> Outcome | None:
        """Splice a ready stop (a few samples ahead); None if none is usable (then plan it)."""
        stops = self._stops
        if stops is None or self._lifecycle != "active":
            return None
        t_req = time.monotonic()
        with self._plan_lock:
            k_req, timeline = self.stream.snapshot()
            if not timeline:
                return None
            # none ready but one being planned: worth waiting for (it starts sooner than a plan made now)
            ready = stops.take(wait_s=min(0.2, 2.0 * max(stops.plan_times, default=0.0)))
            if ready is None:
                return None
            seg = ready.segment
            seg.info.requested_at = t_req
            seg.info.source = source
            if not self.stream.splice(seg, ready.sample):
                return None
            info = plan_summary(seg.info.result, ready.plan_time_s)
            info["stop_lead_samples"] = ready.sample - k_req
            self._installed(seg, None, info, f"{source} (ready stop, {ready.sample - k_req} samples after the request)")
        self._status.set_error(None)
        self.publish_diagnostics()
        return Outcome(True, "", seg, self._ros_time_of(seg.start), info)

    def _installed(self, seg: Segment, target: float | None, info: dict, source: str) -> None:
        if self._stops is not None:
            self._stops.notify(info.get("plan_time_s"))
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
        if self._ros_time_stream:  # the stream runs on ROS time already
            return self.stream.time_of(k)
        now_ros = self.get_clock().now().nanoseconds * 1e-9
        return now_ros + (self.stream.time_of(k) - time.monotonic())

    # ----------------------------------------------------------- stream events
    def _on_segment_start(self, seg: Segment) -> None:
        rec = seg.info
        if isinstance(rec, MoveRecord) and rec.from_idle:
            self._sent_at_start = self.stream.samples_sent - 1
        if isinstance(rec, MoveRecord):  # from idle, or a preemption / stop: request -> its first command
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
            "ready_stops": len(self._stops.ready()) if self._stops is not None else 0,
        }

    def status(self) -> tuple[int, str, dict[str, Any]]:
        """``(level, message, values)`` of the status on /diagnostics."""
        return self._status.status()

    def publish_diagnostics(self) -> None:
        """Publish the status on /diagnostics now."""
        self._status.publish()


def main(args: list[str] | None = None) -> int:
    """``ros2 run flexmotion_ros planner [--ros-args --params-file FILE]``: configured and active at once.

    SIGINT / SIGTERM: the stream ends with the hold before the context goes
    away (:func:`.runner.run`), exit status 0, no traceback.

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
