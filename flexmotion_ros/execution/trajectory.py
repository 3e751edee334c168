"""A planned zero-order-hold sequence as a joint trajectory a controller plays by its own clock.

The planner's exactness holds at every sample only if the actuator applies
``u_k`` over exactly ``[t_k, t_{k+1})``.  A ``commands`` stream cannot promise
that (the transport jitters); a trajectory played by the receiver's clock can.
This module encodes a ZOH plan as ``trajectory_msgs/JointTrajectory`` data
(ROS-free: :class:`JointTrajectory`, :class:`TrajectoryPoint`, times in
integer nanoseconds like ``rclcpp::Time``), so that a
``joint_trajectory_controller`` (JTC) with the settings of
:class:`ReceiverSettings` outputs exactly our sequence; :mod:`.jtc` is the
JTC's sampling rule, re-implemented, that the tests and the plant node use.

The encoding (``K`` commands, sample instants ``t_k`` on a
:class:`SampleClock`, ``header.stamp = t_0``, the start instant)::

    point 0       time_from_start = shift             the state before the move (p_0, v_0)
    point k+1     time_from_start = shift + t_{k+1}-t_0  p_{k+1}, v_{k+1}, accelerations a_k, effort u_k
    point K+1     time_from_start = shift + t_{K+1}-t_0  the hold: p_K, 0, 0, 0

A point carries the state due at its own time and the input of the interval
that ends there.  With ``interpolation_method: none`` the JTC outputs point
``i+1`` while its sample time is in ``[T_i, T_{i+1})``, and since Jazzy 4.17
(ros2_controllers #1306) the command it writes at a control tick ``tau`` is
the sample at ``tau + update_period``; so the points are shifted by
``shift = update_period`` and the command over ``[t_k, t_{k+1})`` is point
``k+1``: ``u_k`` for effort, and for a velocity / position joint the
reference due at ``t_{k+1}``, the end of the interval (see
:mod:`~flexmotion_ros.core.interfaces.reference`).  After the last point the
JTC holds it: the explicit hold point makes that the hold, never the last
command.  With ``interpolation_method: splines`` the points carry no
accelerations: the JTC's cubic through ``(p, v)`` at both ends reproduces the
exact piecewise-quadratic position (a cubic Hermite interpolant of a
quadratic is the quadratic), so no shift is needed and the reference is exact
at any instant; effort cannot use splines (it is interpolated linearly).

A preemption or stop (:func:`timeline_trajectory` from the sample being
played): the JTC does *not* keep the old trajectory up to the new one's
start -- it forgets it at its next update and, before the new first point,
outputs the state it had then (``interpolation_method: none``) or a spline
from it.  So a replacement must not start at the splice: it starts at the
sample being played when it is published and repeats the old commands up to
the splice.  On the same sample clock its points fall on exactly the same
instants (integer nanoseconds) as the old ones, so whichever tick installs it
before the splice, the output is unchanged until the splice and the new plan
from there.

JTC settings for an exact zero-order hold (ros2_controllers >= 4.22.0 on
Jazzy; an effort joint needs #1200's feed-forward effort):
``interpolation_method: none`` (``splines`` for velocity / position only),
``interpolate_from_desired_state: true`` (before a trajectory's first point it
outputs the last command, not the measured state); an effort-only joint goes
through the JTC's PID adapter (``ff_velocity_scale v + effort + PID``), so
``gains.<joint>: {p: 0.0, i: 0.0, d: 0.0, ff_velocity_scale: 0.0}``: the
command is the effort field alone; a velocity-only joint goes through it too
(``ff_velocity_scale v + PID``), so ``{p: 0.0, i: 0.0, d: 0.0,
ff_velocity_scale: 1.0}``: the command is the velocity field (a joint that
claims ``[position, velocity]`` gets both fields directly, no adapter);
speed scaling 1, tolerances
left at 0 (no abort), the sender's and the controller's clocks the same (a
stamp in the future is honoured to the nanosecond), and the controller's
``update_rate`` an integer multiple of the plan's rate (its ticks then fall on
every sample instant, up to a constant phase that only delays the whole move).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum

import numpy as np

from ..core.errors import ConfigError, GoalError
from ..core.interfaces.command import CommandInterface, command_interface
from ..core.interfaces.reference import JointReference, reference_for
from ..core.model.modal_model import ModalModel
from .timeline import HOLD, Segment, predicted_state

#: Nanoseconds per second (``rclcpp::Time`` and ``builtin_interfaces`` count integer nanoseconds).
NS = 1_000_000_000


class Interpolation(Enum):
    """The JTC's ``interpolation_method`` (values: the parameter's strings)."""

    NONE = "none"
    SPLINES = "splines"


@dataclass(frozen=True, kw_only=True)
class ReceiverSettings:
    """How the receiver samples a trajectory (a JTC's settings, or the plant node's).

    Attributes
    ----------
    interpolation : Interpolation
        ``none`` (required for effort) or ``splines``.
    lookahead_ns : int
        The receiver writes, at a tick ``tau``, the sample at ``tau + lookahead_ns``
        (ns).  Jazzy's JTC since 4.17: its ``update_period_``, ``int(1e9 / update_rate)``
        (:meth:`jazzy`); Humble's JTC and the plant node: 0.
    """

    interpolation: Interpolation = Interpolation.NONE
    lookahead_ns: int = 0

    def __post_init__(self) -> None:
        object.__setattr__(self, "interpolation", Interpolation(self.interpolation))
        if int(self.lookahead_ns) != self.lookahead_ns or self.lookahead_ns < 0:
            raise ConfigError("trajectory.lookahead_ns", f"must be an integer >= 0 ns, got {self.lookahead_ns!r}")
        object.__setattr__(self, "lookahead_ns", int(self.lookahead_ns))

    @classmethod
    def jazzy(cls, update_rate_hz: float, interpolation: Interpolation | str = Interpolation.NONE) -> ReceiverSettings:
        """A Jazzy JTC (>= 4.17) running at ``update_rate_hz`` (Hz): look-ahead = its ``update_period_``.

        ``update_period_ = rclcpp::Duration(0, uint32(1e9 / update_rate))``: truncated to whole ns.
        """
        if not (math.isfinite(update_rate_hz) and update_rate_hz >= 1.0):
            raise ConfigError("update_rate", f"must be finite and >= 1 Hz, got {update_rate_hz}")
        return cls(interpolation=Interpolation(interpolation), lookahead_ns=int(1e9 / float(update_rate_hz)))

    @property
    def shift_ns(self) -> int:
        """How far (ns) the encoding shifts the points: the look-ahead for ``none``, 0 for splines."""
        return self.lookahead_ns if self.interpolation is Interpolation.NONE else 0


@dataclass(frozen=True, kw_only=True)
class TrajectoryPoint:
    """``trajectory_msgs/JointTrajectoryPoint``: one value per joint in each non-empty field.

    Attributes
    ----------
    time_from_start_ns : int
        ``time_from_start`` (ns).
    positions, velocities, accelerations, effort : tuple of float
        m, m/s, m/s^2, N (rad and N m for a revolute joint); empty: not given.
    """

    time_from_start_ns: int
    positions: tuple[float, ...] = ()
    velocities: tuple[float, ...] = ()
    accelerations: tuple[float, ...] = ()
    effort: tuple[float, ...] = ()

    def field(self, interface: CommandInterface | str) -> tuple[float, ...]:
        """The field a joint with this command interface is commanded from."""
        iface = command_interface(interface)
        return {
            CommandInterface.EFFORT: self.effort,
            CommandInterface.VELOCITY: self.velocities,
            CommandInterface.POSITION: self.positions,
        }[iface]


@dataclass(frozen=True, kw_only=True)
class JointTrajectory:
    """``trajectory_msgs/JointTrajectory``.

    Attributes
    ----------
    joint_names : tuple of str
    stamp_ns : int
        ``header.stamp`` (ns on the sender's clock); 0: the receiver starts it at its first sample.
    points : tuple of TrajectoryPoint
        Strictly increasing ``time_from_start``.
    """

    joint_names: tuple[str, ...]
    stamp_ns: int
    points: tuple[TrajectoryPoint, ...]

    def point_times_ns(self) -> np.ndarray:
        """Absolute time (ns) of every point: ``stamp + time_from_start``."""
        return np.array([self.stamp_ns + p.time_from_start_ns for p in self.points], dtype=np.int64)


@dataclass(frozen=True, kw_only=True)
class SampleClock:
    """The instants of the global sample indices: sample ``k`` starts at ``origin_ns + round(k 1e9 / rate_hz)``.

    Every trajectory of one timeline is encoded on one clock, so that a
    replacement's points fall on exactly the old ones' instants.

    Attributes
    ----------
    origin_ns : int
        Instant (ns, the node's clock) of global sample 0.
    rate_hz : float
        Sample rate (Hz).
    """

    origin_ns: int
    rate_hz: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.rate_hz) and self.rate_hz > 0.0):
            raise ConfigError("rate_hz", f"must be finite and > 0 Hz, got {self.rate_hz}")
        object.__setattr__(self, "origin_ns", int(self.origin_ns))
        object.__setattr__(self, "rate_hz", float(self.rate_hz))

    @property
    def dt(self) -> float:
        """Sample period (s)."""
        return 1.0 / self.rate_hz

    def at(self, k: int) -> int:
        """Start instant (ns) of global sample ``k``."""
        return self.origin_ns + round(k * NS / self.rate_hz)

    def index(self, t_ns: int) -> int:
        """The sample whose interval ``[at(k), at(k+1))`` holds ``t_ns``."""
        k = math.floor((t_ns - self.origin_ns) * self.rate_hz / NS)
        while self.at(k) > t_ns:  # the rounding of at() may put the boundary 1 ns either way
            k -= 1
        while self.at(k + 1) <= t_ns:
            k += 1
        return k


def encode(
    reference: JointReference,
    *,
    interface: CommandInterface | str,
    joint_name: str,
    clock: SampleClock,
    first_sample: int = 0,
    settings: ReceiverSettings | None = None,
    hold_effort: float = HOLD,
) -> JointTrajectory:
    """A ZOH plan as the trajectory a receiver with ``settings`` plays exactly (module docstring).

    Parameters
    ----------
    reference : JointReference
        The plan's commands and the joint's exact samples (``reference.dt`` must be ``clock.dt``).
    interface : CommandInterface or str
        ``effort``: points carry effort (with positions and velocities: the JTC
        requires positions, and its PID adapter reads velocities);
        ``velocity`` / ``position``: positions, velocities and (``none``) accelerations.
    joint_name : str
    clock : SampleClock
        The timeline's sample instants.
    first_sample : int
        Global index of ``reference``'s first command: ``header.stamp = clock.at(first_sample)``.
    settings : ReceiverSettings, optional
        Default: ``none``, no look-ahead.
    hold_effort : float
        Effort of the final hold point (N).

    Returns
    -------
    JointTrajectory
        ``K + 2`` points (the state before, one per command, the hold).

    Raises
    ------
    ConfigError
        Effort with ``splines`` (the JTC interpolates effort linearly: not a ZOH).
    GoalError
        ``reference.dt`` is not the clock's period.
    """
    iface = command_interface(interface)
    settings = settings or ReceiverSettings()
    if iface is CommandInterface.EFFORT and settings.interpolation is Interpolation.SPLINES:
        raise ConfigError(
            "interpolation_method",
            "must be none for command_interface effort: splines interpolate effort linearly, not a zero-order hold",
        )
    if not math.isclose(reference.dt, clock.dt, rel_tol=1e-12):
        raise GoalError("rate_hz", f"the plan's period {reference.dt} s is not the clock's {clock.dt} s")
    K = reference.samples
    stamp = clock.at(first_sample)
    shift = settings.shift_ns
    with_acc = settings.interpolation is Interpolation.NONE and iface is not CommandInterface.EFFORT
    with_effort = iface is CommandInterface.EFFORT
    p, v, a, u = reference.positions, reference.velocities, reference.accelerations, reference.commands

    def point(j: int, pos: float, vel: float, acc: float, eff: float) -> TrajectoryPoint:
        return TrajectoryPoint(
            time_from_start_ns=shift + clock.at(first_sample + j) - stamp,
            positions=(float(pos),),
            velocities=(float(vel),),
            accelerations=(float(acc),) if with_acc else (),
            effort=(float(eff),) if with_effort else (),
        )

    pts = [point(0, p[0], v[0], 0.0, hold_effort)]
    pts += [point(k + 1, p[k + 1], v[k + 1], a[k], u[k]) for k in range(K)]
    # the hold, what the receiver keeps after the end: at rest where the plan ends (v_K is 0 to rounding)
    pts.append(point(K + 1, p[K], 0.0, 0.0, hold_effort))
    return JointTrajectory(joint_names=(joint_name,), stamp_ns=stamp, points=tuple(pts))


def timeline_commands(timeline: Sequence[Segment], k_from: int, k_to: int) -> np.ndarray:
    """The command the timeline sends at each global sample ``k_from .. k_to - 1`` (HOLD where none plays).

    A later segment takes over from its start (a splice), as in
    :func:`~.timeline.predicted_state`.
    """
    out = np.full(max(k_to - k_from, 0), HOLD, dtype=float)
    for i, seg in enumerate(timeline):
        nxt = timeline[i + 1].start if i + 1 < len(timeline) else None
        lo = max(seg.start, k_from)
        hi = min(seg.end, k_to) if nxt is None else min(seg.end, nxt, k_to)
        if hi > lo:
            out[lo - k_from : hi - k_from] = seg.commands[lo - seg.start : hi - seg.start]
    return out


def timeline_trajectory(
    timeline: Sequence[Segment],
    from_sample: int,
    *,
    model: ModalModel,
    clock: SampleClock,
    interface: CommandInterface | str,
    joint_name: str,
    settings: ReceiverSettings | None = None,
) -> JointTrajectory | None:
    """The trajectory of the timeline from ``from_sample`` to its end (and the hold): publish this.

    For a new move from idle ``from_sample`` is its first sample.  For a
    preemption or stop spliced at ``k_s``, publish the new timeline from the
    sample being played *now* (``from_sample <= k_s``; at most the next one
    the receiver can still see): its points repeat the old commands up to
    ``k_s`` on the same instants, so the receiver, which replaces its whole
    trajectory at its next tick, plays the same commands until ``k_s`` and
    the new plan from there, provided that tick comes before ``clock.at(k_s)``.

    Returns
    -------
    JointTrajectory or None
        None if the timeline is empty (idle: nothing to publish).
    """
    if not timeline:
        return None
    end = timeline[-1].end
    x0 = predicted_state(timeline, from_sample)
    commands = timeline_commands(timeline, from_sample, end)
    ref = reference_for(model, commands, clock.dt, x0, interface)
    return encode(
        ref, interface=interface, joint_name=joint_name, clock=clock, first_sample=from_sample, settings=settings
    )


__all__ = [
    "NS",
    "Interpolation",
    "JointTrajectory",
    "ReceiverSettings",
    "SampleClock",
    "TrajectoryPoint",
    "encode",
    "timeline_commands",
    "timeline_trajectory",
]
