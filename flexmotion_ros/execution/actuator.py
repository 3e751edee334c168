"""The simulated plant's actuator: setpoints of any command interface, a servo, disturbances, trajectories.

ROS-free; the plant node (:mod:`flexmotion_ros.nodes.plant_actuator`) drives it.

:class:`Actuator` holds the machine's state and the setpoint being tracked,
on an integer-nanosecond clock, and advances *exactly*: piecewise-constant
inputs integrated by matrix exponentials (:mod:`flexmotion_ros.core.interfaces.servo`
for a velocity / position joint: ideal tracking or a first-order servo of
``plant.servo_bandwidth`` rad/s; the force itself for an effort joint), cut at
every instant where something changes -- the setpoint's due time (the servo
arrives there, then holds), the disturbance (:class:`Disturbance`: a force
impulse or step on the rigid body's input at ``time_s`` after the first
command).  The disturbance and the servo from the plant's parameters are
:mod:`.actuator_settings`.

:class:`TrajectoryPlayback` is the receiving end of ``output: trajectory``:
it plays joint trajectories with the joint trajectory controller's rule
(:mod:`.jtc`, ``interpolation_method: none`` and no look-ahead: point
``i+1`` over ``[T_i, T_{i+1})``, before ``T_0`` the point it had, after the
last point the last point), integrating each constant piece exactly, so the
machine gets the planned zero-order hold whatever the ticks of the caller.
A new trajectory replaces the current one from the instant it is installed
(its receipt, in real time), as the controller's does at its next tick.
:meth:`TrajectoryPlayback.receive_eager` is the lockstep form: a trajectory
is played at once to its end; one that starts earlier than the plant's time
(a replacement) rewinds the plant to its first point and plays from there.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from ..core.errors import ConfigError
from ..core.interfaces.command import CommandInterface, command_interface
from ..core.interfaces.servo import Servo, ServoState, servo_advance, servo_setpoint, servo_start
from ..core.model.modal_model import ModalModel

# The settings, exported from here too (the plant node imports them so).
from .actuator_settings import Disturbance, DisturbanceKind, disturbance_settings, servo_settings
from .jtc import held_pieces, started
from .trajectory import NS, JointTrajectory, ReceiverSettings, TrajectoryPoint


@dataclass(frozen=True, kw_only=True)
class ActuatorState:
    """Everything an :class:`Actuator` is at one instant (for a rewind)."""

    t_ns: int
    servo: ServoState
    due_ns: int | None
    origin_ns: int | None
    kicked: bool
    braking: bool = False


class Actuator:
    """The machine and its actuated joint, advanced exactly (module docstring).

    Parameters
    ----------
    model : ModalModel
        The simulated (true) machine.
    x0 : array_like
        Initial state ``[p, v, q_1, q_1', ...]``.
    interface : CommandInterface or str
    servo : Servo, optional
        Velocity / position joints only (default ideal).
    disturbance : Disturbance, optional
    t_ns : int
        The clock's initial time (ns).
    """

    def __init__(
        self,
        model: ModalModel,
        x0,
        interface: CommandInterface | str,
        servo: Servo | None = None,
        disturbance: Disturbance | None = None,
        t_ns: int = 0,
    ) -> None:
        self.model = model
        self.interface = command_interface(interface)
        self.servo = servo or Servo()
        self.disturbance = disturbance or Disturbance()
        self._B = model.B()
        self._st = ActuatorState(
            t_ns=int(t_ns),
            servo=servo_start(model, x0, self.interface, self.servo),
            due_ns=None,
            origin_ns=None,
            kicked=False,
        )

    # ------------------------------------------------------------------ state
    @property
    def t_ns(self) -> int:
        """The actuator's time (ns)."""
        return self._st.t_ns

    @property
    def x(self) -> np.ndarray:
        """Machine state ``[p, v, q_1, q_1', ...]``."""
        return self._st.servo.x

    @property
    def setpoint(self) -> float | None:
        """The setpoint tracked (the force for effort); None before the first."""
        return self._st.servo.setpoint

    @property
    def applied(self) -> float:
        """The input applied now: the force (N, with a step disturbance) or the servo's acceleration (m/s^2)."""
        return self._st.servo.acceleration + self._step_force(self._st.t_ns)

    def save(self) -> ActuatorState:
        """Everything, for :meth:`restore`."""
        return self._st

    def restore(self, state: ActuatorState) -> None:
        """Back to a saved instant."""
        self._st = state

    # ---------------------------------------------------------------- inputs
    def set(self, value: float, due_ns: int | None = None) -> None:
        """A new setpoint from now, due at ``due_ns`` (velocity / position: the servo arrives then, then holds).

        Effort: the force, held until the next one (``due_ns`` ignored).
        The first non-zero force (the first move, not an idle hold) starts the disturbance's clock.
        """
        st = self._st
        origin = st.origin_ns
        if origin is None and (self.interface is not CommandInterface.EFFORT or value != 0.0):
            origin = st.t_ns  # the disturbance's clock starts with the first move (not with idle holds)
        if self.interface is CommandInterface.EFFORT:
            h, due_ns = None, None  # a force is held until the next one: no arrival
        elif due_ns is None or due_ns <= st.t_ns:
            h = None
        else:
            h = (due_ns - st.t_ns) / NS
        if self.interface is not CommandInterface.EFFORT and h is None:
            # no time left to get there: hold the reference where it is (a servo at its setpoint)
            servo = replace(st.servo, acceleration=0.0, setpoint=float(value))
            due_ns = None
        else:
            servo = servo_setpoint(st.servo, float(value), h if h is not None else 1.0, self.interface)
        self._st = replace(st, servo=servo, due_ns=due_ns, origin_ns=origin, braking=False)

    def brake(self, h_ns: int) -> None:
        """A velocity / position joint told to hold: its reference comes to rest in ``h_ns`` (ns), then stays.

        A constant deceleration from the reference's velocity (a servo cannot stop
        at once); it ends at rest, past the reference position by half the
        velocity times ``h``.  Effort: nothing (the force is the hold's).
        """
        st = self._st
        if self.interface is CommandInterface.EFFORT:
            return
        h = max(int(h_ns), 1)
        rv = st.servo.reference_velocity
        servo = replace(st.servo, acceleration=-rv / (h / NS), setpoint=0.0)
        self._st = replace(st, servo=servo, due_ns=st.t_ns + h, braking=True)

    # --------------------------------------------------------------- advance
    def _t_dist(self) -> int | None:
        st = self._st
        if not self.disturbance.active or st.origin_ns is None:
            return None
        return st.origin_ns + round(self.disturbance.time_s * NS)

    def _step_force(self, t_ns: int) -> float:
        td = self._t_dist()
        if td is None or self.disturbance.kind is not DisturbanceKind.STEP or t_ns < td:
            return 0.0
        return self.disturbance.value

    def advance_to(self, t_ns: int) -> None:
        """Integrate exactly up to ``t_ns`` (ns; earlier: nothing)."""
        t_ns = int(t_ns)
        while self._st.t_ns < t_ns:
            st = self._st
            td = self._t_dist()
            cuts = [t_ns]
            if st.due_ns is not None and st.due_ns > st.t_ns:
                cuts.append(st.due_ns)
            if td is not None and td > st.t_ns:
                cuts.append(td)
            nxt = min(cuts)
            servo = st.servo
            force = self._step_force(st.t_ns)
            if force:
                servo = replace(servo, acceleration=servo.acceleration + force)
            arrive = st.due_ns is not None and nxt == st.due_ns
            h = (nxt - st.t_ns) / NS
            servo = servo_advance(self.model, servo, h, self.interface, self.servo, arrive=arrive and not st.braking)
            servo = replace(servo, acceleration=st.servo.acceleration)
            due = st.due_ns
            if arrive:  # the servo is at its setpoint (or at rest, braking): it holds there until the next one
                servo = replace(servo, acceleration=0.0)
                if st.braking:
                    servo = replace(servo, reference_velocity=0.0)
                due = None
            kicked = st.kicked
            if td is not None and nxt == td and not kicked and self.disturbance.kind is DisturbanceKind.IMPULSE:
                servo = replace(servo, x=servo.x + self._B * self.disturbance.value)
                kicked = True
            self._st = replace(st, t_ns=nxt, servo=servo, due_ns=due, kicked=kicked, braking=st.braking and not arrive)


def hold_point(position: float) -> TrajectoryPoint:
    """The point a receiver holds before any trajectory: at ``position`` (m), at rest, 0 N."""
    return TrajectoryPoint(
        time_from_start_ns=0, positions=(float(position),), velocities=(0.0,), accelerations=(0.0,), effort=(0.0,)
    )


@dataclass(frozen=True, kw_only=True)
class _PlaybackState:
    actuator: ActuatorState
    current: JointTrajectory | None
    before: TrajectoryPoint
    last: TrajectoryPoint


class TrajectoryPlayback:
    """Plays joint trajectories into an :class:`Actuator` by the JTC's rule, exactly (module docstring).

    Parameters
    ----------
    actuator : Actuator
    joint_name : str
        The joint a trajectory must name (alone).
    history : int
        Sample instants kept for a rewind (:meth:`receive_eager`).
    period_ns : int
        A velocity / position joint told to hold (after a trajectory's last point) comes to rest in this long (ns).
    """

    def __init__(self, actuator: Actuator, joint_name: str, history: int = 50_000, period_ns: int = 10_000_000) -> None:
        self.actuator = actuator
        self.joint_name = joint_name
        self.settings = ReceiverSettings()  # interpolation none, no look-ahead: point i+1 over [T_i, T_{i+1})
        self._current: JointTrajectory | None = None
        self._before = hold_point(float(actuator.x[0]))
        self._last = self._before
        self._history: deque[_PlaybackState] = deque(maxlen=max(1, int(history)))
        self._held: TrajectoryPoint | None = None  # the last point a servo joint was told to hold
        #: How long (ns) a servo joint takes to come to rest on a hold (one sample of the sender).
        self.period_ns = int(period_ns)
        self.received = 0
        self.rewinds = 0

    def check(self, trajectory: JointTrajectory) -> None:
        """Refuse what this receiver cannot play (one joint, ours; the field of our interface in every point)."""
        if tuple(trajectory.joint_names) != (self.joint_name,):
            raise ConfigError(
                "joint_trajectory.joint_names", f"must be [{self.joint_name!r}], got {list(trajectory.joint_names)}"
            )
        iface = self.actuator.interface
        for i, p in enumerate(trajectory.points):
            if len(p.field(iface)) != 1:
                raise ConfigError(
                    f"joint_trajectory.points[{i}]",
                    f"needs one {iface.value} value for command_interface {iface.value}",
                )
        times = [p.time_from_start_ns for p in trajectory.points]
        if any(b <= a for a, b in zip(times, times[1:])):
            raise ConfigError("joint_trajectory.points", "time_from_start must increase strictly")

    def install(self, trajectory: JointTrajectory, t_ns: int) -> None:
        """Replace the current trajectory from ``t_ns`` (ns; the actuator is played there first)."""
        self.play_to(t_ns)
        self._current = started(trajectory, t_ns) if trajectory.points else None
        self._before = self._last
        self.received += 1

    def play_to(self, t_ns: int, on_sample: Callable[[int], None] | None = None) -> None:
        """Integrate the current trajectory (or the hold) exactly up to ``t_ns``; ``on_sample(t)`` at each sample instant."""
        act = self.actuator
        if t_ns <= act.t_ns:
            return
        if self._current is None:
            act.advance_to(t_ns)
            return
        iface = act.interface
        for piece in held_pieces(self._current, act.t_ns, int(t_ns), self.settings, self._before):
            value = piece.point.field(iface)[0]
            if piece.due_ns is None and iface is not CommandInterface.EFFORT:
                if piece.point is not self._held:  # after the last point: the servo comes to rest and holds
                    act.brake(self.period_ns)
                    self._held = piece.point
            elif piece.begins or value != act.setpoint or piece.point is not self._last:
                act.set(value, piece.due_ns)
            self._last = piece.point
            act.advance_to(piece.end_ns)
            if piece.due_ns is not None and piece.end_ns == piece.due_ns:
                self._history.append(self._save())
                if on_sample is not None:
                    on_sample(piece.end_ns)

    def end_ns(self) -> int | None:
        """When the current trajectory's last point is reached (None: none)."""
        if self._current is None or not self._current.points:
            return None
        return int(self._current.point_times_ns()[-1])

    def receive_eager(self, trajectory: JointTrajectory, now_ns: int, on_sample: Callable[[int], None] | None = None):
        """Lockstep: install at the trajectory's first point (rewinding if the plant is past it) and play it to its end.

        ``now_ns`` resolves a stamp of 0 ("start now").  Returns the instant (ns) played from.
        """
        trajectory = started(trajectory, now_ns)
        t0 = int(trajectory.point_times_ns()[0]) if trajectory.points else int(now_ns)
        if t0 < self.actuator.t_ns:
            self._rewind(t0)
        self.install(trajectory, t0)
        end = self.end_ns()
        if end is not None:  # to the last point, and one period of its hold (a servo joint comes to rest)
            self.play_to(end + self.period_ns, on_sample)
        return t0

    def _save(self) -> _PlaybackState:
        return _PlaybackState(
            actuator=self.actuator.save(), current=self._current, before=self._before, last=self._last
        )

    def _rewind(self, t_ns: int) -> None:
        """Back to the latest saved sample instant at or before ``t_ns``, then forward to it with what played then."""
        while self._history and self._history[-1].actuator.t_ns > t_ns:
            self._history.pop()
        if not self._history:
            raise ConfigError(
                "joint_trajectory.header.stamp", "starts before anything this plant still remembers: cannot rewind"
            )
        snap = self._history[-1]
        self.actuator.restore(snap.actuator)
        self._current, self._before, self._last = snap.current, snap.before, snap.last
        self.rewinds += 1
        self.play_to(t_ns)


__all__ = [
    "Actuator",
    "ActuatorState",
    "Disturbance",
    "DisturbanceKind",
    "TrajectoryPlayback",
    "disturbance_settings",
    "hold_point",
    "servo_settings",
]
