"""The stream process's side: its request loop (:func:`serve`) and the stream it runs, one configuration at a time.

At ``configure`` the child builds its stream (:class:`ChildOutputStream` for
one input: the setpoint encoder of the interface; :class:`ChildCommandStream`
for several) around the publisher its ROS side opens (``open_output``,
injected: this module imports no ROS); every sample sent becomes a row of the
shared ring (:mod:`.stream_ipc`).  Its only other Python thread is this
request loop, which sleeps in ``select`` while the stream runs.  Whatever
ends it -- a ``stop`` request, a fault, the parent's death (end of file on
the request pipe) -- the last command is the hold.
"""

from __future__ import annotations

import select
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .command_stream import CommandStream
from .output import OutputSettings, OutputStream
from .realtime import SlackCollector, raise_threads
from .stream_halt import StreamHalt
from .stream_ipc import NO_SEGMENT, SharedProgress, recv, send
from .stream_trace import StreamTrace
from .timeline import HOLD, Segment

#: The stream thread refreshes the publisher's matched-subscription count every this many samples sent
#: (and every ``IDLE_TICK_S`` while it sleeps); the child's main thread then wakes only for requests.
MATCH_SAMPLES = 100
#: Before the first configuration, or while the stream is stopped, the main thread refreshes it this often (s).
MATCH_PERIOD_S = 0.1


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
            if trace is not None:
                trace.before_publish()
            stream.sent_ns = time.time_ns()  # just before DDS stamps it (the feedback pairs readings with it)
            row = [float(value)] * cfg.inputs if np.ndim(value) == 0 else [float(v) for v in np.ravel(value)]
            publish(row)
            if trace is not None:
                trace.published(stream.sent_ns)

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


__all__ = [
    "MATCH_PERIOD_S",
    "MATCH_SAMPLES",
    "ChildCommandStream",
    "ChildOutputStream",
    "ChildSettings",
    "OpenOutput",
    "serve",
]
