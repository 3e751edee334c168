"""Goal topics and services of ``flexmotion_planner`` (a part of :class:`~.planner_node.PlannerNode`).

``~/goal``, ``~/goals``, ``~/joint_trajectory``, ``~/move`` and ``~/plan``:
a target is checked on receipt (a bad one refused at once, never coalesced
away unseen) and handed to the planning thread (the newest goal wins); the
executor stays free for ``~/stop`` meanwhile.  Planning and installing the
request: :mod:`.planner_moves`.
"""

from __future__ import annotations

from collections.abc import Callable

from nav_msgs.srv import GetPlan
from rclpy.task import Future
from std_msgs.msg import Float64, Float64MultiArray
from trajectory_msgs.msg import JointTrajectory

from ..core.errors import FlexmotionError
from ..core.multi_input.dispatch import rest_state
from ..execution.requests import Request, RequestKind
from . import messages, multi_axis
from .planner_moves import MoveHandling, Outcome

#: A goal handed to an idle planning thread: the executor waits up to this long (s) for the thread to
#: prepare its plan (checks, start state, the request to the planning child) before its own work resumes.
#: Both need this process's interpreter lock: the executor's round after a callback (rebuilding its wait
#: set, ~0.3 ms) otherwise delayed the plan's start (measured 0.45 ms from the callback to the thread).
HANDOVER_WAIT_S = 0.002


class GoalHandling(MoveHandling):
    """The planner node's goal topics and services (a mixin of :class:`~.planner_node.PlannerNode`)."""

    def _on_goal(self, msg: Float64) -> None:
        try:  # several rigid bodies: refused with the reason (one target cannot say where each goes)
            target = multi_axis.goal_target(self._config, msg.data)
        except FlexmotionError as exc:
            self._refuse("~/goal", str(exc))
            return
        self._submit(RequestKind.GOAL, target, "~/goal")

    def _on_goals(self, msg: Float64MultiArray) -> None:
        try:
            target = multi_axis.goals_target(self._config, msg.data)
        except FlexmotionError as exc:
            self._refuse("~/goals", str(exc))
            return
        self._submit(RequestKind.GOAL, target, "~/goals")

    def _on_joint_trajectory(self, msg: JointTrajectory) -> None:
        try:
            goal = multi_axis.trajectory_target(self._config, msg, self._state.joint_name)
        except FlexmotionError as exc:
            self._refuse("~/joint_trajectory", str(exc))
            return
        if goal.target is None:
            source = "~/joint_trajectory (empty: stop)"
            if self._stop_begin(source)[0] is None:
                self._plan_stop_async(source)
        else:
            self._submit(RequestKind.GOAL, goal.target, "~/joint_trajectory", arrival_time=goal.arrival_time)

    async def _on_move(self, request: GetPlan.Request, response: GetPlan.Response) -> GetPlan.Response:
        return await self._answer_plan(request, response, execute=True)

    async def _on_plan(self, request: GetPlan.Request, response: GetPlan.Response) -> GetPlan.Response:
        return await self._answer_plan(request, response, execute=False)

    def _submit(
        self,
        kind: RequestKind,
        target: float,
        source: str,
        arrival_time: float | None = None,
        answer: Callable[[Outcome], None] | None = None,
    ) -> None:
        """Hand a goal (newest wins) or a query to the planning thread; the executor is free at once.

        ``answer(outcome)`` is called once, from the planning thread (or at once if refused here).
        """
        reply = answer if answer is not None else (lambda out: None)
        if kind is RequestKind.GOAL and self._lifecycle != "active":
            reply(self._refuse(source, f"the planner is {self._lifecycle} (lifecycle): activate it to move"))
            return
        try:  # a bad target is refused on receipt, never coalesced away unseen
            self._config.check_goal(target)
        except FlexmotionError as exc:
            reply(self._refuse(source, str(exc)))
            return
        if kind is RequestKind.GOAL:
            with self._stop_lock:  # the newest wins: a stop still being planned gives way to this goal
                if self._stop_ticket is not None and not self._stop_ticket.cancelled:
                    self._stop_ticket.cancelled = f"superseded by a newer goal ({source})"
        request = Request(kind=kind, target=target, source=source, arrival_time=arrival_time, answer=reply)
        if self._worker.submit(request) and kind is RequestKind.GOAL:
            request.handed_over.wait(HANDOVER_WAIT_S)  # bounded: a stop waits at most this long behind it

    async def _answer_plan(
        self, request: GetPlan.Request, response: GetPlan.Response, execute: bool
    ) -> GetPlan.Response:
        # planned in the planning thread: meanwhile the executor serves ~/stop, goals and the rest
        done: Future = Future()

        def answer(out: Outcome) -> None:
            done.set_result(out)
            self._wake_executor()

        kind = RequestKind.GOAL if execute else RequestKind.QUERY
        source = "~/move" if execute else "~/plan"
        try:  # x (one input); x, y, z: the first three rigid bodies
            target = multi_axis.pose_target(self._config, request.goal.pose.position)
        except FlexmotionError as exc:
            response.plan = messages.error_path(str(exc), self.get_clock().now().to_msg())
            return response
        self._submit(kind, target, source, answer=answer)
        out: Outcome = await done
        config = self._config
        if not out.ok:
            response.plan = messages.error_path(out.reason, self.get_clock().now().to_msg())
        elif out.segment is None:  # already there: a one-pose path
            states = rest_state(config.model, self._position)[None, :]
            response.plan = multi_axis.path(
                config, states, self.stream.dt, out.start_time, self._frame_id, self._max_points
            )
        else:
            response.plan = multi_axis.path(
                config, out.segment.states, self.stream.dt, out.start_time, self._frame_id, self._max_points
            )
        return response

    def _wake_executor(self) -> None:
        """Wake the executor so that a service waiting for the planning thread answers now."""
        try:
            self._wake.trigger()
        except Exception:  # noqa: BLE001, S110 -- the node is being destroyed: nobody waits any more
            pass
