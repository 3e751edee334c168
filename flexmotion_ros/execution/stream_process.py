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

Protocol: length-prefixed pickles over three pipes (requests in, answers
out, events out: a fault), and an anonymous shared memory
(:class:`SharedProgress`) the child writes and the parent reads: the next
sample index, the samples sent, the publisher's matched subscriptions, the
deadline anchor, and a ring with one row per sample sent (index, send time,
lateness, the segment that started / finished there, the model input, the
system time just before publishing).  The child never waits for the parent:
a parent that falls behind by a whole ring loses rows (counted), never a sample.

Safety: whatever ends the child's stream -- a ``stop`` request (shutdown,
deactivation), a fault, the parent's death (end of file on the request pipe,
whatever killed it) -- the last command is the hold
(:meth:`~.command_stream.CommandStream.stop`).  SIGINT / SIGTERM are ignored
in the child: Ctrl-C reaches the whole process group, and the parent ends
the stream in order.
"""

from __future__ import annotations

import mmap
import os
import pickle
import select
import signal
import struct
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .command_stream import CommandStream, StreamHalt
from .heap import make_resident
from .output import OutputSettings, OutputStream
from .plan_process import reap_child
from .realtime import SlackCollector, raise_threads
from .stream_trace import StreamTrace
from .timeline import HOLD, Segment

#: Rows kept in the shared sample ring (65 s at 1 kHz): how far the parent may fall behind.
RING_ROWS = 1 << 16
#: The stream thread refreshes the publisher's matched-subscription count every this many samples sent
#: (and every ``IDLE_TICK_S`` while it sleeps); the child's main thread then wakes only for requests.
MATCH_SAMPLES = 100
#: Before the first configuration, or while the stream is stopped, the main thread refreshes it this often (s).
MATCH_PERIOD_S = 0.1
#: Values per sample the shared ring has room for (a machine with more inputs streams in-process).
MAX_INPUTS = 8
#: No segment started / finished at this sample (the ring's id columns).
NO_SEGMENT = -1.0

# header slots of SharedProgress
_ROWS, _K_NEXT, _SENT, _MATCHED, _T_ANCHOR, _K_ANCHOR, _INPUTS = range(7)
_HEADER = 8
# ring columns before the m command values
_K, _TIME, _LATE, _STARTED, _FINISHED = range(5)
_FIXED = 5
_LEN = struct.Struct("<I")


def send(fd: int, obj: Any) -> None:
    """Write one length-prefixed pickle to pipe ``fd`` (whole, even if the pipe takes it in parts)."""
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    view = memoryview(_LEN.pack(len(data)) + data)
    while view:
        view = view[os.write(fd, view) :]


def _read_exact(fd: int, n: int) -> bytes:
    parts, left = [], n
    while left:
        chunk = os.read(fd, left)
        if not chunk:
            raise EOFError("the other end closed the pipe")
        parts.append(chunk)
        left -= len(chunk)
    return b"".join(parts)


def recv(fd: int) -> Any:
    """Read one length-prefixed pickle from pipe ``fd`` (EOFError at end of file)."""
    (n,) = _LEN.unpack(_read_exact(fd, _LEN.size))
    return pickle.loads(_read_exact(fd, n))  # noqa: S301 -- our own child / parent, never a stranger


class SharedProgress:
    """The child's progress in anonymous shared memory (created before the fork, read by the parent).

    Parameters
    ----------
    max_inputs : int
        Room for this many command values per sample (the configuration says how many are used).
    rows : int
        Rows of the sample ring.
    """

    def __init__(self, max_inputs: int = MAX_INPUTS, rows: int = RING_ROWS) -> None:
        self.max_inputs = int(max_inputs)
        self.rows = int(rows)
        width = _FIXED + self.max_inputs
        size = 8 * (_HEADER + self.rows * width + self.rows)
        self._map = mmap.mmap(-1, size)  # MAP_SHARED | MAP_ANONYMOUS: the child's writes are the parent's reads
        buf = np.frombuffer(self._map, dtype=np.float64, count=_HEADER + self.rows * width)
        self.header = buf[:_HEADER]
        self.ring = buf[_HEADER:].reshape(self.rows, width)
        self.ring_ns = np.frombuffer(
            self._map, dtype=np.int64, count=self.rows, offset=8 * (_HEADER + self.rows * width)
        )
        make_resident(buf)  # every page now: a flat RSS, and no first-touch fault in the deadline loop
        make_resident(self.ring_ns)

    # ------------------------------------------------------------- the child
    def write_row(self, k: int, t: float, late: float, started: float, finished: float, value, t_ns: int) -> None:
        """Append one sample sent (the row first, then the count: a reader never sees a half-written row)."""
        n = int(self.header[_ROWS])
        i = n % self.rows
        row = self.ring[i]
        row[_K], row[_TIME], row[_LATE], row[_STARTED], row[_FINISHED] = k, t, late, started, finished
        row[_FIXED : _FIXED + int(self.header[_INPUTS])] = value
        self.ring_ns[i] = t_ns
        self.header[_ROWS] = n + 1
        self.header[_SENT] += 1

    def set_inputs(self, m: int) -> None:
        self.header[_INPUTS] = m

    def set_next(self, k_next: int) -> None:
        self.header[_K_NEXT] = k_next

    def set_matched(self, n: int) -> None:
        self.header[_MATCHED] = n

    def set_anchor(self, t_anchor: float, k_anchor: int) -> None:
        self.header[_T_ANCHOR], self.header[_K_ANCHOR] = t_anchor, k_anchor

    # ------------------------------------------------------------ the parent
    @property
    def written(self) -> int:
        """Rows written so far (samples sent by the child's stream)."""
        return int(self.header[_ROWS])

    @property
    def inputs(self) -> int:
        """Command values per sample of the current configuration."""
        return int(self.header[_INPUTS])

    @property
    def k_next(self) -> int:
        """The next sample index the child will send."""
        return int(self.header[_K_NEXT])

    @property
    def matched(self) -> int:
        """The ``commands`` publisher's matched subscriptions (writer side)."""
        return int(self.header[_MATCHED])

    @property
    def anchor(self) -> tuple[float, int]:
        """``(t_anchor, k_anchor)``: sample ``k_anchor`` is due at monotonic time ``t_anchor`` (s)."""
        return float(self.header[_T_ANCHOR]), int(self.header[_K_ANCHOR])

    def rows_from(self, first: int, last: int) -> tuple[np.ndarray, np.ndarray]:
        """Copies of ring rows ``first..last-1`` (their global counts; those overwritten are gone)."""
        idx = np.arange(max(first, last - self.rows), last) % self.rows
        return self.ring[idx].copy(), self.ring_ns[idx].copy()


@dataclass(frozen=True, kw_only=True)
class ChildSettings:
    """What the child's stream needs (sent at configure; everything else stays in the planner).

    Attributes
    ----------
    rate_hz : float
    hold_when_idle : bool
    priority : int
        ``stream_priority``: SCHED_FIFO of the deadline loop (0: normal); the child's other threads one below.
    inputs : int
        Values per sample.
    output : OutputSettings or None
        One input: the command interface (the setpoint encoder runs in the child); None for several inputs.
    model : Any
        The planner's model (the encoder's ``b0``; one input only).
    joint_name : str
    topic : str
        The resolved ``commands`` topic (the planner's name, remappings applied).
    namespace : str
        The planner's namespace (the child's node lives there).
    node_name : str
    qos_depth : int
    qos_reliable : bool
    """

    rate_hz: float
    hold_when_idle: bool
    priority: int
    inputs: int
    output: OutputSettings | None
    model: Any
    joint_name: str
    topic: str
    namespace: str
    node_name: str
    qos_depth: int
    qos_reliable: bool


#: ``open_output(settings) -> (publish(list_of_values), matched_count(), close())``: the child's ROS side.
OpenOutput = Callable[[ChildSettings], tuple[Callable[[list], None], Callable[[], int], Callable[[], None]]]


class _RowWriter:
    """Mixin of the child's stream: every sample sent becomes a row of the shared ring."""

    progress: SharedProgress
    sent_ns: int  # system time (ns) just before the last publish
    pending: list[float]  # the segments that started / finished at the sample being sent
    trace: StreamTrace | None  # the benchmarks' per-sample trace (stream_trace.TRACE_ENV)

    def step(self):
        out = super().step()  # type: ignore[misc]
        if out is not None and out.value is not None:
            if self.trace is not None:
                self.trace.step_done(out.sample, out.deadline, out.time)
            self.progress.write_row(
                out.sample,
                out.time,
                out.time - out.deadline,
                self.pending[0],
                self.pending[1],
                out.value,
                self.sent_ns,
            )
            self.pending = [NO_SEGMENT, NO_SEGMENT]
        return out

    def _next_value(self, k: int):
        value = super()._next_value(k)  # type: ignore[misc]
        self.progress.set_next(k + 1)  # under the stream's lock, when the sample is chosen
        return value

    def _halt(self, cause, why):
        new = self.halted is None  # type: ignore[attr-defined]
        halt = super()._halt(cause, why)  # type: ignore[misc]
        if new and halt.hold_sent:  # the hold that ended it is a sample sent too
            now = time.monotonic()
            self.progress.write_row(halt.sample - 1, now, 0.0, NO_SEGMENT, NO_SEGMENT, HOLD, time.time_ns())
            self.progress.set_next(halt.sample)
        return halt


class ChildOutputStream(_RowWriter, OutputStream):
    """One input: the setpoint encoder of the interface, rows in the ring."""


class ChildCommandStream(_RowWriter, CommandStream):
    """Several inputs: ``m`` values per sample, rows in the ring."""


class _Child:
    """The child's request handler: one stream at a time, built at ``configure``."""

    def __init__(self, progress: SharedProgress, events: int, open_output: OpenOutput) -> None:
        self.progress = progress
        self.events = events
        self.open_output = open_output
        self.stream: CommandStream | None = None
        self.matched: Callable[[], int] = lambda: 0
        self.close_output: Callable[[], None] = lambda: None
        self.collector = SlackCollector()
        self.trace = StreamTrace.from_environment()

    def configure(self, cfg: ChildSettings) -> None:
        self.end("reconfigured")
        if not 1 <= cfg.inputs <= self.progress.max_inputs:
            raise ValueError(f"{cfg.inputs} inputs: the stream process has room for 1..{self.progress.max_inputs}")
        publish, self.matched, self.close_output = self.open_output(cfg)
        self.progress.set_inputs(cfg.inputs)

        def publish_values(value) -> None:
            delay = trace.run_delay() if trace is not None else 0.0
            stream.sent_ns = time.time_ns()  # just before DDS stamps it (the feedback pairs readings with it)
            row = [float(value)] * cfg.inputs if np.ndim(value) == 0 else [float(v) for v in np.ravel(value)]
            publish(row)
            if trace is not None:
                trace.published(stream.sent_ns, delay)

        def on_start(seg: Segment) -> None:
            stream.pending[0] = float(seg.info)

        def on_finish(seg: Segment) -> None:
            stream.pending[1] = float(seg.info)

        def on_fault(halt: StreamHalt) -> None:
            try:
                send(self.events, ("fault", halt))
            except OSError:
                pass

        matched = self.matched
        progress = self.progress
        trace = self.trace
        collector = self.collector

        def after_sample(slack: float) -> None:
            t0 = time.monotonic() if trace is not None else 0.0
            if progress.written % MATCH_SAMPLES == 0:
                progress.set_matched(matched())
            if trace is None:
                collector(slack)
                return
            t1, before = time.monotonic(), list(collector.collections)
            collector(slack)
            trace.slack(t0, t1, next((g for g in range(3) if collector.collections[g] != before[g]), -1))

        def on_idle() -> None:
            progress.set_matched(matched())
            collector.idle()

        common = {
            "on_start": on_start,
            "on_finish": on_finish,
            "on_fault": on_fault,
            "priority": cfg.priority,
            "after_sample": after_sample,
            "on_idle": on_idle,
        }
        if trace is not None:
            common["sleep"] = trace.sleep  # which CPU, and what the thread went through inside the sleep
        stream: Any
        if cfg.output is not None:
            stream = ChildOutputStream(
                cfg.rate_hz,
                publish_values,
                cfg.hold_when_idle,
                settings=cfg.output,
                model=cfg.model,
                joint_name=cfg.joint_name,
                **common,
            )
        else:
            stream = ChildCommandStream(cfg.rate_hz, publish_values, cfg.hold_when_idle, **common)
        stream.progress = self.progress
        stream.pending = [NO_SEGMENT, NO_SEGMENT]
        stream.sent_ns = 0
        stream.trace = trace
        self.stream = stream

    def handle(self, op: str, args: tuple) -> Any:
        if op == "configure":
            self.configure(*args)
            return None
        stream = self.stream
        if stream is None:
            raise RuntimeError("the stream process is not configured")
        if op == "start":
            if stream.priority > 0:
                raise_threads(max(1, stream.priority - 1))  # DDS's threads too: one step below the loop
                # every generation collected and measured now, the heap so far frozen: the first samples no
                # longer pay a full collection of unknown cost (55-96 ms, the storm's first gap)
                self.collector.enable(prime=True, freeze=True)
                sys.setswitchinterval(min(sys.getswitchinterval(), 0.25 * stream.dt))
            stream.start()
            return stream.priority_error
        if op == "stop":
            return stream.stop(*args)
        if op == "start_now":
            ident, commands, first_state = args
            return stream.start_now(Segment(commands, first_state, info=ident))
        if op == "splice":
            ident, commands, first_state, at = args
            return stream.splice(Segment(commands, first_state, info=ident), at)
        if op == "hold_when_idle":
            stream.hold_when_idle = bool(args[0])
            return None
        raise ValueError(f"unknown request {op!r}")

    def end(self, why: str) -> StreamHalt | None:
        """The hold, and the publisher closed (the end of a configuration, or of the child)."""
        halt = None
        if self.stream is not None:
            halt = self.stream.stop(why)
            self.collector.disable()
            self.stream = None
            if self.trace is not None:
                self.trace.save()
        self.close_output()
        self.close_output = lambda: None
        self.matched = lambda: 0
        return halt


def serve(requests: int, answers: int, events: int, progress: SharedProgress, open_output: OpenOutput) -> None:
    """The child's loop: answer each request; end of file (the parent died or closed) ends it with the hold."""
    child = _Child(progress, events, open_output)
    try:
        while True:
            # no periodic wake-up while the stream runs: a thread taking this interpreter's lock at 10 Hz
            # cost the stream 5 ms gaps every 100 ms under load (its own thread refreshes the count then)
            streaming = child.stream is not None and child.stream.running
            ready, _, _ = select.select([requests], [], [], None if streaming else MATCH_PERIOD_S)
            if not streaming:
                try:
                    progress.set_matched(child.matched())
                except Exception:  # noqa: BLE001, S110 -- a count that cannot be read stays as it was
                    pass
            if not ready:
                continue
            t_request = time.monotonic()
            try:
                msg = recv(requests)
            except (EOFError, OSError):
                return  # the parent is gone: the finally below sends the hold
            if msg is None:
                return
            op, args = msg[0], tuple(msg[1:])
            try:
                answer: tuple = ("ok", child.handle(op, args))
            except Exception as exc:  # noqa: BLE001 -- answered, the loop goes on
                answer = ("error", type(exc).__name__, str(exc))
            stream = child.stream
            if stream is not None:
                progress.set_anchor(*stream.anchor())
            try:
                send(answers, answer)
            except OSError:
                return
            if child.trace is not None:  # the only other Python thread that runs while the stream does
                child.trace.request(op, t_request, time.monotonic())
    finally:
        child.end("the planner process ended")


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


__all__ = [
    "MAX_INPUTS",
    "ChildSettings",
    "OpenOutput",
    "SharedProgress",
    "StreamProcess",
    "recv",
    "send",
    "serve",
]
