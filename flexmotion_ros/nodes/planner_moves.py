"""Planning and installing a request of ``flexmotion_planner`` (a part of :class:`~.planner_node.PlannerNode`).

Every request -- ``~/goal``, ``~/joint_trajectory``, ``~/move``, ``~/plan``,
``~/stop`` -- ends in :meth:`MoveHandling.request`: plan from the measured
state when idle, or from the state the timeline predicts at the splice sample
during a move (:mod:`flexmotion_ros.execution.splice`), in the planning child
when the node has one, then install it into the stream under the install
lock.  Refusals never raise: one line in the log, on ``/diagnostics`` and in
the answer.  The topics and services that submit requests:
:mod:`.planner_goals`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from ..core.errors import FlexmotionError, GoalError, InputError, SolverError
from ..core.multi_input.dispatch import (
    AnyConfig,
    check_budgets,
    move_problem,
    positions_text,
    rest_state,
    state_at_rest,
    state_size,
)
from ..core.multi_input.dispatch import plan as plan_move  # plan_move, or plan_multi_move for several inputs
from ..core.results import PlanResult
from ..execution import (
    SPLICE_ATTEMPTS,
    Segment,
    ended_at_rest,
    lead_samples,
    longer_lead,
    plan_summary,
    splice_point,
)
from ..execution.measured_state import AT_REST_TOL, EarlyArrival
from ..execution.plan_process import PlanProcessClosed
from ..execution.realtime import lower_threads
from ..execution.requests import Request, RequestKind
from ..execution.stream_halt import StreamStopped
from . import messages, multi_axis


@dataclass
class MoveRecord:
    """What a segment on the stream came from."""

    result: PlanResult  # or a MultiPlanResult (several inputs)
    target: float | np.ndarray | None
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


def _plan_here(
    config: AnyConfig, problem, rate_hz: float | None, *, warm_start=None, urgent: bool = True
) -> PlanResult:
    """``plan_move`` (``plan_multi_move`` for several inputs) in this process (looked up at each call: tests replace it).

    ``urgent`` is the planning child's (:meth:`~flexmotion_ros.execution.plan_process.PlanProcess.__call__`): no effect here.
    """
    if warm_start is None:
        return plan_move(config, problem, rate_hz)
    return plan_move(config, problem, rate_hz, warm_start=warm_start)


def _has_target(problem) -> bool:
    """A goal (some final position given), not a stop (every final position free)."""
    include = getattr(problem, "include_position", None)
    return bool(include) if include is not None else any(t is not None for t in problem.targets)


class MoveHandling:
    """The planner node's plans and their installation (a mixin of :class:`~.planner_node.PlannerNode`)."""

    def _handle(self, req: Request) -> Outcome:
        """The planning thread's work: one request, planned (and for a goal, installed)."""
        return self.request(
            req.target,
            execute=req.kind is RequestKind.GOAL,
            source=req.source,
            arrival_time=req.arrival_time,
            ticket=req,
        )

    def _planning_a_goal(self) -> bool:
        """A goal (not a query, not cancelled) is being planned now: the stop preparer pauses."""
        req = self._worker.planning
        return req is not None and req.kind is RequestKind.GOAL and not req.cancelled

    def _not_planned(self, req: Request, reason: str) -> Outcome:
        """The answer to a request superseded by a newer goal, cancelled by a stop, or refused as busy."""
        self.get_logger().info(f"{req.source}: not planned: {reason}")
        return Outcome(False, reason)

    def request(
        self,
        target: float | None,
        execute: bool,
        source: str,
        arrival_time: float | None = None,
        ticket: Request | None = None,
    ) -> Outcome:
        """Plan a move to ``target`` (None: stop) and, if ``execute``, stream it.

        ``arrival_time`` (s, from the move's first command): arrive at rest
        then (method ``fixed_time``); None: the configured method.  From idle,
        the move starts from the measured state (``state.source``).

        Never raises for bad input: a refused request returns ``ok=False`` and
        the reason, logs it and publishes ERROR on /diagnostics.  ``ticket``:
        the planning thread's request; cancelled meanwhile (a stop), its plan
        is dropped, never installed.
        """
        t_req = ticket.requested_at if ticket is not None else time.monotonic()
        if execute and self._lifecycle != "active":
            return self._refuse(source, f"the planner is {self._lifecycle} (lifecycle): activate it to move")
        self._status.set_planning(source)
        try:
            out = self._plan_request(target, execute, source, t_req, arrival_time, ticket)
        except (FlexmotionError, SolverError) as exc:
            return self._refuse(source, str(exc))
        except (PlanProcessClosed, StreamStopped) as exc:  # a request still in flight when the node shuts down
            return self._refuse(source, f"not planned: {exc}")
        except Exception as exc:  # noqa: BLE001 -- keep serving whatever a method raises
            self.get_logger().error(f"{source}: unexpected {type(exc).__name__}")
            return self._refuse(source, f"{type(exc).__name__}: {exc}")
        finally:
            self._status.set_planning("")
        if out is None:  # cancelled while planned
            return self._not_planned(ticket, ticket.cancelled)
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
            return rest_state(model, self._position)
        st = self._state
        if not execute:
            try:
                return self._listener.store.fresh(self._state_joints, st.timeout_s, self._listener.topic, wait=False)
            except GoalError:
                return rest_state(model, self._position)
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
        return None if state_at_rest(self._config.model, x, AT_REST_TOL) else x

    def _planner_for(self, problem) -> Callable[..., PlanResult]:
        """Where ``problem`` is planned: the stop child (final position free) or the goal child; else here.

        A child that died is replaced by planning here, in a thread (a fork from a threaded process is
        not safe): the stream then shares the lock again, which the log says once.
        """
        children = self._children
        if children is None:
            return _plan_here
        child = children.goal if _has_target(problem) else children.stop
        if child.closed:  # shutting down: calling it refuses (PlanProcessClosed), nothing is planned here
            return child
        if child.dead:
            self.get_logger().error(f"planning process {child.name} is gone: planning in-process from now on")
            self._children = None
            lower_threads(keep_fifo=("flexmotion-stream",))  # planning here must not run under SCHED_FIFO
            return _plan_here
        return child

    def _plan_to(self, config: AnyConfig, problem, arrival_time: float | None, urgent: bool = True) -> PlanResult:
        """``plan_move``; with ``arrival_time`` (s) method ``fixed_time`` (``trajectory.early_arrival`` if too early).

        In the planning child for goals, or for stops (the final position free), when the node has them;
        ``urgent`` (a move waits for it): boosted there under ``stream_priority`` (``~/plan``: not).
        """
        planner = self._planner_for(problem)

        def plan(c: AnyConfig, p, rate: float | None) -> PlanResult:
            return planner(c, p, rate, urgent=urgent)

        if arrival_time is None:
            return plan(config, problem, config.rate_hz)
        timed = replace(config, method="fixed_time", options={**config.options, "arrival_time": float(arrival_time)})
        try:
            return plan(timed, problem, config.rate_hz)
        except InputError as exc:
            if exc.parameter != "arrival_time":
                raise
            if self._state.early_arrival is EarlyArrival.OPTIMUM:
                self.get_logger().info(
                    f"time_from_start {arrival_time:.6g} s is before the optimum: arriving as fast as possible "
                    "(trajectory.early_arrival: optimum)"
                )
                return plan(config, problem, config.rate_hz)
            raise GoalError(
                "joint_trajectory.points[-1].time_from_start",
                f"{arrival_time:.9g} s is before the fastest arrival ({exc.reason}); refused "
                "(trajectory.early_arrival: refuse; 'optimum' arrives as fast as possible instead)",
            ) from None

    def _plan_request(
        self,
        target,
        execute: bool,
        source: str,
        t_req: float,
        arrival_time: float | None = None,
        ticket: Request | None = None,
    ) -> Outcome | None:
        """Plan outside the install lock, install under it; None if ``ticket`` was cancelled meanwhile."""
        config = self._config
        model = config.model
        if target is not None:
            target = config.check_goal(target)
            if execute and self.commands_publisher.get_subscription_count() == 0:
                raise GoalError(
                    "commands",
                    "no subscriber is matched on 'commands' (writer side): nothing would move; start the "
                    "controller, or wait for the planner's 'streaming ready' (DDS discovery can take seconds)",
                )
        lead = self._lead_samples()
        for _attempt in range(SPLICE_ATTEMPTS):
            k_next, timeline, version = self.stream.versioned_snapshot()
            multi = multi_axis.is_multi(config)
            point = splice_point(timeline, k_next, lead, None if multi else model.n_modes)  # None: idle
            if point is not None and point.state.size != state_size(model):
                raise GoalError(
                    "model",
                    f"the state size changed during a move ({point.state.size} -> {state_size(model)}): "
                    "stop or wait until idle, then send the goal again",
                )
            if point is None:
                at = None
                if target is None:
                    x0 = self._idle_moving_state()  # a machine moving after a restart: stop it
                    if x0 is None:
                        return Outcome(True, f"already at rest at {positions_text(self._position)}")
                else:
                    x0 = self._idle_start_state(execute)
            else:
                at, x0 = point.sample, point.state
            # a partial goal keeps the other rigid bodies' targets: where the timeline ends, or where it is now
            kept_state = timeline[-1].states[-1] if point is not None else x0
            goal = multi_axis.resolve_target(config, target, kept_state)
            problem = move_problem(config, x0, goal)
            check_budgets(config, problem)  # both budgets in microseconds: an absurd goal never reaches the planner
            if ticket is not None:  # the executor, waiting for this (planner_goals.HANDOVER_WAIT_S), resumes
                ticket.handed_over.set()
            t0 = time.perf_counter()
            result = self._plan_to(config, problem, arrival_time, urgent=execute)
            plan_time = time.perf_counter() - t0
            self._plan_times.append(plan_time)
            sampled = result.sampled
            if sampled is None:
                raise SolverError(f"method {config.method} returned no sampled command sequence")
            record = MoveRecord(result, goal, source, t_req, at is None, plan_time)
            seg = Segment(np.asarray(sampled.commands, float), np.asarray(sampled.states, float), info=record)
            info = plan_summary(result, plan_time)
            if not execute:
                k0 = k_next if at is None else at
                return Outcome(True, "", seg, self._ros_time_of(k0), info)
            with self._install_lock:  # held for the splice only: a stop never waits for a plan
                if ticket is not None and ticket.cancelled:
                    return None
                if self.stream.version != version:  # a stop or a goal was installed meanwhile: plan from it
                    self.get_logger().info(f"{source}: the timeline changed while planning; replanning")
                    continue
                if at is None and seg.samples == 0:
                    self._position = multi_axis.position_of(config, x0)  # measured there, at rest
                    return Outcome(
                        True, f"already at {positions_text(self._position)}", None, self._ros_time_of(k_next), info
                    )
                if at is None or not self.stream.splice(seg, at):
                    # the timeline ran out while planning: valid from rest only if x0 was the rest at its end
                    if at is not None and not ended_at_rest(timeline, at, self.stream.idle):
                        # overran the look-ahead: plan again from a later sample
                        self.get_logger().warning(
                            f"{source}: planning took {plan_time * 1e3:.0f} ms, beyond the {lead} sample "
                            "look-ahead; replanning"
                        )
                        lead = longer_lead(lead)
                        continue
                    self._move_requested_at = t_req
                    seg.info.from_idle = True
                    self.stream.start_now(seg)
                info["plan_attempts"] = _attempt + 1  # > 1: the look-ahead was overrun (or the timeline changed)
                info["planned_at_sample"], info["lead_samples"] = k_next, lead  # the look-ahead this plan had
                self._installed(seg, goal, info, source)
                self._predicted_end = np.array(seg.states[-1], float)
                return Outcome(True, "", seg, self._ros_time_of(seg.start), info)
        raise SolverError(
            f"planning overran its look-ahead {SPLICE_ATTEMPTS} times (last {lead} samples); the move continues unchanged"
        )

    def _installed(self, seg: Segment, target: float | None, info: dict, source: str) -> None:
        if self._stops is not None:
            self._stops.notify(info.get("plan_time_s"))
        self.installed.append(seg)
        config = self._config
        self._position = multi_axis.position_of(config, seg.states[-1])
        where = target if target is not None else self._position
        self._status.moving(where if np.ndim(where) == 0 else positions_text(where), info, move=seg.info)
        stamp = messages.to_time(self._ros_time_of(seg.start))
        self._trajectory_pub.publish(
            multi_axis.planned_trajectory(config, seg.states, seg.commands, self.stream.dt, stamp, self._max_points)
        )
        if seg.samples + 1 > self._max_points:
            self.get_logger().info(
                f"~/planned_trajectory decimated: {seg.samples + 1} samples > max_trajectory_points {self._max_points}"
            )
        what = f"to {positions_text(target)}" if target is not None else f"stop at {positions_text(self._position)}"
        self.get_logger().info(
            f"{source}: {what}: {info['samples']} samples ({info['duration_s']:.6g} s, certified {info['certified']}), "
            f"planned in {info['plan_time_s'] * 1e3:.1f} ms, from sample {seg.start}"
        )
