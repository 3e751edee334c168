"""Goal requests, ROS-free: the newest goal wins, a stop never waits behind one.

The planner node plans goals off its executor thread, in one
:class:`RequestWorker` thread, so that the executor keeps taking requests
while a goal is planned (a plan may take seconds):

* **Goals coalesce to the newest.**  At most one goal waits: a goal that
  arrives while another waits *supersedes* it (the waiting one is answered
  "superseded", never planned, and counted in :attr:`RequestWorker.superseded`,
  which the node reports on ``/diagnostics``).  A burst of 100 goals is planned
  as at most two (the one being planned and the newest), and none is lost
  unseen.
* **A stop preempts planning.**  :meth:`RequestWorker.cancel` answers the
  waiting goal and marks the one being planned as cancelled: its plan is
  dropped when it finishes (it is never installed); the stop itself is
  handled by the caller at once, not queued behind the goal.
* **Plan-only queries** (``~/plan``: nothing moves) are answered in order,
  at most :data:`MAX_QUERIES` waiting (then refused as busy), and never
  supersede or get superseded.

Every request gets exactly one answer, through its ``answer`` callback
(called from the worker thread, or from the thread that superseded or
cancelled it).
"""

from __future__ import annotations

import enum
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from .heap import release_free_heap

#: Plan-only queries that may wait; more are refused at once (a bounded queue: flat memory under a storm).
MAX_QUERIES = 16
#: The worker hands freed heap memory back to the system when idle, at most this often (s): ~5 ms a time.
RELEASE_PERIOD_S = 30.0


class RequestKind(enum.Enum):
    """What a request asks for."""

    GOAL = "goal"  # plan and move (``~/goal``, ``~/joint_trajectory``, ``~/move``)
    QUERY = "query"  # plan only, nothing moves (``~/plan``)


@dataclass(kw_only=True, eq=False)
class Request:
    """One request to the planner.

    Attributes
    ----------
    kind : RequestKind
    target : float
        The goal position (m or rad).
    source : str
        Where it came from (``~/goal``, ``~/move``, ...), for the log.
    arrival_time : float or None
        Requested arrival (s, from the first command), or None.
    answer : callable
        ``answer(outcome)``: called exactly once with the node's outcome (or
        with the ``superseded`` / ``cancelled`` text given to :meth:`RequestWorker.cancel`).
    requested_at : float
        Monotonic time (s) the request arrived.
    cancelled : str
        Non-empty once cancelled (the reason): its plan must not be installed.
    handed_over : threading.Event
        Set once the worker has done the request's own work up to its plan (see :meth:`RequestWorker.submit`),
        and at the latest when it is answered.
    """

    kind: RequestKind
    target: float
    source: str
    answer: Callable[[Any], None]
    arrival_time: float | None = None
    requested_at: float = field(default_factory=time.monotonic)
    cancelled: str = ""
    handed_over: threading.Event = field(default_factory=threading.Event)
    _answered: bool = False

    def reply(self, outcome: Any) -> None:
        """Answer once (a second answer is ignored)."""
        if self._answered:
            return
        self._answered = True
        self.handed_over.set()
        self.answer(outcome)


class RequestWorker:
    """The one thread that plans goals and queries, newest goal first.

    Parameters
    ----------
    handle : callable
        ``handle(request) -> outcome``: plan (and for a goal, install) the
        request; must not raise (the node refuses with the reason).
    refused : callable
        ``refused(request, reason) -> outcome``: the outcome that answers a
        request that is superseded, cancelled or refused as busy.
    """

    def __init__(self, handle: Callable[[Request], Any], refused: Callable[[Request, str], Any]) -> None:
        self._handle = handle
        self._refused = refused
        self._cond = threading.Condition()
        self._goal: Request | None = None
        self._queries: deque[Request] = deque()
        self._current: Request | None = None
        self._stop = False
        self._thread: threading.Thread | None = None
        #: Goals superseded by a newer one before they were planned (counted since start-up).
        self.superseded = 0
        #: Goals cancelled (waiting or being planned) by a stop or a deactivation.
        self.cancelled = 0
        #: Times the worker handed freed heap memory back to the system (when idle, every RELEASE_PERIOD_S).
        self.releases = 0
        self._released = time.monotonic()

    # ----------------------------------------------------------------- control
    def start(self) -> None:
        """Start the thread."""
        with self._cond:
            self._stop = False
        self._thread = threading.Thread(target=self._run, name="flexmotion-planning", daemon=True)
        self._thread.start()

    def stop(self, reason: str = "the planner is shutting down", timeout: float = 2.0) -> None:
        """Answer everything waiting with ``reason``, end the thread (a plan in progress is dropped)."""
        with self._cond:
            self._stop = True
            self._cond.notify_all()
        self.cancel(reason, queries=True)
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout)

    @property
    def planning(self) -> Request | None:
        """The request being planned now (None if none)."""
        with self._cond:
            return self._current

    def submit(self, request: Request) -> bool:
        """Queue ``request``: a goal replaces (and answers as superseded) the goal waiting, a query waits in order.

        Returns True if the worker was idle (it takes this request next, at once): the caller may then
        wait a little on :attr:`Request.handed_over` (the node's executor does, for a goal), so that the
        worker prepares the plan before the caller's own work takes the interpreter lock back.
        """
        old: Request | None = None
        busy = False
        with self._cond:
            idle = self._current is None and self._goal is None and not self._queries
            if self._stop:
                busy = True
            elif request.kind is RequestKind.GOAL:
                old, self._goal = self._goal, request
                if old is not None:
                    self.superseded += 1
            elif len(self._queries) >= MAX_QUERIES:
                busy = True
            else:
                self._queries.append(request)
            self._cond.notify_all()
        if busy:
            why = "the planner is shutting down" if self._stop else f"busy: {MAX_QUERIES} plan requests already wait"
            request.reply(self._refused(request, why))
        if old is not None:
            old.reply(self._refused(old, f"superseded by a newer goal (from {request.source}) before it was planned"))
        return idle and not busy

    def cancel(self, reason: str, queries: bool = False) -> int:
        """Cancel the goal waiting and the goal being planned (``queries``: the waiting queries too).

        The waiting ones are answered with ``reason`` now; the one being
        planned is marked (:attr:`Request.cancelled`): the handler must drop
        its plan and answer it with the reason.  Returns how many goals were cancelled.
        """
        with self._cond:
            waiting = [self._goal] if self._goal is not None else []
            self._goal = None
            if queries:
                waiting += list(self._queries)
                self._queries.clear()
            current = self._current
            n = sum(1 for r in waiting if r.kind is RequestKind.GOAL)
            if current is not None and current.kind is RequestKind.GOAL and not current.cancelled:
                current.cancelled = reason
                n += 1
            self.cancelled += n
        for r in waiting:
            r.reply(self._refused(r, reason))
        return n

    # ------------------------------------------------------------------ thread
    def _next(self) -> Request | None:
        with self._cond:
            while not self._stop and self._goal is None and not self._queries:
                self._cond.wait()
            if self._stop:
                return None
            if self._goal is not None:  # the newest motion first: a query only reads
                req, self._goal = self._goal, None
            else:
                req = self._queries.popleft()
            self._current = req
            return req

    def _run(self) -> None:
        while True:
            req = self._next()
            if req is None:
                return
            try:
                outcome = self._handle(req)
            except Exception as exc:  # noqa: BLE001 -- the handler should not raise; never leave a request unanswered
                outcome = self._refused(req, f"{type(exc).__name__}: {exc}")
            with self._cond:
                self._current = None
                idle = self._goal is None and not self._queries
            req.reply(outcome)
            now = time.monotonic()
            if idle and now - self._released >= RELEASE_PERIOD_S:  # flat RSS over a long run (execution.heap)
                self._released = now
                self.releases += 1
                release_free_heap()


__all__ = ["MAX_QUERIES", "RELEASE_PERIOD_S", "Request", "RequestKind", "RequestWorker"]
