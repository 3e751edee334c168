"""The command stream in a process of its own: the child's side (fork, shared progress, its request loop).

In the planner's process the stream thread shares the interpreter lock with
the executor, DDS callbacks, message building (a 3000-point
``~/planned_trajectory`` costs ~33 ms of CPU to build), diagnostics and the
feedback: any of them holding the lock when a deadline comes delays the
sample.  Planning already runs in forked children (:mod:`.plan_process`);
here the deadline loop itself does: :meth:`StreamProcess.fork` forks a child
before ``rclpy.init``, whose only work is the absolute-deadline loop and the
``commands`` publisher (its own rclpy context, one tiny node, injected by the
caller as ``open_output``: this module imports no ROS).  The planner keeps the
whole decision logic and talks to the child through :class:`~.remote_stream.RemoteStream`.

Protocol: length-prefixed pickles over three pipes and the child's progress
in shared memory (:mod:`.stream_ipc`); the child's request loop and its
stream: :mod:`.stream_server`.  This module is the parent's handle
(:class:`StreamProcess`: fork, one request at a time, close).

Safety: whatever ends the child's stream -- a ``stop`` request (shutdown,
deactivation), a fault, the parent's death (end of file on the request pipe,
whatever killed it) -- the last command is the hold
(:meth:`~.command_stream.CommandStream.stop`).  SIGINT / SIGTERM are ignored
in the child: Ctrl-C reaches the whole process group, and the parent ends
the stream in order.
"""

from __future__ import annotations

import os
import select
import signal
import sys
import threading
from dataclasses import dataclass
from typing import Any

from .plan_process import reap_child
from .stream_ipc import SharedProgress, recv, send
from .stream_server import MATCH_PERIOD_S, OpenOutput, serve


@dataclass
class StreamProcess:
    """The parent's handle of the stream child: its pid, pipes and shared progress.

    Create it with :meth:`fork` while the process has a single thread (before
    ``rclpy.init``, after the planning children: the child then holds none of
    their parent-side pipes in a way that matters -- it ends with its parent).
    """

    pid: int
    requests: int
    answers: int
    events: int
    progress: SharedProgress
    dead: bool = False

    def __post_init__(self) -> None:
        self._lock = threading.Lock()

    @classmethod
    def fork(cls, open_output: OpenOutput) -> StreamProcess:
        """Fork the child (one thread only); it waits for ``configure``."""
        if threading.active_count() > 1:
            raise RuntimeError(f"fork the stream process before any thread starts ({threading.active_count()} run)")
        progress = SharedProgress()
        req_r, req_w = os.pipe()
        ans_r, ans_w = os.pipe()
        ev_r, ev_w = os.pipe()
        sys.stdout.flush()
        sys.stderr.flush()
        pid = os.fork()
        if pid == 0:
            status = 0
            try:
                signal.signal(signal.SIGINT, signal.SIG_IGN)
                signal.signal(signal.SIGTERM, signal.SIG_IGN)
                for fd in (req_w, ans_r, ev_r):
                    os.close(fd)
                serve(req_r, ans_w, ev_w, progress, open_output)
            except BaseException:  # noqa: BLE001 -- nothing may escape into the parent's code
                status = 1
            finally:
                os._exit(status)
        for fd in (req_r, ans_w, ev_w):
            os.close(fd)
        return cls(pid=pid, requests=req_w, answers=ans_r, events=ev_r, progress=progress)

    def call(self, op: str, *args: Any, timeout: float = 5.0) -> Any:
        """One request, its answer (raises what the child raised as RuntimeError, or on a dead child)."""
        with self._lock:
            if self.dead:
                raise RuntimeError(f"the stream process ({self.pid}) is gone")
            try:
                send(self.requests, (op, *args))
                ready, _, _ = select.select([self.answers], [], [], timeout)
                if not ready:
                    raise TimeoutError(f"no answer to {op!r} within {timeout:g} s")
                answer = recv(self.answers)
            except (EOFError, OSError, TimeoutError) as exc:
                self.dead = True
                raise RuntimeError(f"the stream process ({self.pid}) failed: {exc}") from None
        if answer[0] == "ok":
            return answer[1]
        raise RuntimeError(f"{answer[1]} in the stream process: {answer[2]}")

    def close(self, timeout: float = 2.0) -> None:
        """End the child (it sends the hold if it was streaming) and reap it."""
        with self._lock:
            if not self.dead:
                try:
                    send(self.requests, None)
                except OSError:
                    pass
            self.dead = True
            for fd in (self.requests, self.answers, self.events):
                try:
                    os.close(fd)
                except OSError:
                    pass
        reap_child(self.pid, timeout)


# MATCH_PERIOD_S: the node's documentation refers to it here (the main thread's refresh of the matched count)
__all__ = ["MATCH_PERIOD_S", "StreamProcess"]
