"""``flexmotion_planner``: goals in, a fixed-rate command stream out.

``ros2 run flexmotion_ros planner --ros-args --params-file config/wie_bernstein.yaml``

Interfaces (standard types only)
--------------------------------
``~/goal`` (std_msgs/Float64)
    Absolute target position (m or rad); with several rigid bodies refused
    with the reason (use ``~/goals``).
``~/goals`` (std_msgs/Float64MultiArray)
    One target per rigid body (``model.rigid_bodies``; one value for a
    single-input model).  Several inputs (``model.inputs``): :mod:`.multi_axis`.
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
``commands`` (std_msgs/Float64MultiArray, one element per input; ``output: trajectory``: see :mod:`.planner_output`)
    The exact zero-order-hold plan at ``rate_hz`` from an absolute-deadline
    thread (:class:`~flexmotion_ros.execution.CommandStream`); one explicit hold sample (0) ends each move;
    ``publish_hold_when_idle`` keeps the hold going while idle.
``~/planned_trajectory`` (trajectory_msgs/JointTrajectory, transient local)
    Predicted position, velocity and command per sample (:mod:`.messages`).
``/diagnostics`` (diagnostic_msgs/DiagnosticArray)
    ``idle`` / ``moving`` / ``error: <reason>``; the last plan's duration,
    samples, method, certificate, planning time, stream timing
    (:mod:`.planner_status`).

Requests (received by :mod:`.planner_goals`, planned and installed by
:mod:`.planner_moves`): goals are planned off the executor, in one planning
thread (:mod:`flexmotion_ros.execution.requests`): the newest goal
wins, a goal superseded before it was planned is answered so and counted
(``goals_superseded`` on /diagnostics); ``~/stop`` cancels the goal being
planned and is answered within 10 ms.  The executable plans in two forked
child processes (:mod:`flexmotion_ros.execution.plan_process`: goals, stops),
so planning never holds the stream thread's interpreter lock.
The command stream itself runs in a third child, forked last, with its own
rclpy context: the deadline loop and the ``commands`` publisher, nothing else
(:mod:`.planner_stream` says when; the hold even if this process dies).

Preemption: a goal (or stop) during a move is planned from the state the
timeline predicts at a sample ``k_s`` far enough ahead to cover the planning
time (``replan_lead_s``; at least 1.5 x the recent planning time + 20 ms,
the slowest 20 % of the last 20 plans set aside, at most 1 s); the new
sequence is spliced in at ``k_s``.  If planning overran (``k_s`` already
sent), or the timeline changed meanwhile, it is planned again.  Commands before and after
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
log says so (:class:`~flexmotion_ros.execution.stream_halt.StreamHalt`).
``~/stop`` splices a stop planned in advance (verified like every plan,
:class:`~flexmotion_ros.execution.splice.StopPreparer`: from the state
predicted at checkpoints just ahead of the stream) a few samples after the
request; without a usable one it plans the stop as a preemption.
"""

from __future__ import annotations

import gc
import sys
import threading
from collections import deque
from typing import Any

import numpy as np
from nav_msgs.srv import GetPlan
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import SingleThreadedExecutor
from rclpy.lifecycle import LifecycleNode, TransitionCallbackReturn
from std_msgs.msg import Float64, Float64MultiArray
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from ..core.errors import ConfigError
from ..core.multi_input.dispatch import AnyConfig, bounds_text, n_inputs, positions_text
from ..execution import (
    PLAN_TIME_WINDOW,
    Segment,
)
from ..execution.learning import identification_settings
from ..execution.measured_state import StateSource, state_settings
from ..execution.plan_process import PlanningProcesses
from ..execution.realtime import SlackCollector
from ..execution.remote_stream import RemoteStream
from ..execution.requests import RequestWorker
from ..execution.splice import StopPreparer
from ..execution.stream_process import StreamProcess
from . import messages, multi_axis
from .measured_state import StateListener
from .parameters import declare, declare_method_options, declared_values, validating_callback
from .planner_feedback import FeedbackGlue
from .planner_goals import GoalHandling
from .planner_identify import IdentifyHandling
from .planner_lifecycle import LifecycleTransitions
from .planner_output import OutputGlue, check_output
from .planner_parameters import PLANNER_NODE_ONLY, planner_config, planner_specs
from .planner_qos import COMMAND_QOS, GOAL_QOS, LATCHED_QOS
from .planner_status import DIAGNOSTIC_NAME, StatusGlue, StatusReporter
from .planner_stops import StopHandling
from .planner_stream import StreamGlue
from .runner import run
from .stream_child import open_output

NODE_NAME = "flexmotion_planner"
#: Installed segments kept for inspection (``PlannerNode.installed``).
INSTALLED_KEPT = 32


class PlannerNode(
    OutputGlue,
    FeedbackGlue,
    GoalHandling,
    StopHandling,
    IdentifyHandling,
    StreamGlue,
    StatusGlue,
    LifecycleTransitions,
    LifecycleNode,
):
    """The planner, a managed (lifecycle) node; ``Node`` keyword arguments (``context``, ``parameter_overrides``, ``cli_args``) pass through.

    Parameters
    ----------
    autostart : bool
        Configure and activate at once (``ros2 run``, the tests); False: stay
        unconfigured until ``~/change_state`` (or :meth:`trigger_configure`).
    planning : PlanningProcesses, optional
        Plan in these child processes (forked before ``rclpy.init``, as
        :func:`main` does), so that planning never holds this process's
        interpreter lock while the stream thread needs it; None: plan in a
        thread of this process.  The node does not close them.
    stream_process : StreamProcess, optional
        Run the command stream there (forked before ``rclpy.init``, as
        :func:`main` does: :mod:`.planner_stream` says when); None: in a
        thread of this process.  The node does not close it.

    Raises
    ------
    FlexmotionError
        The start-up parameters are invalid (the node is destroyed).
    """

    def __init__(
        self,
        *,
        autostart: bool = True,
        planning: PlanningProcesses | None = None,
        stream_process: StreamProcess | None = None,
        **node_kwargs: Any,
    ) -> None:
        super().__init__(NODE_NAME, **node_kwargs)
        self._children = planning
        self._stream_process = stream_process
        self._lock_sharers_raised = False  # the other threads under SCHED_FIFO (stream_priority, planning children)
        self._collector = SlackCollector()  # garbage collection in the stream's slack (enabled with the above)
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
        self._config: AnyConfig = planner_config(self._values())
        v = self._values()
        self._position = multi_axis.initial_position(self._config, v["initial_position"])
        self._state = state_settings(v)  # ConfigError names a bad state.* / joint_name / trajectory.* value
        self._state_joints = multi_axis.state_joints(self._state, self._config)
        self._joint_names = multi_axis.command_joint_names(self._config, v)  # the joints of 'commands', in order
        self._replan_lead_s = float(v["replan_lead_s"])
        self._max_points = int(v["max_trajectory_points"])
        self._frame_id = str(v["frame_id"])

        rate = self._config.rate_hz
        # The stream thread must get the GIL within a fraction of a period while
        # another thread plans (CPython's default switch interval is 5 ms).
        self._switch_interval = sys.getswitchinterval()
        sys.setswitchinterval(min(self._switch_interval, max(5e-5, 0.2 / rate)))

        # the splice of a plan into the timeline; never held while planning, so a stop never waits for a plan
        self._install_lock = threading.Lock()
        # the stop being planned on demand (one at a time) and its ticket (a newer goal cancels it)
        self._stop_lock = threading.Lock()
        self._stop_future = None
        self._stop_ticket = None
        self._plan_times: deque[float] = deque(maxlen=PLAN_TIME_WINDOW)
        self._sent_at_start = 0
        self._move_requested_at = 0.0
        #: Recently installed segments, oldest first (start index, plan): for tests and the demo (bounded:
        #: each holds its plan's arrays).
        self.installed: deque[Segment] = deque(maxlen=INSTALLED_KEPT)

        # a lifecycle publisher: nothing goes out unless active (the hold is sent before deactivating it)
        # 'commands' (output: stream) or the trajectory topic (output: trajectory), see planner_output
        self._output = check_output(v, self._config)
        if self._streams_remotely(v):  # the stream process publishes 'commands' (planner_stream)
            self.commands_publisher = self._remote_publisher(COMMAND_QOS)
        else:
            self.commands_publisher = self._output_publisher(v, COMMAND_QOS)
        self._trajectory_pub = self.create_publisher(JointTrajectory, "~/planned_trajectory", LATCHED_QOS)
        # /diagnostics from its own thread (started last), not an executor timer
        self._status = StatusReporter(
            self,
            float(v["diagnostics_period_s"]),
            self._position if np.ndim(self._position) == 0 else positions_text(self._position),
            self._status_context,
            tick=self._check_streaming_ready,
        )
        self._command_subscribers = 0  # writer-side matches of 'commands' last seen (the status thread watches)

        self._listener: StateListener | None = None
        #: The state this planner's own last move ends in (None before its first): what the measurement should show.
        self._predicted_end: np.ndarray | None = None
        if self._state.source is StateSource.MEASURED:
            self._listener = StateListener(self, self._state.topic)

        # Goals are planned in the planning thread (newest wins), not in the executor: the executor stays free
        # for ~/stop.  Reentrant: a ~/move waiting for its plan (a coroutine) must not hold up ~/stop; the
        # executor is single-threaded, so callbacks still run one at a time.
        requests = ReentrantCallbackGroup()
        self._worker = RequestWorker(self._handle, self._not_planned)
        self._wake = self.create_guard_condition(lambda: None, callback_group=requests)
        self.create_subscription(Float64, "~/goal", self._on_goal, GOAL_QOS, callback_group=requests)
        self.create_subscription(Float64MultiArray, "~/goals", self._on_goals, GOAL_QOS, callback_group=requests)
        self.create_subscription(
            JointTrajectory, "~/joint_trajectory", self._on_joint_trajectory, GOAL_QOS, callback_group=requests
        )
        self.create_service(GetPlan, "~/move", self._on_move, callback_group=requests)
        self.create_service(GetPlan, "~/plan", self._on_plan, callback_group=requests)
        self.create_service(Trigger, "~/stop", self._on_stop, callback_group=requests)

        self._make_stream(v, rate)
        self._feedback_setup(v)  # closed-loop replanning (planner_feedback), off unless feedback.replan_period_s
        self._setup_identification(v)  # ~/identify, measurements, learning (planner_identify.py)
        self._worker.start()
        # A full garbage collection over everything imported (rclpy, scipy, ...) takes
        # ~100 ms on a loaded machine and holds the GIL: measured as a 100 ms hole in
        # the stream.  Freezing the start-up heap leaves only new objects to scan.
        gc.collect()
        gc.freeze()
        self._froze_gc = True
        m = self._config.model
        self.get_logger().info(
            f"ready: {m.n_modes} mode(s), u_max {bounds_text(self._config)}, {rate:g} Hz, method {self._config.method}, "
            + (
                f"joint {self._state.joint_name!r}, "
                if not multi_axis.is_multi(self._config)
                else f"commands for joints {list(self._joint_names)}, rigid bodies {list(m.rigid_bodies)}, "
            )
            + (
                f"start state measured on {self._listener.topic}"
                if self._listener is not None
                else f"at {positions_text(self._position)} (state.source: assumed)"
            )
            + (", stream on ROS time (use_sim_time)" if self._ros_time_stream else "")
        )
        self.publish_diagnostics()
        self._status.start()

    def destroy_node(self) -> None:
        if getattr(self, "_lifecycle", "finalized") in ("inactive", "active"):
            self._end_stream("shutdown")  # the hold first, while the context is valid
            self._lifecycle = "finalized"
        worker = getattr(self, "_worker", None)
        if worker is not None:
            worker.stop()
        self._feedback_close()
        status = getattr(self, "_status", None)
        if status is not None:
            status.stop()
        stream = getattr(self, "stream", None)
        if stream is not None:
            stream.stop("shutdown")
            if isinstance(stream, RemoteStream):
                stream.close()
            sys.setswitchinterval(self._switch_interval)
        listener = getattr(self, "_listener", None)
        if listener is not None:
            self._listener = None
            listener.close()
        self._close_identification()
        super().destroy_node()
        # Jazzy's LifecycleNode leaves its state machine alive, and it holds the rcl node: the node, and
        # with the last node of a context its DDS participant, lived on until the garbage collector found
        # the cycle -- never, once gc.freeze() had frozen it.  41 leaked participants in one test process
        # put new ones beyond Fast DDS's 32 localhost discovery ports (maxInitialPeersRange): unseen.
        state_machine = getattr(self, "_state_machine", None)
        if state_machine is not None:
            state_machine.destroy_when_not_in_use()
        self._unfreeze_gc()

    # ------------------------------------------------------------- parameters
    def _values(self) -> dict[str, Any]:
        return declared_values(
            self, self._param_names if hasattr(self, "_param_names") else [s.name for s in planner_specs()]
        )

    def _validate(self, candidate: dict[str, Any]) -> None:
        new = planner_config(candidate)
        check_output(candidate, new)  # e.g. model.c != 0 for a velocity joint; trajectory output: one input only
        old = getattr(self, "_config", None)
        if old is not None and self._lifecycle in ("inactive", "active"):
            # the stream's message layout and the measured state's joints are fixed at start-up
            shape = (multi_axis.is_multi(old), n_inputs(old), getattr(old.model, "rigid_bodies", ()))
            if (multi_axis.is_multi(new), n_inputs(new), getattr(new.model, "rigid_bodies", ())) != shape:
                raise ConfigError(
                    "model.inputs",
                    "the inputs and rigid bodies are fixed at start-up (the layout of 'commands' and of the measured "
                    "state): restart the planner with the new parameter file",
                )
        identification_settings(candidate)

    def _apply_parameters(self, params) -> None:
        if self._lifecycle not in ("inactive", "active"):
            return  # configure reads them
        v = self._values()
        self._config = planner_config(v)  # validated by the on-set callback
        self._replan_lead_s = float(v["replan_lead_s"])
        self._max_points = int(v["max_trajectory_points"])
        self._frame_id = str(v["frame_id"])
        self.stream.hold_when_idle = bool(v["publish_hold_when_idle"])
        self._apply_identification(v)
        changed = ", ".join(f"{p.name}={messages.value_text(p.value)}" for p in params)
        self.get_logger().info(f"parameters set ({changed}); the next goal uses them")

    @property
    def config(self) -> AnyConfig:
        """The configuration the next goal is planned with."""
        return self._config


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
    try:  # before rclpy.init: a fork is safe only while this process has one thread
        planning: PlanningProcesses | None = PlanningProcesses.fork()
    except (RuntimeError, OSError) as exc:
        sys.stderr.write(f"{NODE_NAME}: planning in-process (no planning processes: {exc})\n")
        planning = None
    try:  # last: it holds the planning children's pipes only as long as it lives, and it ends with this process
        streaming: StreamProcess | None = StreamProcess.fork(open_output)
    except (RuntimeError, OSError) as exc:
        sys.stderr.write(f"{NODE_NAME}: streaming in-process (no stream process: {exc})\n")
        streaming = None
    try:
        return run(
            lambda: PlannerNode(planning=planning, stream_process=streaming), SingleThreadedExecutor, NODE_NAME, args
        )
    finally:
        if streaming is not None:
            streaming.close()
        if planning is not None:
            planning.close()


__all__ = ["DIAGNOSTIC_NAME", "NODE_NAME", "PLANNER_NODE_ONLY", "PlannerNode", "main"]

if __name__ == "__main__":
    sys.exit(main())
