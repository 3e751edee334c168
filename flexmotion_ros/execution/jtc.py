"""The ``joint_trajectory_controller``'s sampling rule, re-implemented (ROS-free, integer nanoseconds).

Source: ros-controls/ros2_controllers, branch ``jazzy`` (read 2026-12 at
``ed360c9``): ``joint_trajectory_controller/src/trajectory.cpp``
(``Trajectory::sample``, ``interpolate_between_points``) and
``src/joint_trajectory_controller.cpp`` (``update``); the behaviour below has
been there since 4.17.0 (#1306 "Sample at t + dT", #1395 "sum periods"); the
effort field reaches an effort command interface since 4.22.0 (#1200,
feed-forward effort).  Humble's JTC (2.x) samples at ``t`` (no look-ahead)
and has no feed-forward effort.  No ``ros2_controllers`` is installed here:
this is a re-implementation from the source, not a test against the binary.

:func:`sample` -- ``Trajectory::sample(t)``, with ``T_i = stamp + time_from_start_i``:

* ``stamp == 0`` means "start now": the first sample's time becomes the stamp
  (:func:`started`);
* ``t`` before the point recorded when the trajectory was installed: nothing;
* ``t < T_0``: ``none`` outputs that recorded point (the state when the
  trajectory was installed: the measured state, or the last command with
  ``interpolate_from_desired_state: true``); ``splines`` interpolates from it
  to point 0;
* ``T_i <= t < T_{i+1}``: ``none`` outputs point ``i+1`` as it is (no field
  is computed); ``splines`` interpolates: linear with positions only, cubic
  with positions and velocities, quintic with accelerations too; effort
  linearly;
* ``t >= T_last``: the last point, empty velocity / acceleration / effort
  filled with zeros.

``update`` at a tick ``tau``: a trajectory received since the last tick
replaces the current one *entirely* (the JTC documentation: "the current
implementation just forgets the old trajectory"); on its first tick it records
the point before it (above) and its time runs from ``tau`` (summed periods);
the command written for the next cycle is ``sample(tau + update_period)``
(``command_next_``), for position, velocity and acceleration interfaces and,
for an effort interface (always through its PID adapter), as
``ff_velocity_scale * v + effort + PID(errors)``.  With zero gains and
``ff_velocity_scale: 0`` that is the effort field alone.
:class:`TrajectoryPlayer` is that loop; :func:`held_pieces` gives, for a
plant that integrates exactly between its own ticks, the intervals on which
the command is constant.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .trajectory import NS, Interpolation, JointTrajectory, ReceiverSettings, TrajectoryPoint


def started(trajectory: JointTrajectory, first_sample_ns: int) -> JointTrajectory:
    """The trajectory with ``stamp == 0`` ("start now") resolved to the receiver's first sample time (ns)."""
    return trajectory if trajectory.stamp_ns != 0 else replace(trajectory, stamp_ns=int(first_sample_ns))


def sample(
    trajectory: JointTrajectory,
    t_ns: int,
    interpolation: Interpolation | str,
    before: TrajectoryPoint | None = None,
    before_ns: int | None = None,
) -> TrajectoryPoint | None:
    """``Trajectory::sample``: the point the JTC's trajectory gives at ``t_ns`` (module docstring).

    Parameters
    ----------
    trajectory : JointTrajectory
        With its stamp resolved (:func:`started`).
    t_ns : int
        Sample time (ns, the receiver's clock).
    interpolation : Interpolation or str
    before : TrajectoryPoint, optional
        The point recorded when the trajectory was installed (needed before ``T_0``).
    before_ns : int, optional
        When it was recorded (ns).

    Returns
    -------
    TrajectoryPoint or None
        None where the JTC's ``sample`` returns false (no points, before ``before_ns``,
        before ``T_0`` with nothing recorded).
    """
    method = Interpolation(interpolation)
    pts = trajectory.points
    if not pts or (before_ns is not None and t_ns < before_ns):
        return None
    times = trajectory.point_times_ns()
    if t_ns < times[0]:
        if before is None:
            return None
        if method is Interpolation.NONE:
            return before
        t_a = before_ns if before_ns is not None else int(times[0])
        return _interpolate(t_a, before, int(times[0]), pts[0], t_ns)
    i = int(np.searchsorted(times, t_ns, side="right")) - 1  # T_i <= t < T_{i+1}
    if i < len(pts) - 1:
        if method is Interpolation.NONE:
            return pts[i + 1]
        out = _interpolate(int(times[i]), pts[i], int(times[i + 1]), pts[i + 1], t_ns)
        return replace(out, time_from_start_ns=pts[i + 1].time_from_start_ns)
    last = pts[-1]
    dim = len(last.positions)
    return replace(
        last,
        velocities=last.velocities or (0.0,) * dim,
        accelerations=last.accelerations or (0.0,) * dim,
        effort=last.effort or (0.0,) * dim,
    )


def _interpolate(t_a: int, a: TrajectoryPoint, t_b: int, b: TrajectoryPoint, t: int) -> TrajectoryPoint:
    """``interpolate_between_points``: linear / cubic / quintic in position, linear in effort."""
    so_far = (t - t_a) / NS
    between = (t_b - t_a) / NS
    dim = len(a.positions)
    has_vel = bool(a.velocities) and bool(b.velocities)
    has_acc = bool(a.accelerations) and bool(b.accelerations)
    has_eff = bool(a.effort) and bool(b.effort)
    if so_far < 0.0:
        so_far, has_vel, has_acc = 0.0, False, False
    if so_far > between:
        so_far, has_vel, has_acc = between, False, False
    t1, t2, t3, t4, t5 = (so_far**n for n in range(1, 6))
    T1, T2, T3, T4, T5 = (between**n for n in range(1, 6))
    pos, vel, acc = [0.0] * dim, [0.0] * dim, [0.0] * dim
    eff = [0.0] * dim
    for j in range(dim):
        if has_eff:
            slope = (b.effort[j] - a.effort[j]) / between if between != 0.0 else 0.0
            eff[j] = a.effort[j] + t1 * slope
        p0, p1 = a.positions[j], b.positions[j]
        if not has_vel and not has_acc:
            c1 = (p1 - p0) / between if between != 0.0 else 0.0
            pos[j], vel[j] = p0 + t1 * c1, c1
        elif has_vel and not has_acc:
            v0, v1 = a.velocities[j], b.velocities[j]
            c2 = c3 = 0.0
            if between != 0.0:
                c2 = (-3.0 * p0 + 3.0 * p1 - 2.0 * v0 * T1 - v1 * T1) / T2
                c3 = (2.0 * p0 - 2.0 * p1 + v0 * T1 + v1 * T1) / T3
            pos[j] = p0 + t1 * v0 + t2 * c2 + t3 * c3
            vel[j] = v0 + t1 * 2.0 * c2 + t2 * 3.0 * c3
            acc[j] = 2.0 * c2 + t1 * 6.0 * c3
        elif has_vel and has_acc:
            v0, v1, a0, a1 = a.velocities[j], b.velocities[j], a.accelerations[j], b.accelerations[j]
            c3 = c4 = c5 = 0.0
            if between != 0.0:
                c3 = (-20.0 * p0 + 20.0 * p1 - 3.0 * a0 * T2 + a1 * T2 - 12.0 * v0 * T1 - 8.0 * v1 * T1) / (2.0 * T3)
                c4 = (30.0 * p0 - 30.0 * p1 + 3.0 * a0 * T2 - 2.0 * a1 * T2 + 16.0 * v0 * T1 + 14.0 * v1 * T1) / (
                    2.0 * T4
                )
                c5 = (-12.0 * p0 + 12.0 * p1 - a0 * T2 + a1 * T2 - 6.0 * v0 * T1 - 6.0 * v1 * T1) / (2.0 * T5)
            c2 = 0.5 * a0
            pos[j] = p0 + t1 * v0 + t2 * c2 + t3 * c3 + t4 * c4 + t5 * c5
            vel[j] = v0 + t1 * 2.0 * c2 + t2 * 3.0 * c3 + t3 * 4.0 * c4 + t4 * 5.0 * c5
            acc[j] = 2.0 * c2 + t1 * 6.0 * c3 + t2 * 12.0 * c4 + t3 * 20.0 * c5
        # (accelerations without velocities: the JTC computes nothing for positions; not produced here)
    return TrajectoryPoint(
        time_from_start_ns=b.time_from_start_ns,
        positions=tuple(pos),
        velocities=tuple(vel),
        accelerations=tuple(acc),
        effort=tuple(eff),
    )


@dataclass(frozen=True, kw_only=True)
class HeldPiece:
    """An interval on which the receiver's command is one point (``none``).

    Attributes
    ----------
    start_ns, end_ns : int
        The part of the query window it covers (ns).
    due_ns : int or None
        When the point's state is due: the end of the whole piece (ns); None
        after the last point (held for ever).
    point : TrajectoryPoint
    begins : bool
        ``start_ns`` is where the point starts being output (a new setpoint),
        not just the start of the query window.
    """

    start_ns: int
    end_ns: int
    due_ns: int | None
    point: TrajectoryPoint
    begins: bool = False


def held_pieces(
    trajectory: JointTrajectory,
    t_from_ns: int,
    t_to_ns: int,
    settings: ReceiverSettings,
    before: TrajectoryPoint | None = None,
) -> list[HeldPiece]:
    """The command ``tau -> sample(tau + lookahead)`` over ``[t_from, t_to)`` as constant pieces (``none``).

    A plant that integrates each piece exactly applies the sequence exactly,
    whatever its own ticks: the pieces change at ``T_i - lookahead``, the
    sample instants of the encoding, not at the plant's ticks.

    Raises
    ------
    ValueError
        With ``splines`` (the command is not piecewise constant).
    """
    if settings.interpolation is not Interpolation.NONE:
        raise ValueError("held_pieces needs interpolation_method none")
    times = trajectory.point_times_ns() - settings.lookahead_ns
    boundaries = {int(t) for t in times}
    cuts = [int(t) for t in times if t_from_ns < t < t_to_ns]
    bounds = [t_from_ns, *cuts, t_to_ns]
    out = []
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        if hi <= lo:
            continue
        pt = sample(trajectory, lo + settings.lookahead_ns, Interpolation.NONE, before)
        if pt is None:
            raise ValueError("nothing to play before the trajectory's first point: give the point before it")
        later = times[times > lo]
        due = int(later[0]) if later.size else None
        out.append(HeldPiece(start_ns=lo, end_ns=hi, due_ns=due, point=pt, begins=lo in boundaries))
    return out


class TrajectoryPlayer:
    """The JTC's update loop for one joint: receive trajectories, write a command at each tick.

    Behaves like the JTC with ``interpolate_from_desired_state: true`` (the
    point before a new trajectory is the last command written), so a
    receiver that starts holding ``initial`` never outputs a measured value.

    Parameters
    ----------
    settings : ReceiverSettings
    initial : TrajectoryPoint
        The hold before any trajectory (e.g. the current position, zero velocity and effort).
    """

    def __init__(self, settings: ReceiverSettings, initial: TrajectoryPoint) -> None:
        self.settings = settings
        self._pending: JointTrajectory | None = None
        self._current: JointTrajectory | None = None
        self._before = initial
        self._before_ns: int | None = None
        self.last = initial
        self.last_ns: int | None = None

    def receive(self, trajectory: JointTrajectory) -> None:
        """A new trajectory (it replaces the current one at the next tick)."""
        self._pending = trajectory

    @property
    def current(self) -> JointTrajectory | None:
        """The trajectory being played (stamp resolved), None before the first."""
        return self._current

    @property
    def before(self) -> TrajectoryPoint:
        """The point recorded when the current trajectory was installed."""
        return self._before

    def tick(self, tau_ns: int) -> TrajectoryPoint:
        """The command written at tick ``tau_ns`` (ns): ``sample(tau + lookahead)``; the hold when idle."""
        if self._pending is not None:
            self._current = started(self._pending, tau_ns)
            self._pending = None
            self._before, self._before_ns = self.last, (self.last_ns if self.last_ns is not None else tau_ns)
        if self._current is not None:
            pt = sample(
                self._current,
                tau_ns + self.settings.lookahead_ns,
                self.settings.interpolation,
                self._before,
                self._before_ns,
            )
            if pt is not None:
                self.last = pt
        self.last_ns = tau_ns
        return self.last


__all__ = ["HeldPiece", "TrajectoryPlayer", "held_pieces", "sample", "started"]
