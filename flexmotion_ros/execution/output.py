"""What the planner puts on the wire: a command stream or trajectories, in the joint's command interface.

``output: stream`` (the default) publishes one value per sample on
``commands``; ``output: trajectory`` publishes the whole planned sequence as
a joint trajectory (:mod:`.trajectory`) that the receiver plays by its own
clock.  The settings and their checks are :mod:`.output_config`.  Either way ``command_interface`` says which value: the force
(``effort``), or the velocity / position reference of a servo-driven joint
integrated exactly from the plan (:mod:`flexmotion_ros.core.interfaces`).

* :class:`SetpointEncoder` turns the stream's model inputs ``u_k`` into the
  setpoints of the interface, sample by sample, with the same recursion as
  :func:`~flexmotion_ros.core.interfaces.reference.joint_reference` (so a
  one-segment move is bit for bit its reference), and gives the hold: 0 N,
  0 m/s, or the position where the joint is -- never 0 m for a position joint.
* :class:`OutputStream` is the command stream with those hooks: in stream
  mode it publishes the encoded setpoints (the hold on every ending, as the
  plain stream does); in trajectory mode it publishes nothing per sample, and
  every installation (a move from idle, a preemption, a stop, a replan)
  publishes the timeline's trajectory from the sample being played
  (:func:`~.trajectory.timeline_trajectory`), every ending (stop, shutdown,
  deactivation, fault) a one-point hold trajectory.

Trajectory timing.  The stream's sample ``k`` and the trajectory's sample
``k`` are the same instant (:class:`~.trajectory.SampleClock` anchored on the
stream), so the stream's timeline *is* the receiver's.  A trajectory must
reach the receiver before its first point: a move from idle therefore starts
``start_delay`` samples after the next one (the receiver holds meanwhile: a
pad of hold samples on the timeline), and a splice closer than
``splice_margin`` samples is refused (the caller then plans again from
further ahead, as for a plan that overran its look-ahead).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from scipy.linalg import expm

from ..core.interfaces.command import CommandInterface, check_acceleration_model, command_interface
from ..core.model.modal_model import ModalModel
from .command_stream import CommandStream

# The settings, exported from here too (the nodes and the stream process import them so).
from .output_config import MAX_START_DELAY_S, OutputMode, OutputSettings, output_settings
from .stream_halt import StreamHalt
from .timeline import HOLD, Segment, predicted_state
from .trajectory import (
    NS,
    JointTrajectory,
    SampleClock,
    TrajectoryPoint,
    timeline_trajectory,
)


class SetpointEncoder:
    """The setpoint of each sample from the model input ``u_k`` (module docstring).

    ``velocity``: ``v_{k+1} = v_k + b0 u_k dt``; ``position``:
    ``p_{k+1} = p_k + v_k dt + b0 u_k dt^2 / 2`` (``c = 0``), the reference
    due at the end of the sample; ``effort``: ``u_k``.

    Parameters
    ----------
    model : ModalModel
    dt : float
        Sample period (s).
    interface : CommandInterface
    """

    def __init__(self, model: ModalModel, dt: float, interface: CommandInterface) -> None:
        self.interface = command_interface(interface)
        check_acceleration_model(model, self.interface)
        self.b0 = float(model.b0)
        self.dt = float(dt)
        self.position = 0.0
        self.velocity = 0.0

    def reset(self, x) -> None:
        """The joint's reference restarts at state ``x`` (``[p, v, ...]``): a move from idle."""
        self.position, self.velocity = float(x[0]), float(x[1])

    def encode(self, u: float) -> float:
        """The setpoint sent for model input ``u`` (N or m/s^2), advancing the reference one sample."""
        if self.interface is CommandInterface.EFFORT:
            return float(u)
        a, dt = self.b0 * float(u), self.dt
        self.position = self.position + self.velocity * dt + 0.5 * a * dt * dt
        self.velocity = self.velocity + a * dt
        return self.velocity if self.interface is CommandInterface.VELOCITY else self.position

    def hold(self) -> float:
        """The hold: 0 N, 0 m/s (the reference stops), or the reference position (m)."""
        if self.interface is CommandInterface.EFFORT:
            return HOLD
        self.velocity = 0.0
        return 0.0 if self.interface is CommandInterface.VELOCITY else self.position


def hold_trajectory(interface: CommandInterface, joint_name: str, position: float) -> JointTrajectory:
    """One point, now (``stamp 0``, ``time_from_start 0``): the joint held at ``position`` (m), at rest, 0 N."""
    acc = interface is not CommandInterface.EFFORT
    point = TrajectoryPoint(
        time_from_start_ns=0,
        positions=(float(position),),
        velocities=(0.0,),
        accelerations=(0.0,) if acc else (),
        effort=(HOLD,) if not acc else (),
    )
    return JointTrajectory(joint_names=(joint_name,), stamp_ns=0, points=(point,))


def back_states(model: ModalModel, x, samples: int, dt: float) -> np.ndarray:
    """The states ``samples`` zero-input samples *before* ``x`` and up to it (``samples + 1`` rows).

    The pad of a delayed start: the receiver holds (zero input) meanwhile, so
    the plan made for ``x`` starts from the state the hold leads to.
    """
    back = expm(-model.A() * dt)
    out = np.empty((samples + 1, model.n_states))
    out[samples] = np.asarray(x, float)
    for j in range(samples - 1, -1, -1):
        out[j] = back @ out[j + 1]
    return out


def forward_hold(model: ModalModel, x, samples: int, dt: float) -> np.ndarray:
    """The state after ``samples`` samples of zero input from ``x`` (exact)."""
    return expm(model.A() * (samples * dt)) @ np.asarray(x, float)


class OutputStream(CommandStream):
    """The command stream with the output of :class:`OutputSettings` (module docstring).

    Parameters
    ----------
    rate_hz : float
    publish_value : callable
        ``publish_value(setpoint)`` on ``commands`` (stream mode; never called in trajectory mode).
    publish_trajectory : callable
        ``publish_trajectory(JointTrajectory)`` (trajectory mode).
    settings : OutputSettings
    model : ModalModel
        The planner's model (the reference's recursion, a trajectory's points).
    joint_name : str
    ros_ns : callable
        ``ros_ns(t)``: the node's clock (integer ns) at the stream clock's time ``t`` (s).
    on_sample : callable, optional
        ``on_sample(k, u, t_ns)`` after each sample sent (the model input ``u``; ``t_ns``: the system time
        just before it was published, 0 in trajectory mode), in the stream thread.
    on_publish : callable, optional
        ``on_publish(u)`` just before each value is published on ``commands`` (stream mode), in the stream thread.
    on_start_now : callable, optional
        ``on_start_now(segment)`` when a move from idle is installed (its ``start`` set), before its first sample.
    **kwargs
        As for :class:`CommandStream` (``on_fault`` is called after the hold trajectory went out).
    """

    def __init__(
        self,
        rate_hz: float,
        publish_value: Callable[[float], None],
        hold_when_idle: bool = True,
        *,
        settings: OutputSettings,
        model: ModalModel,
        joint_name: str,
        publish_trajectory: Callable[[JointTrajectory], None] | None = None,
        ros_ns: Callable[[float], int] | None = None,
        on_sample: Callable[[int, float, int], None] | None = None,
        on_publish: Callable[[float], None] | None = None,
        on_start_now: Callable[[Segment], None] | None = None,
        on_fault: Callable[[StreamHalt], None] | None = None,
        **kwargs: Any,
    ) -> None:
        self.settings = settings
        self.model = model
        self.joint_name = joint_name
        self.encoder = SetpointEncoder(model, 1.0 / float(rate_hz), settings.interface)
        self._publish_value = publish_value
        self._publish_trajectory = publish_trajectory
        self._ros_ns = ros_ns or (lambda t: round(t * NS))
        self._on_sample = on_sample
        self._on_publish = on_publish
        self._sent_ns = 0
        self._on_start_now = on_start_now
        self._user_on_fault = on_fault
        self._delay = settings.delay_samples(rate_hz)
        self._clock_lock = threading.Lock()
        self.sample_clock: SampleClock | None = None
        self._published_timeline: list[Segment] = []  # what the receiver was last told (trajectory mode)
        #: Hold samples appended to every segment installed (closed-loop replanning: the window in which the
        #: loop can still correct after a plan's last command); 0: none.
        self.settle_samples = 0
        self.trajectories_published = 0
        self.holds_published = 0
        #: The last trajectory published (trajectory mode), None before the first.
        self.last_trajectory: JointTrajectory | None = None
        super().__init__(rate_hz, self._emit, hold_when_idle, on_fault=self._fault, **kwargs)

    @property
    def trajectory_mode(self) -> bool:
        """Trajectories, not a command stream."""
        return self.settings.mode is OutputMode.TRAJECTORY

    @property
    def splice_margin(self) -> int:
        """No splice closer than this many samples ahead of the stream (trajectory mode: the start delay)."""
        return self._delay

    # ----------------------------------------------------------------- values
    def _emit(self, value: float) -> None:
        """The stream's publish: the encoded setpoint (stream mode); nothing in trajectory mode."""
        if self.trajectory_mode:
            return
        # idle: the hold of the interface -- after a move's last command, while idle, and on every halt (stop,
        # fault: the stream empties its timeline before it sends the hold); a zero inside a move is a command
        setpoint = self.encoder.hold() if value == HOLD and self.idle else self.encoder.encode(value)
        if self._on_publish is not None:
            self._on_publish(value)
        self._sent_ns = time.time_ns()  # just before DDS stamps it: a reading stamped with it pairs with this sample
        self._publish_value(setpoint)

    def step(self):
        out = super().step()
        if out is not None and out.value is not None and self._on_sample is not None:
            self._on_sample(out.sample, out.value, self._sent_ns)
        return out

    # --------------------------------------------------------------- timeline
    def start_now(self, segment: Segment) -> int:
        """A move from idle: the reference restarts at its first state; trajectory mode: after the start delay."""
        if not self.idle:
            raise RuntimeError("stream is not idle; splice instead")
        self._settle_tail(segment)
        self.encoder.reset(segment.states[0])  # before the stream can send the move's first sample
        if self._on_start_now is not None:
            k_next, _ = self.snapshot()
            segment.start = k_next + self._delay  # where it will start (set again by the stream)
            self._on_start_now(segment)
        if self._delay == 0:
            k0 = super().start_now(segment)
            self._installed(segment, k0)
            return k0
        pad = Segment(np.zeros(self._delay), back_states(self.model, segment.states[0], self._delay, self.dt))
        k0 = super().start_now(pad)
        if not super().splice(segment, k0 + self._delay):  # cannot fail: the pad plays for >= 2 samples
            raise RuntimeError("the padded start could not be spliced")
        self._installed(segment, segment.start)
        return segment.start

    def splice(self, segment: Segment, at: int) -> bool:
        """As :meth:`CommandStream.splice`; trajectory mode also refuses a splice closer than the margin."""
        if self.trajectory_mode:
            k_next, _ = self.snapshot()
            if at < k_next + self._delay:
                return False
        self._settle_tail(segment)
        if not super().splice(segment, at):
            return False
        self._installed(segment, None)
        return True

    def _settle_tail(self, segment: Segment) -> None:
        """Append :attr:`settle_samples` hold samples (the plan ends at rest: its last state stays)."""
        n = self.settle_samples
        if n <= 0 or getattr(segment, "settle_samples", 0):
            return
        segment.commands = np.concatenate([segment.commands, np.full(n, HOLD)])
        segment.states = np.concatenate([segment.states, np.repeat(segment.states[-1:], n, axis=0)])
        segment.settle_samples = n

    def _installed(self, segment: Segment, first: int | None) -> None:
        """Trajectory mode: publish the timeline from the move's first sample or from the sample being played."""
        if not self.trajectory_mode or self._publish_trajectory is None:
            return
        k_next, timeline = self.snapshot()
        if not timeline:
            return
        with self._clock_lock:
            if first is not None or self.sample_clock is None:
                # anchored on the stream: its sample k and the trajectory's are the same instant
                self.sample_clock = SampleClock(origin_ns=self._ros_ns(self.time_of(0)), rate_hz=1.0 / self.dt)
            clock = self.sample_clock
        frm = first if first is not None else max(k_next - 1, timeline[0].start)
        traj = timeline_trajectory(
            timeline,
            frm,
            model=self.model,
            clock=clock,
            interface=self.settings.interface,
            joint_name=self.joint_name,
            settings=self.settings.receiver,
        )
        if traj is None:
            return
        self._published_timeline = timeline
        self.last_trajectory = traj
        self._publish_trajectory(traj)
        self.trajectories_published += 1

    # ---------------------------------------------------------------- endings
    def stop(self, why: str = "stopped", timeout: float = 2.0) -> StreamHalt:
        """As :meth:`CommandStream.stop`; trajectory mode then publishes the hold trajectory."""
        k_next, _ = self.snapshot()
        halt = super().stop(why, timeout)
        self._publish_hold(k_next)
        return halt

    def _fault(self, halt: StreamHalt) -> None:
        self._publish_hold(halt.sample)
        if self._user_on_fault is not None:
            self._user_on_fault(halt)

    def _publish_hold(self, k_next: int) -> None:
        """The one-point hold trajectory where the receiver's reference is now (trajectory mode, once per ending)."""
        if not self.trajectory_mode or self._publish_trajectory is None or self.last_trajectory is None:
            return
        if self.last_trajectory.stamp_ns == 0:
            return  # the hold went out already
        x = predicted_state(self._published_timeline, max(k_next - 1, 0))
        position = float(x[0]) if x is not None else 0.0
        hold = hold_trajectory(self.settings.interface, self.joint_name, position)
        try:
            self._publish_trajectory(hold)
        except Exception:  # noqa: BLE001, S110 -- the publisher is gone (shutdown): nothing more can be sent
            return
        self.last_trajectory = hold
        self.holds_published += 1


def timeline_position(timeline: Sequence[Segment], k: int) -> float | None:
    """The position (m) the timeline predicts at sample ``k`` (None if empty)."""
    x = predicted_state(timeline, k)
    return None if x is None else float(x[0])


__all__ = [
    "MAX_START_DELAY_S",
    "OutputMode",
    "OutputSettings",
    "OutputStream",
    "SetpointEncoder",
    "back_states",
    "forward_hold",
    "hold_trajectory",
    "output_settings",
    "timeline_position",
]
