"""Planning in a child process, so that the command stream never waits for the planner's GIL.

A plan (``plan_move``: LPs, matrix exponentials) holds the interpreter lock for
most of its tens of milliseconds; a stream thread in the same process then
misses its deadlines (issue 14: gaps up to 443 ms while goals were planned).
:class:`PlanProcess` runs ``plan_move`` in a child process forked at start-up,
before any thread exists (the ``ros2 run`` executable forks it before
``rclpy.init``): the parent only sends the request and waits on a pipe, which
releases the lock, so the stream thread keeps its deadlines whatever is planned.

Measured (``bench/storm.py``, 2 CPUs at load 6, a 200 Hz stream under
SCHED_FIFO): planning in a thread left 39 gaps over two periods in 6 s, in the
child none (max 8.4 ms).

The protocol is pickle over two pipes: ``(config, problem, rate_hz, warm_start)`` in,
``("ok", PlanResult)`` or ``("error", type name, parameter, reason, message)``
out.  Our own errors (:mod:`flexmotion_ros.core.errors`) are rebuilt as
themselves; anything else becomes :class:`PlanProcessError` naming the
original type (an internal failure, reported as such).  If the child dies, the
call raises :class:`PlanProcessError` and the owner falls back to planning
in-process (a fork from a threaded process is not safe).

Priority (:meth:`PlanProcess.boost`): under ``stream_priority`` the node's
threads run under ``SCHED_FIFO``, but a child under normal scheduling is
preempted by every busy process on the machine: on 2 CPUs at load 9 a 4.5 ms
(CPU) plan took 19 ms from the request to the plan and 25 ms to the answer
(``bench/ros_streaming.py``, goal to first command 35 ms median).  Boosted,
the child plans under ``SCHED_FIFO`` (below the node's threads) for the first
:data:`BOOST_BUDGET_S` of each plan, then at normal scheduling until its
answer: a long plan never holds a CPU away from the machine's other work.
"""

from __future__ import annotations

import os
import pickle
import select
import signal
import sys
import threading
import time
from dataclasses import dataclass
from typing import Any

from ..core import errors
from ..core.config import PlannerConfig
from ..core.kernels import warm_up
from ..core.multi_input.dispatch import plan as plan_move  # plan_move, or plan_multi_move for several inputs
from ..core.results import PlanResult
from .realtime import set_process_priority

#: A boosted child plans under SCHED_FIFO for at most this long per plan (s), then at normal scheduling.
BOOST_BUDGET_S = 0.05

#: The errors rebuilt as themselves in the parent (by name; the parameter/reason ones with both).
_ERRORS: dict[str, type[errors.FlexmotionError]] = {
    cls.__name__: cls
    for cls in (
        errors.FlexmotionError,
        errors.InputError,
        errors.ModelError,
        errors.GoalError,
        errors.ConfigError,
        errors.SolverError,
        errors.UnreachableError,
    )
}


class PlanProcessError(RuntimeError):
    """The child failed: an unexpected exception there (its type named), or the child died."""


class PlanProcessClosed(PlanProcessError):
    """The child was closed (the node is shutting down) before or while this was planned."""


def _encode_error(exc: BaseException) -> tuple:
    return ("error", type(exc).__name__, getattr(exc, "parameter", None), getattr(exc, "reason", None), str(exc))


def _decode_error(kind: str, parameter: str | None, reason: str | None, message: str) -> BaseException:
    cls = _ERRORS.get(kind)
    if cls is None:
        return PlanProcessError(f"{kind} in the planning process: {message}")
    if issubclass(cls, errors.InputError):
        return cls(parameter or "", reason or message)
    return cls(message)


def serve(requests: Any, answers: Any) -> None:
    """The child's loop: plan each request, answer it; ``None`` (or a closed pipe) ends it."""
    while True:
        try:
            job = pickle.load(requests)
        except (EOFError, OSError):
            return
        if job is None:
            return
        config, problem, rate_hz, warm_start = job
        try:
            answer: tuple = ("ok", plan_move(config, problem, rate_hz, warm_start=warm_start))
        except Exception as exc:  # noqa: BLE001 -- every failure is answered, the loop goes on
            answer = _encode_error(exc)
        try:
            pickle.dump(answer, answers, protocol=pickle.HIGHEST_PROTOCOL)
            answers.flush()
        except (BrokenPipeError, OSError):
            return


class PlanProcess:
    """``plan_move`` in a forked child process; call it like ``plan_move(config, problem, rate_hz)``.

    Create it with :meth:`fork` while the process has a single thread (before
    ``rclpy.init``).  Calls are serialised (one plan at a time per child);
    :meth:`close` ends the child.
    """

    def __init__(self, pid: int, requests: Any, answers: Any, name: str) -> None:
        self.pid = pid
        self.name = name
        self._requests = requests
        self._answers = answers
        self._lock = threading.Lock()
        self.dead = False
        self.closed = False  # close() was called: the owner is shutting down
        self._boost = 0  # SCHED_FIFO priority of each plan's first BOOST_BUDGET_S (0: normal scheduling)
        self._lowered = True  # the child runs under normal scheduling now
        #: Seconds of each plan a boosted child runs under SCHED_FIFO.
        self.boost_budget_s = BOOST_BUDGET_S

    @classmethod
    def fork(cls, name: str = "flexmotion-planning") -> PlanProcess:
        """Fork the child (the caller must have one thread only: a fork copies no other thread)."""
        if threading.active_count() > 1:
            raise RuntimeError(f"fork the planning process before any thread starts ({threading.active_count()} run)")
        # compile (or load from numba's cache) the kernels before the fork: the child inherits them, so its
        # first plan neither compiles nor outlives a priority boost's budget loading them
        warm_up()
        to_child_r, to_child_w = os.pipe()
        to_parent_r, to_parent_w = os.pipe()
        sys.stdout.flush()
        sys.stderr.flush()
        pid = os.fork()
        if pid == 0:  # the child: plan until told to stop, then leave without running the parent's exit handlers
            status = 0
            try:
                # Ctrl-C reaches the whole process group: the parent shuts down in order and closes the child
                signal.signal(signal.SIGINT, signal.SIG_IGN)
                signal.signal(signal.SIGTERM, signal.SIG_IGN)
                os.close(to_child_w)
                os.close(to_parent_r)
                with os.fdopen(to_child_r, "rb") as requests, os.fdopen(to_parent_w, "wb") as answers:
                    serve(requests, answers)
            except BaseException:  # noqa: BLE001 -- nothing may escape into the parent's code
                status = 1
            finally:
                os._exit(status)
        os.close(to_child_r)
        os.close(to_parent_w)
        return cls(pid, os.fdopen(to_child_w, "wb"), os.fdopen(to_parent_r, "rb"), name)

    def boost(self, priority: int) -> str | None:
        """Plan under ``SCHED_FIFO`` ``priority`` for each plan's first :attr:`boost_budget_s`; 0: never.

        Takes effect at the next plan (a plan in progress keeps its scheduling until its budget ends).
        Returns why it was refused (then the child keeps normal scheduling), else None.
        """
        priority = max(0, int(priority))
        error = None if self.dead else set_process_priority(self.pid, priority)
        if error is not None:
            priority = 0
        self._boost = priority
        self._lowered = priority == 0
        return error

    @property
    def boosted(self) -> int:
        """The ``SCHED_FIFO`` priority of each plan's start (0: normal scheduling)."""
        return self._boost

    def __call__(
        self,
        config: PlannerConfig,
        problem: Any,
        rate_hz: float | None = None,
        *,
        warm_start: Any = None,
        urgent: bool = True,
    ) -> PlanResult:
        """Plan in the child; raises what ``plan_move`` raised there, or :class:`PlanProcessError`.

        ``warm_start``: ``plan_move``'s (a replan's guess, the rest of the plan being executed).
        ``urgent``: a boosted child (:meth:`boost`) plans this one boosted; False (a plan nothing waits to
        move on, e.g. ``~/plan``): at normal scheduling throughout.
        """
        with self._lock:
            if self.closed:
                raise PlanProcessClosed(f"the planning process {self.name} was closed: the node is shutting down")
            if self.dead:
                raise PlanProcessError(f"the planning process {self.name} ({self.pid}) is gone")
            boost = self._boost if urgent else 0
            if not boost and not self._lowered:  # this one is not urgent: normal scheduling throughout
                set_process_priority(self.pid, 0)
                self._lowered = True
            if boost and self._lowered:  # the last plan outlived its budget: this one starts boosted again
                self._lowered = set_process_priority(self.pid, boost) is not None
            try:
                pickle.dump((config, problem, rate_hz, warm_start), self._requests, protocol=pickle.HIGHEST_PROTOCOL)
                self._requests.flush()
                if boost and not self._lowered:
                    ready, _, _ = select.select([self._answers], [], [], self.boost_budget_s)
                    if not ready:  # a long plan: the rest at normal scheduling
                        set_process_priority(self.pid, 0)
                        self._lowered = True
                answer = pickle.load(self._answers)  # blocks in read(): the lock of this interpreter is free
            except (EOFError, OSError, ValueError, pickle.UnpicklingError) as exc:
                self.dead = True
                if self.closed:  # close() closed the pipes under this call (ValueError: a closed file)
                    raise PlanProcessClosed(
                        f"the planning process {self.name} was closed: the node is shutting down"
                    ) from None
                raise PlanProcessError(f"the planning process {self.name} ({self.pid}) died: {exc!r}") from None
        if answer[0] == "ok":
            return answer[1]
        raise _decode_error(*answer[1:])

    def close(self, timeout: float = 2.0) -> None:
        """Tell the child to stop and reap it (killed if it does not stop within ``timeout`` s)."""
        self.closed = True
        if not self.dead:
            try:
                pickle.dump(None, self._requests)
                self._requests.flush()
            except OSError:
                pass
        self.dead = True
        for f in (self._requests, self._answers):
            try:
                f.close()
            except OSError:
                pass
        reap_child(self.pid, timeout)


def reap_child(pid: int, timeout: float) -> None:
    """Wait up to ``timeout`` (s) for child ``pid`` to exit, then kill it (SIGKILL); reap it either way."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            done, _ = os.waitpid(pid, os.WNOHANG)
        except ChildProcessError:
            return
        if done:
            return
        threading.Event().wait(0.01)
    try:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
    except (ProcessLookupError, ChildProcessError):
        pass


@dataclass(frozen=True, kw_only=True)
class PlanningProcesses:
    """The planner node's two children: goals (and ``~/plan``) in one, stops in the other.

    Two, so that a stop never waits behind a goal still being planned (a
    cancelled goal's plan runs to its end in its child).
    """

    goal: PlanProcess
    stop: PlanProcess

    @classmethod
    def fork(cls) -> PlanningProcesses:
        """Fork both (before any thread exists; raises RuntimeError otherwise)."""
        goal = PlanProcess.fork("flexmotion-planning-goals")
        try:
            stop = PlanProcess.fork("flexmotion-planning-stops")
        except BaseException:
            goal.close()
            raise
        return cls(goal=goal, stop=stop)

    def close(self) -> None:
        """End both children."""
        self.goal.close()
        self.stop.close()


__all__ = [
    "BOOST_BUDGET_S",
    "PlanProcess",
    "PlanProcessClosed",
    "PlanProcessError",
    "PlanningProcesses",
    "serve",
    "reap_child",
]
