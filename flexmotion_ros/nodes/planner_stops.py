"""Stops of ``flexmotion_planner`` (a part of :class:`~.planner_node.PlannerNode`).

``~/stop`` (and an empty ``~/joint_trajectory``) cancels the goal waiting or
being planned, then splices a ready stop
(:class:`~flexmotion_ros.execution.splice.StopPreparer`) at once; without a
usable one it plans the stop from the look-ahead in a thread of its own (in
the stop child, when the node has planning processes) and answers within
:data:`STOP_ANSWER_S`, saying from which sample the stop acts.  A goal
submitted meanwhile supersedes it (the newest wins).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable

import numpy as np
from rclpy.task import Future
from std_srvs.srv import Trigger

from ..core.errors import SolverError
from ..core.multi_input.dispatch import AnyConfig, body_positions, move_problem, positions_text
from ..execution import Segment, plan_summary
from ..execution.requests import Request, RequestKind
from ..execution.splice import READY_STOP_LEADS
from .planner_moves import MoveRecord, Outcome

#: ``~/stop`` answers within this (s): a stop still being planned then is answered with where it will start.
STOP_ANSWER_S = 0.01
#: A stop waits at most this (s) for a ready stop being planned (it starts sooner than one planned then).
STOP_READY_WAIT_S = 0.02


class _Until:
    """Awaitable in an rclpy coroutine callback: done once ``predicate()`` is true (checked when the executor wakes)."""

    def __init__(self, predicate: Callable[[], bool]) -> None:
        self._predicate = predicate

    def __await__(self):
        while not self._predicate():
            yield


class StopHandling:
    """The planner node's stops (a mixin of :class:`~.planner_node.PlannerNode`)."""

    def _stop_begin(self, source: str) -> tuple[Outcome | None, dict]:
        """A stop: cancel the goals waiting or being planned, then splice a ready stop (None if none is usable).

        Runs in the executor thread at once: it never waits behind a goal's plan
        (the goal being planned is dropped when its plan finishes).  Returns the
        outcome (None: plan the stop, :meth:`_plan_stop_async`) and where the
        request came (``request_sample``, ``lead_samples``: the look-ahead then).
        """
        k_next, timeline = self.stream.snapshot()
        where = {"request_sample": k_next, "lead_samples": self._lead_samples(), "moving": bool(timeline)}
        if self._lifecycle == "active":
            self._worker.cancel(f"superseded by a stop ({source}) before it started")
        return self._ready_stop(source, k_next + READY_STOP_LEADS * where["lead_samples"]), where

    def _plan_stop_async(self, source: str) -> Future:
        """Plan the stop in a thread of its own (one at a time: a second stop shares the first one's result).

        Not the planning thread: that may still be finishing a cancelled goal.  A
        goal submitted meanwhile supersedes the stop (newest wins).
        """
        with self._stop_lock:
            if self._stop_future is not None and not self._stop_future.done():
                return self._stop_future
            done: Future = Future()
            ticket = Request(kind=RequestKind.GOAL, target=math.nan, source=source, answer=lambda out: None)
            self._stop_future, self._stop_ticket = done, ticket

        def work() -> None:
            try:
                out = self.request(None, execute=True, source=source, ticket=ticket)
            except Exception as exc:  # noqa: BLE001 -- request() refuses instead of raising; never leave it unanswered
                out = Outcome(False, f"{type(exc).__name__}: {exc}")
            done.set_result(out)
            self._wake_executor()

        threading.Thread(target=work, name="flexmotion-stop", daemon=True).start()
        return done

    async def _on_stop(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        source = "~/stop"
        out, where = self._stop_begin(source)
        if out is None:  # none ready: planned in its own thread; answered when spliced or after STOP_ANSWER_S
            done = self._plan_stop_async(source)
            deadline = time.monotonic() + STOP_ANSWER_S
            timer = threading.Timer(STOP_ANSWER_S, self._wake_executor)
            timer.daemon = True
            timer.start()
            # mid-move: answered by the deadline; idle: nothing moves meanwhile, the answer waits for the
            # measured state (a restarted planner may find the machine moving)
            await _Until(lambda: done.done() or (where["moving"] and time.monotonic() >= deadline))
            timer.cancel()
            if not done.done():
                k, lead = where["request_sample"], where["lead_samples"]
                response.success = True
                response.message = (
                    f"stopping: the stop is being planned from the state predicted at sample {k + lead}, "
                    f"{lead} samples after the request (look-ahead {lead}); if it cannot be planned, the move "
                    "continues unchanged to its own end (see /diagnostics)"
                )
                return response
            out = done.result()
        response.success = out.ok
        if not out.ok:
            response.message = out.reason
        elif out.segment is None:
            response.message = out.reason or "already at rest"
        else:
            k_req, lead = where["request_sample"], where["lead_samples"]
            if "lead_samples" in out.info:  # planned now: its look-ahead counted from the request
                lead = out.info["planned_at_sample"] - k_req + out.info["lead_samples"]
            response.message = (
                f"stopping: {out.segment.samples} samples ({out.segment.samples * self.stream.dt:.6g} s), "
                f"at rest at {positions_text(body_positions(self._config.model, out.segment.states[-1]))}; "
                f"from sample {out.segment.start}, "
                f"{out.segment.start - k_req} samples after the request (look-ahead {lead})"
                + (
                    f"; a ready stop (taken within {READY_STOP_LEADS} look-aheads)"
                    if "stop_lead_samples" in out.info
                    else ""
                )
                + (
                    f"; planned {out.info['plan_attempts']} times (the look-ahead was overrun or the timeline changed)"
                    if out.info.get("plan_attempts", 1) > 1
                    else ""
                )
            )
        return response

    def _plan_stop(self, x0: np.ndarray, config: AnyConfig) -> Segment:
        """The stop from ``x0`` (final position free), planned and verified like every plan (preparer thread)."""
        t0 = time.perf_counter()
        problem = move_problem(config, x0, None)
        result = self._planner_for(problem)(config, problem, config.rate_hz)
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

    def _ready_stop(self, source: str, latest: int) -> Outcome | None:
        """Splice a ready stop starting by sample ``latest``; None if none is usable (then plan it)."""
        stops = self._stops
        if stops is None or self._lifecycle != "active":
            return None
        t_req = time.monotonic()
        with self._install_lock:
            k_req, timeline = self.stream.snapshot()
            if not timeline:
                return None
            # none ready but one being planned: worth waiting for (it starts sooner than a plan made now)
            # not taken if it starts much later than a stop planned now would (READY_STOP_LEADS)
            ready = stops.take(wait_s=min(STOP_READY_WAIT_S, 2.0 * max(stops.plan_times, default=0.0)), latest=latest)
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
